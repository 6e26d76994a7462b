"""`pvvjax dynamic`'s training time, model by model and split by split, beside what a
practitioner would try first on the same windows and folds, in one run on one machine:

- gradient-boosted trees: scikit-learn's `HistGradientBoostingRegressor` and LightGBM's
  `LGBMRegressor` (defaults, seed 0);
- a ridge ARX model: ridge regression (standardised, its penalty by generalised cross-
  validation over 1e-3..1e3) on the same features.

The peers' features are, per window, db1's inputs averaged over it, their backward rates (as
`window_static_rates` takes them) and the inputs of the 1 to 4 windows before (causal: the
first window held before a record's start), so that they see the recent past as the dynamic
models do. Each peer fits one model per fold on the training rows' real windows and predicts
the held-out rows; every model is scored as `pvvjax dynamic` scores its own
(`dynamics.heldout_scores`, `dynamics.rms_by_kind`). Usage:

    python benchmarks/bench_dynamic.py [--kind-split] [--out DIR] [--table FILE.md]

Run it twice with the compile cache warm for the times (the first run fills it); with `--out`
a second run resumes the trained parts and times only the peers. Needs scikit-learn and
LightGBM (the `bench` extra)."""

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
import pandas as pd

LAGS = 4


def lagged_features(seq, lags: int = LAGS) -> np.ndarray:
    """(R, W, C) per window: the plain inputs, their rates, then the plain inputs of the `lags`
    windows before, the first window's held before the row starts."""
    plain = [i for i, n in enumerate(seq.names) if not n.startswith("d_")]
    x = seq.inputs[..., plain]
    cols = [seq.inputs]
    for k in range(1, lags + 1):
        cols.append(np.concatenate([np.repeat(x[:, :1], k, axis=1), x[:, :-k]], axis=1))
    return np.concatenate(cols, axis=-1)


def _peers() -> dict:
    from lightgbm import LGBMRegressor
    from sklearn.ensemble import HistGradientBoostingRegressor
    from sklearn.linear_model import RidgeCV
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    return {"trees (HistGradientBoosting)": lambda: HistGradientBoostingRegressor(random_state=0),
            "trees (LightGBM)": lambda: LGBMRegressor(random_state=0, verbose=-1),
            "ridge ARX": lambda: make_pipeline(StandardScaler(), RidgeCV(alphas=np.logspace(-3, 3, 13)))}


def fit_peer(make, feats, seq, split) -> tuple[np.ndarray, float]:
    """One model per fold on the training rows' real windows: the held-out (R, W) prediction
    and the seconds it took to fit and predict."""
    pred = np.full(seq.amplitude.shape, np.nan)
    t0 = time.perf_counter()
    for test, val in zip(split.test, split.val):
        sel = seq.mask & (~test & ~val)[:, None]
        model = make().fit(feats[sel], seq.amplitude[sel])
        held = test[:, None] & np.ones_like(seq.mask)
        pred[held] = model.predict(feats[held])
    return pred, time.perf_counter() - t0


def score(name, pred, d, cfg, seconds) -> dict:
    """One row of the peer table."""
    from pvvjax.dynamics import heldout_scores, rms_by_kind

    seq = d.seq
    s = heldout_scores(pred, seq.amplitude, seq.mask, seq.time, seq.maneuvers, cfg.dynamic.transients, d.nominal_g)
    kinds = rms_by_kind(pred, seq.amplitude, seq.mask, seq.maneuvers)
    return dict(model=name, rms_g=s["rms_g"], rms_transient_g=s["rms_transient_g"], faa_pass_share=s["faa_pass_share"],
                kendall_tau=s["kendall_tau"], time_of_peak_err_median_s=s["time_of_peak_err_median_s"],
                train_s=seconds, **{f"rms_{k}_g": v for k, v in kinds.items()})


def main():
    from pvvjax.config import ExperimentConfig
    from pvvjax.dynamics.study import comparison_table, run_parts
    from pvvjax.experiment import enable_compilation_cache, resolve_campaign
    from pvvjax.io import markdown_table

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kind-split", action="store_true", help="also the split by maneuver kind (the default)")
    ap.add_argument("--out", default=None, help="folder for the parts, resumed (default: a temporary one)")
    ap.add_argument("--table", default=None, help="also write the peer tables to this Markdown file")
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
    d, by_split = parts["db1"]
    print(f"machine: {platform.machine()}, {jax.device_count()} {jax.default_backend()} device(s); db1, "
          f"{len(d.seq.conditions)} conditions, {int(d.seq.mask.sum())} windows; {cfg.dynamic.folds} folds x "
          f"{cfg.dynamic.seeds} seeds")
    for (split, model), s in times.items():
        print(f"{split:9s} {model:20s} {s:7.1f} s")
    cond = sum(s for (split, _), s in times.items() if split == "condition")
    print(f"pvvjax dynamic: {total:.0f} s in all ({cond:.0f} s the split by condition, with the windows' analysis)")

    split, feats = d.splits[0], lagged_features(d.seq)
    rows = [score(f"pvvjax {m}", arrays["heldout"], d, cfg, times.get(("condition", m), np.nan))
            for m, (_, arrays) in by_split["condition"].items()]
    for name, make in _peers().items():
        pred, seconds = fit_peer(make, feats, d.seq, split)
        rows.append(score(name, pred, d, cfg, seconds))
    peers = pd.DataFrame(rows)
    if "rms_level_g" not in peers:
        peers["rms_level_g"] = np.nan
    main_cols = ["model", "rms_g", "rms_level_g", "rms_transient_g", "faa_pass_share", "kendall_tau",
                 "time_of_peak_err_median_s", "train_s"]
    kinds = [c for c in peers if c.startswith("rms_") and c not in main_cols]
    text = ["Held out by condition, db1, the same windows and folds; peers on the inputs, their rates and "
            f"{LAGS} lagged windows.", "", markdown_table(peers[main_cols], "{:.4g}"), "",
            "Window RMS by maneuver kind, g:", "", markdown_table(peers[["model", *kinds]], "{:.4g}"), ""]
    print("\n".join(text))
    if args.table:
        Path(args.table).write_text("\n".join(text))


if __name__ == "__main__":
    main()
