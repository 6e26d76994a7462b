"""The experiment shell: campaign, databases on disk, their summary, the host's CPU devices.
(The main job itself runs end to end in test_cli: `pvvjax run`.)"""

import os
import subprocess
import sys

import pandas as pd
import pytest
from conftest import write_tiny

from pvvjax.config import ExperimentConfig, load_config
from pvvjax.experiment import (
    database_summary,
    resolve_campaign,
    use_cpu_cores,
    use_deterministic_gpu,
    write_databases,
)


def test_a_campaign_folder_is_loaded_and_named(tmp_path):
    folder = write_tiny(tmp_path / "c")
    said = []
    campaign, where = resolve_campaign(ExperimentConfig(), folder, log=said.append)
    assert where == folder and campaign.names == ("C1", "C2")
    assert said == [said[0]] and said[0].startswith("loaded 2 counters, 2 conditions")


def test_databases_are_written_beside_their_config_and_summarised(tmp_path, default_campaign, default_dbs):
    cfg = ExperimentConfig(name="dbs")
    write_databases(default_dbs, tmp_path, cfg)
    for name, df in default_dbs.items():
        pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / f"{name}.parquet"), df, check_dtype=False)
        assert len(pd.read_csv(tmp_path / f"{name}.csv")) == len(df)
    assert load_config(tmp_path / "config.toml") == cfg
    text = database_summary(default_dbs)
    n = len(default_dbs["peaks"])
    assert text.startswith(f"{n} conditions;")
    for name in ("db1", "db2", "db3"):
        assert f"  {name}: {len(default_dbs[name])} rows x " in text
    assert "paper conditions (peak PVV, g):" in text and "T1-level-135" in text  # Table 1, beside the paper


@pytest.mark.check
def test_cpu_devices_are_set_before_jax_starts_only(monkeypatch):
    # Here JAX is running: nothing changes. In a fresh process, the flag gives XLA 3 host devices.
    import jax  # noqa: F401 (JAX running, also when this test runs alone)

    monkeypatch.delenv("XLA_FLAGS", raising=False)
    use_cpu_cores(3)
    assert "XLA_FLAGS" not in os.environ
    code = ("from pvvjax.experiment import use_cpu_cores; use_cpu_cores(3); import jax; "
            "print(jax.local_device_count())")
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"} | {"JAX_PLATFORMS": "cpu"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == "3"


@pytest.mark.check
def test_deterministic_gpu_flag_is_set_before_jax_starts_and_a_users_setting_wins(monkeypatch):
    import jax  # noqa: F401

    monkeypatch.delenv("XLA_FLAGS", raising=False)
    use_deterministic_gpu()  # JAX is running here: a no-op
    assert "XLA_FLAGS" not in os.environ
    code = ("import os; from pvvjax.experiment import use_deterministic_gpu; use_deterministic_gpu(); "
            "import jax; jax.numpy.ones(2).block_until_ready(); print(os.environ['XLA_FLAGS'])")
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"} | {"JAX_PLATFORMS": "cpu"}
    for given, expected in [("", "--xla_gpu_deterministic_ops=true"),
                            ("--xla_gpu_deterministic_ops=false", "--xla_gpu_deterministic_ops=false")]:
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             env=env | {"XLA_FLAGS": given}, check=True)  # XLA on CPU accepts the flag
        assert out.stdout.strip() == expected
