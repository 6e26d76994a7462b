"""The multi-process path of a sweep (`jax.distributed`, one process per host): two CPU
processes on this machine, joined through a coordinator on localhost, train a small sweep
into one folder, and its results table is the one process's."""

import socket
import subprocess
import sys

import jax
import numpy as np
import pandas as pd
import pytest
import tomli_w

from pvvjax.nets import load_nets

pytestmark = pytest.mark.check  # several processes: the check lane's


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _two_processes_and_one(tmp_path, campaign, max_steps: int, databases, hidden, seeds: int) -> int:
    """The same sweep by one process and by two joined by jax.distributed: the same results
    table and nets; the number of nets."""
    cfg = tmp_path / "sweep.toml"
    cfg.write_text(tomli_w.dumps(dict(
        name="dist", campaign=dict(path=str(campaign)), train=dict(max_steps=max_steps),
        sweep=dict(databases=databases, hidden=hidden, seeds=seeds, folds=3, test_folds=[0, 1], cpu_devices=1))))
    n = len(databases) * len(hidden) * seeds * 2  # nets: databases x architectures x seeds x test folds
    sweep = [sys.executable, "-m", "pvvjax", "sweep", str(cfg)]
    join = ["--out", str(tmp_path / "two"), "--coordinator", f"127.0.0.1:{_free_port()}", "--num-processes", "2"]
    # The single process runs beside the joined pair (each spends most of its seconds importing).
    start = lambda args: subprocess.Popen(sweep + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE,  # noqa: E731
                                          text=True)
    one = start(["--out", str(tmp_path / "one")])
    procs = [start(join + ["--process-id", str(i)]) for i in (1, 0)]
    outs = [p.communicate(timeout=300) for p in procs]
    one_out = one.communicate(timeout=300)
    assert one.returncode == 0, one_out[1][-2000:]
    assert all(p.returncode == 0 for p in procs), [o[1][-2000:] for o in outs]
    assert all(f"{n} nets in" in o[0] for o in outs)  # both processes report the whole sweep

    a, b = (pd.read_parquet(tmp_path / d / "results.parquet").sort_values("net_id").reset_index(drop=True)
            for d in ("one", "two"))
    assert list(a.net_id) == list(b.net_id) and len(a) == n
    for col in ("database", "architecture", "seed", "test_fold", "steps", "best_step", "config_hash"):
        assert (a[col] == b[col]).all(), col
    # The nets are sharded over two processes' devices, a program XLA partitions into other
    # arithmetic: the same nets to float32 rounding.
    metrics = [c for c in a.columns if c.endswith(("_rms_g", "_max_abs_g", "_p95_abs_g"))]
    np.testing.assert_allclose(b[metrics], a[metrics], rtol=0, atol=1e-6)
    ids = list(a.net_id)
    for (pa, _), (pb, _) in zip(load_nets(tmp_path / "one", ids), load_nets(tmp_path / "two", ids)):
        for u, v in zip(jax.tree.leaves(pa), jax.tree.leaves(pb)):
            np.testing.assert_allclose(v, u, rtol=0, atol=1e-5)
    return n


def test_two_processes_give_the_one_process_results_table_of_a_micro_sweep(tmp_path, small_campaign_dir):
    # The full-size check's micro twin: 2 nets of one database, 100 steps.
    assert _two_processes_and_one(tmp_path, small_campaign_dir, 100, ["db1"], [[4]], 1) == 2


def test_two_processes_give_the_one_process_results_table(tmp_path, small_campaign_dir):
    assert _two_processes_and_one(tmp_path, small_campaign_dir, 300, ["db1", "db2"], [[4], [6]], 2) == 16
