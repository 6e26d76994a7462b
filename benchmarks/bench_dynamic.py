"""`pvvjax dynamic`'s training time, model by model and split by split, beside what a
practitioner would try first on the same windows and folds: gradient-boosted trees
(scikit-learn's `HistGradientBoostingRegressor`) on the db1 inputs and their backward rates,
one model per fold. The same run, the same machine, the compile cache warm (run it twice:
the first run fills it). Usage:

    python benchmarks/bench_dynamic.py [--kind-split] [--out DIR]

Needs scikit-learn (the `bench` extra). Prints one line per (split, model) with its time
and its held-out window RMS, the total, and the trees' time and RMS as a ratio."""

from __future__ import annotations

import argparse
import dataclasses
import platform
import re
import tempfile
import time
from pathlib import Path

import jax
import numpy as np


def _trees(d, split) -> tuple[float, float]:
    """Seconds to fit one tree ensemble per fold on the training rows' real windows (db1's
    inputs and their rates) and predict the held-out rows; the held-out window RMS, g."""
    from sklearn.ensemble import HistGradientBoostingRegressor

    seq = d.seq
    pred = np.full(seq.amplitude.shape, np.nan)
    t0 = time.perf_counter()
    for test, val in zip(split.test, split.val):
        rows = ~test & ~val
        sel = seq.mask & rows[:, None]
        model = HistGradientBoostingRegressor(random_state=0).fit(seq.inputs[sel], seq.amplitude[sel])
        held = seq.mask & test[:, None]
        pred[held] = model.predict(seq.inputs[held])
    seconds = time.perf_counter() - t0
    err = (pred - seq.amplitude)[seq.mask]
    return seconds, float(np.sqrt(np.mean(err ** 2)))


def main():
    from pvvjax.config import ExperimentConfig
    from pvvjax.dynamics.study import comparison_table, prepare_database, run_parts
    from pvvjax.experiment import enable_compilation_cache, resolve_campaign

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kind-split", action="store_true", help="also the split by maneuver kind (the default)")
    ap.add_argument("--out", default=None, help="folder for the parts (default: a temporary one)")
    args = ap.parse_args()
    enable_compilation_cache()
    cfg = ExperimentConfig()
    cfg = cfg.with_(dynamic=dataclasses.replace(cfg.dynamic, kind_holdout=args.kind_split))
    campaign, _ = resolve_campaign(cfg, log=lambda m: None)
    times = {}

    def log(line):
        m = re.match(r"\s+(\S+) (\S+) (\S+): trained in", line)
        print(line, flush=True)
        if m:
            times[(m.group(2), m.group(3))] = time.perf_counter() - log.t0
        log.t0 = time.perf_counter()

    with tempfile.TemporaryDirectory() as tmp:
        t0 = log.t0 = time.perf_counter()
        parts = run_parts(campaign, cfg, Path(args.out or tmp) / "parts", log)
        total = time.perf_counter() - t0
        table = comparison_table(parts, cfg).set_index("model")
    cols = ["rms_g", "rms_transient_g", "peak_err_rms_g", "time_of_peak_err_median_s", "faa_pass_share",
            "kendall_tau", "rms_kind_holdout_g", "median_best_step", "degenerate", "best"]
    print(table[[c for c in cols if c in table]].to_string(float_format=lambda v: f"{v:.4g}"))
    d = prepare_database(campaign, cfg, "db1")
    trees_s, trees_rms = _trees(d, d.splits[0])
    print(f"machine: {platform.machine()}, {jax.device_count()} {jax.default_backend()} device(s); db1, "
          f"{len(d.seq.conditions)} conditions, {int(d.seq.mask.sum())} windows; {cfg.dynamic.folds} folds x "
          f"{cfg.dynamic.seeds} seeds")
    for (split, model), s in times.items():
        rms = f", held-out window RMS {table.rms_g[model]:.4f} g" if split == "condition" else ""
        print(f"{split:9s} {model:20s} {s:7.1f} s{rms}")
    cond = sum(s for (split, _), s in times.items() if split == "condition")
    print(f"pvvjax dynamic: {total:.0f} s in all ({cond:.0f} s the split by condition, with the windows' analysis)")
    print(f"gradient-boosted trees (HistGradientBoostingRegressor, db1 inputs and rates), split by condition: "
          f"{trees_s:.1f} s, held-out window RMS {trees_rms:.4f} g; pvvjax's split by condition takes "
          f"{cond / trees_s:.0f}x as long")


if __name__ == "__main__":
    main()
