"""The lag test's judge on benchmark worlds: the time constant learned jointly with window
nets (`discovery._lag._learned_lag`, the settings of the benchmark config), per world.

Each job is SEED_OFFSET:SCENARIO of the benchmark config; one row per world (learned τ, its
median and range over folds × seeds, the lagged nets' held-out ensemble RMS, seconds) is
printed and written to OUT (CSV, with the config). The table in docs/discovery-studies.md ("The lag
test judged by a learned lag"):

    python experiments/learned_lag_probe.py 0:long-lag,0:null-31,3:long-lag --out runs/learned-lag.csv
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).parent))
from discovery_benchmark import _campaign, find_scenario  # noqa: E402

from pvvjax._strict import from_dict  # noqa: E402
from pvvjax.analysis.databases import DB_INPUTS  # noqa: E402
from pvvjax.config import DiscoveryConfig, ExperimentConfig  # noqa: E402
from pvvjax.discovery import Model  # noqa: E402
from pvvjax.discovery._confirm import _train_model  # noqa: E402
from pvvjax.discovery._lag import _learned_lag  # noqa: E402
from pvvjax.discovery._workflow import _context  # noqa: E402
from pvvjax.io import write_table  # noqa: E402

CONFIG = Path(__file__).parent / "configs" / "discovery" / "benchmark.toml"


def learned(offset: int, name: str) -> dict:
    """The learned lag of one benchmark world (its replay calibrated by its own peak nets)."""
    sc, overrides = find_scenario(CONFIG, offset, name)
    cfg = ExperimentConfig(discovery=from_dict(DiscoveryConfig, {**overrides, "database": sc["database"]}))
    t0 = time.perf_counter()
    ctx = _context(_campaign(sc["synth"]), cfg, lambda m: None)
    ctx.replay_params = _train_model(ctx, Model({}, tuple(DB_INPUTS[cfg.discovery.database])), rows="peaks")
    got = _learned_lag(ctx, log=lambda m: None)
    tau = got["tau_s"]
    return dict(scenario=name, seed_offset=offset, seed=sc["seed"], tau_s=got["tau_median_s"], tau_min_s=tau.min(),
                tau_max_s=tau.max(), ensemble_rms_g=got["metrics"]["ensemble_rms_g"],
                confirmed=got["tau_median_s"] >= cfg.discovery.lag_slow_s, seconds=time.perf_counter() - t0), cfg


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("jobs", help="comma-separated SEED_OFFSET:SCENARIO")
    ap.add_argument("--out", type=Path, help="CSV of the rows (and Parquet beside it)")
    args = ap.parse_args()
    rows, cfg = [], None
    for job in args.jobs.split(","):
        off, _, name = job.partition(":")
        row, cfg = learned(int(off), name)
        rows.append(row)
        print(f"{name} (seed {row['seed']}): learned τ {row['tau_s']:.2f} s ({row['tau_min_s']:.2f}-"
              f"{row['tau_max_s']:.2f}), ensemble RMS {row['ensemble_rms_g']:.4f} g; "
              f"{'a slow lag' if row['confirmed'] else 'no slow lag'}; {row['seconds']:.0f} s", flush=True)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        write_table(pd.DataFrame(rows), args.out.with_suffix(""), cfg)
    return np.array([r["tau_s"] for r in rows])


if __name__ == "__main__":
    main()
