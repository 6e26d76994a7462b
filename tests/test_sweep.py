"""Sweeps: many nets in one program, resumable, sharded when devices allow."""

import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import jax
import numpy as np
import pandas as pd
import pytest

from pvvjax.analysis.databases import DB_INPUTS
from pvvjax.config import ExperimentConfig, SweepConfig, TrainConfig
from pvvjax.nets.networks import mlp_apply
from pvvjax.nets.sweep import load_nets, load_params, net_table, run_sweep
from pvvjax.nets.train import TrainingError

FAST = TrainConfig(learning_rate=1e-2, max_steps=600, eval_every=50, patience=4)


def _cfg(**sweep):
    base = dict(databases=("db1", "db3"), hidden=((4,), (6, 3)), seeds=2, folds=3, test_folds=(0,))
    return ExperimentConfig(sweep=SweepConfig(**{**base, **sweep}), train=FAST)


@pytest.mark.heavy
def test_sweep_results_params_and_resume(tmp_path, small_dbs):
    cfg = _cfg()
    res = run_sweep(cfg, small_dbs, tmp_path, log=lambda *a: None)
    assert len(res) == 8 and res.net_id.is_unique
    assert set(res.architecture) == {"6-4-1", "6-6-3-1", "7-4-1", "7-6-3-1"}
    for col in ("train_rms_g", "val_rms_g", "test_rms_g", "test_max_abs_g", "test_p95_abs_g", "wall_s", "config_hash"):
        assert res[col].notna().all()
    assert (res.test_rms_g < 0.2).all()
    # saved parameters reproduce the recorded predictions, and the split is by condition
    row = res.iloc[0]
    [(params, meta)] = load_nets(tmp_path, [row.net_id])
    assert meta["inputs"] == list(DB_INPUTS[row.database])
    db = small_dbs[row.database]
    x = np.zeros((len(db), 8), np.float32)
    x[:, : len(meta["inputs"])] = db[meta["inputs"]].to_numpy(np.float32)
    # predictions, conditions and split are list columns at full precision, also read back from disk
    saved = pd.read_parquet(tmp_path / "results.parquet").set_index("net_id").loc[row.net_id]
    assert saved.predictions.dtype == np.float64 and list(saved.conditions) == db.condition.astype(str).tolist()
    np.testing.assert_allclose(mlp_apply(params, x), saved.predictions, rtol=0, atol=2e-7)
    split = pd.Series(saved.split, index=db.condition)
    assert split.groupby(level=0).nunique().max() == 1 and set(split) == {"train", "val", "test"}
    # a second run trains nothing and changes nothing
    lines = []
    res2 = run_sweep(cfg, small_dbs, tmp_path, log=lines.append)
    assert "0 to train" in lines[0]
    pd.testing.assert_frame_equal(res.sort_values("net_id").reset_index(drop=True),
                                  res2.sort_values("net_id").reset_index(drop=True))
    # growing the sweep trains only the new nets
    res3 = run_sweep(_cfg(seeds=3), small_dbs, tmp_path, log=lines.append)
    assert "8 already finished, 4 to train" in lines[-1] and len(res3) == 12


def test_net_ids_are_stable_and_config_sensitive():
    a, b = net_table(_cfg()), net_table(_cfg())
    assert list(a.net_id) == list(b.net_id)
    c = net_table(ExperimentConfig(sweep=_cfg().sweep, train=TrainConfig(learning_rate=0.1)))
    assert set(a.net_id).isdisjoint(c.net_id)


def test_a_learning_rate_axis_trains_in_one_program(tmp_path, small_dbs):
    from conftest import Lowerings

    cfg = _cfg(databases=("db1",), hidden=((4,),), seeds=2, learning_rates=(3e-3, 1e-2, 3e-2, 1e-1))
    with Lowerings() as lowered:
        res = run_sweep(cfg, small_dbs, tmp_path, log=lambda *a: None)
    assert len(res) == 8 and sorted(set(res.learning_rate)) == [3e-3, 1e-2, 3e-2, 1e-1]
    assert lowered["_segment"] <= 1 and lowered["_init"] <= 1, dict(lowered)  # once (zero when already compiled)
    assert res.groupby("learning_rate").val_rms_g.median().nunique() == 4
    # a net of the axis is the net of a sweep at that one rate
    one = run_sweep(_cfg(databases=("db1",), hidden=((4,),), seeds=2, learning_rates=(1e-2,)), small_dbs,
                    tmp_path / "one", log=lambda *a: None)
    both = res[res.learning_rate == 1e-2].set_index("net_id").loc[one.net_id]
    np.testing.assert_array_equal(np.stack(both.predictions), np.stack(one.predictions))
    with pytest.raises(ValueError, match="learning_rates lists a value twice"):
        SweepConfig(learning_rates=(1e-2, 1e-2))


def test_rbf_family(tmp_path, small_dbs):
    res = run_sweep(ExperimentConfig(sweep=SweepConfig(databases=("db2",), family="rbf", centers=(8, 16), folds=3,
                                                       test_folds=(0,))), small_dbs, tmp_path, log=lambda *a: None)
    assert list(res.architecture) == ["rbf-8", "rbf-16"] or sorted(res.architecture) == ["rbf-16", "rbf-8"]
    assert (res.test_rms_g < 0.2).all()


def test_nan_stops_the_sweep_naming_net_and_step(tmp_path, small_dbs):
    dbs = {k: v.copy() for k, v in small_dbs.items()}
    dbs["db1"].loc[dbs["db1"].index[5], "mlf"] = np.nan
    with pytest.raises(TrainingError, match=r"net db1 6-4-1 seed 0 fold 0 .*at step 50"):
        run_sweep(_cfg(databases=("db1",), hidden=((4,),), seeds=1), dbs, tmp_path, log=lambda *a: None)


def _sweep_config_file(tmp_path, campaign_dir, n_archs, databases=("db1", "db2", "db3"), patience=12,
                       checkpoint_s=0.5):
    hidden = ", ".join(f"[{h}]" for h in range(2, 2 + n_archs))
    dbs = ", ".join(f'"{d}"' for d in databases)
    cfg = tmp_path / "sweep.toml"
    cfg.write_text(textwrap.dedent(f"""
        name = "kill"
        out_dir = "{tmp_path.as_posix()}"
        [campaign]
        path = "{Path(campaign_dir).as_posix()}"
        [sweep]
        databases = [{dbs}]
        hidden = [{hidden}]
        seeds = 2
        folds = 3
        chunk_evals = 1
        checkpoint_s = {checkpoint_s}
        [train]
        learning_rate = 0.003
        max_steps = 6000
        eval_every = 25
        patience = {patience}
    """))
    return cfg


@pytest.mark.check
@pytest.mark.heavy
def test_killed_sweep_resumes_without_duplicates_or_corrupt_files(tmp_path, small_campaign_dir):
    # 48 nets with a long patience: the training outlasts the first checkpoint by seconds even
    # when every program comes compiled from the cache (a warm run trains 144 nets of patience
    # 12 within one checkpoint interval, and leaves nothing to kill).
    cfg = _sweep_config_file(tmp_path, small_campaign_dir, n_archs=8, databases=("db1",), patience=80,
                             checkpoint_s=0.2)
    out = tmp_path / "kill" / "sweep"
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "pvvjax", "sweep", str(cfg)], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.time() + 240
    while time.time() < deadline and not list((out / "parts").glob("*.parquet")):
        time.sleep(0.05)
    time.sleep(0.3)
    assert proc.poll() is None, "the sweep finished before it could be killed; make it longer"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    finished_before = {p.name for p in (out / "parts").glob("*.parquet")}
    total = 8 * 2 * 3
    assert finished_before and not (out / "results.parquet").exists()
    assert sum(len(pd.read_parquet(out / "parts" / p)) for p in finished_before) < total  # killed mid-training
    done = subprocess.run([sys.executable, "-m", "pvvjax", "sweep", str(cfg)], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    res = pd.read_parquet(out / "results.parquet")
    assert len(res) == total and res.net_id.is_unique
    assert finished_before <= {p.name for p in (out / "parts").glob("*.parquet")}  # kept, not retrained
    assert not list(out.rglob("*.tmp*"))
    for p in (out / "params").glob("*.npz"):
        load_params(p)  # every parameter file reads back
    assert len(load_nets(out, list(res.net_id), res)) == total


SHARDING_SCRIPT = """
import os, sys, json
import jax, numpy as np
from pvvjax.config import ExperimentConfig, SweepConfig, TrainConfig
from pvvjax.data.campaign import load_campaign
from pvvjax.analysis.databases import build_databases
from pvvjax.nets.sweep import run_sweep
assert jax.device_count() == 2, jax.devices()
dbs = build_databases(load_campaign(sys.argv[1]))
cfg = ExperimentConfig(sweep=SweepConfig(databases=("db1",), hidden=((4,), (6,), (8,)), seeds=2, folds=3,
                                         test_folds=(0,)),
                       train=TrainConfig(learning_rate=1e-2, max_steps=600, eval_every=50, patience=4))
res = run_sweep(cfg, dbs, sys.argv[2], log=lambda *a: None)
print(json.dumps(dict(zip(res.net_id, res.val_rms_g))))
"""


@pytest.mark.check
@pytest.mark.heavy
def test_sweep_axis_is_sharded_over_devices_in_a_separate_process(tmp_path, small_campaign_dir, small_dbs):
    env = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=2", "JAX_PLATFORMS": "cpu"}
    out = subprocess.run([sys.executable, "-c", SHARDING_SCRIPT, str(small_campaign_dir), str(tmp_path / "two")],
                         capture_output=True, text=True, env=env, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    two = pd.read_json(pd.io.common.StringIO(out.stdout.strip().splitlines()[-1]), typ="series", precise_float=True)
    cfg = ExperimentConfig(sweep=SweepConfig(databases=("db1",), hidden=((4,), (6,), (8,)), seeds=2, folds=3,
                                             test_folds=(0,)),
                           train=TrainConfig(learning_rate=1e-2, max_steps=600, eval_every=50, patience=4))
    one = run_sweep(cfg, small_dbs, tmp_path / "one", log=lambda *a: None).set_index("net_id").val_rms_g
    assert jax.device_count() == 1
    # XLA partitions a sharded program into other arithmetic (on one device a net's bits do
    # not depend on its batch: test_batched), and early stopping can turn a last-bit
    # difference into another best step: equal to 2 %, where a broken sharding (nets mixed
    # up, data not replicated) would be far off.
    assert set(two.index) == set(one.index)
    np.testing.assert_allclose(two.loc[one.index].to_numpy(), one.to_numpy(), rtol=2e-2)


@pytest.mark.parametrize("per_group, widths", [(1, {2}), (3, {3}), (5, {5}), (12, {16, 8})])
def test_a_groups_nets_are_not_padded_beyond_its_size_up_to_8(monkeypatch, per_group, widths):
    # Padded nets are computed and thrown away: a group of 3 (discovery's seeds) trains as 3,
    # not 4; a lone net as 2 (a batch of one compiles to other arithmetic); above 8 the widths
    # are powers of two (few shapes to compile as nets finish).
    from pvvjax.nets import batched
    from pvvjax.nets.networks import mlp_init
    from pvvjax.nets.train import make_data

    rng = np.random.default_rng(0)
    x = rng.normal(size=(40, 2)).astype(np.float32)
    y = np.tanh(x[:, 0]).astype(np.float32)
    w = (np.arange(40) % 4 > 0).astype(np.float32)
    data = jax.tree.map(lambda a: np.stack([a, a]), make_data(x, y, w, 1.0 - w))
    n = 2 * per_group
    params = jax.tree.map(lambda *a: np.stack(a), *[mlp_init(jax.random.key(i), 2, (3,)) for i in range(n)])
    seen, program = [], batched._program

    def recorded(state, *args, **kw):
        seen.append(jax.tree.leaves(state)[0].shape[:2])  # (groups, nets per group)
        return program(state, *args, **kw)

    monkeypatch.setattr(batched, "_program", recorded)
    # patience 1 and different seeds: nets finish in different chunks, so compaction is exercised
    cfg = TrainConfig(learning_rate=1e-2, max_steps=400, eval_every=10, patience=1)
    fits = batched.train_nets(params, data, np.repeat([0, 1], per_group), cfg, chunk_evals=1, compact=True)
    assert {m for _, m in seen} == widths and all(g == 2 for g, _ in seen)
    assert fits.best_val_rms.shape == (n,) and np.isfinite(fits.best_val_rms).all()


@pytest.mark.parametrize("format", [None, 2])
def test_a_sweep_folder_of_an_earlier_format_is_refused_naming_it(tmp_path, small_dbs, format):
    # Format 1 held a parameter file per net and nets whose bits followed their batch, format 2
    # predictions as rounded JSON strings: their folders are not this pvvjax's, so not resumed.
    from pvvjax.io import ResultsFolderError, claim_folder
    from pvvjax.nets.sweep import FOLDER_FORMAT, databases_fingerprint, sweep_settings

    cfg = _cfg()
    old = {k: v for k, v in sweep_settings(cfg).items() if k != "format"}
    if format is not None:
        old["format"] = format
    claim_folder(tmp_path, old, databases_fingerprint(small_dbs, ["db1", "db2", "db3"]))
    there = "'(unset)'" if format is None else format
    with pytest.raises(ResultsFolderError, match=rf"format: {re.escape(str(there))} there, {FOLDER_FORMAT} now"):
        run_sweep(cfg, small_dbs, tmp_path, log=lambda *a: None)
