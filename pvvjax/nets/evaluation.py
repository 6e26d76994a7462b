"""From sweep results to the paper's results: held-out predictions, Table 1, outliers,
and the paper's architecture-search rule. Tables in, tables out (pandas)."""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["BAND_G", "attach_measured", "heldout_predictions", "search_architecture", "table1"]

BAND_G = 0.05  # the paper's error band


def heldout_predictions(results: pd.DataFrame) -> pd.DataFrame:
    """Each condition's prediction by the nets that held it out (test fold), per database,
    architecture and (where the sweep had those axes) learning rate and weight decay; the
    median over seeds is the ensemble prediction.

    Returns:
        Long table: database, architecture, [learning_rate, weight_decay,] condition,
        predicted, n_nets (see `attach_measured` for the measured values and the band flag).
    """
    keys = ["database", "architecture"] + [k for k in ("learning_rate", "weight_decay")
                                           if k in results and results[k].nunique(dropna=False) > 1]
    rows = []
    for r in results.itertuples():
        pred = np.asarray(r.predictions, np.float64)
        cond = np.asarray(r.conditions)
        split = np.asarray(r.split)
        head = tuple(getattr(r, k) for k in keys)
        for c, p in zip(cond[split == "test"], pred[split == "test"]):
            rows.append(head + (r.seed, c, p))
    long = pd.DataFrame(rows, columns=keys + ["seed", "condition", "predicted"])
    out = (long.groupby(keys + ["condition"])
           .agg(predicted=("predicted", "median"), n_nets=("predicted", "size")).reset_index())
    return out


def attach_measured(pred: pd.DataFrame, dbs: dict) -> pd.DataFrame:
    """Add the measured peak PVV and maneuver of each condition, the error, and the flag
    `outside_band` (|error| > 0.05 g: possible bad data, as the paper flags points far
    off the 45-degree line)."""
    parts = []
    for db, g in pred.groupby("database"):
        ref = dbs[db].set_index("condition")[["peak_pvv_g", "maneuver"]]
        parts.append(g.join(ref, on="condition").rename(columns={"peak_pvv_g": "measured"}))
    out = pd.concat(parts, ignore_index=True)
    out["error"] = out.predicted - out.measured
    out["outside_band"] = out.error.abs() > BAND_G
    return out


def table1(pred: pd.DataFrame, conditions: dict[str, float]) -> pd.DataFrame:
    """The paper's Table 1: measured ('Test') and held-out db1/db2/db3 predictions.

    Args:
        pred: `attach_measured` output (one architecture per database).
        conditions: condition id -> the paper's test value, g.
    """
    rows = []
    for cid, paper in conditions.items():
        sel = pred[pred.condition == cid]
        if sel.empty:
            continue
        row = {"condition": cid, "paper test": paper, "test": float(sel.measured.iloc[0])}
        for db in ("db1", "db2", "db3"):
            s = sel[sel.database == db]
            row[db] = float(s.predicted.iloc[0]) if len(s) else np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def search_architecture(val_rms: pd.Series, coarse_step: int = 5, fine: tuple[int, ...] = (2, 3)) -> dict:
    """The paper's architecture search as a selection rule over a sweep of first-layer widths.

    Start with the fewest processing elements, add `coarse_step` at a time while the
    validation RMS improves, then try ±2 and ±3 around the best to fine-tune.

    Args:
        val_rms: validation RMS indexed by first-layer width (e.g. median over seeds and folds).

    Returns:
        dict: width (chosen), path (widths visited, in order), val_rms (of the chosen).
    """
    widths = sorted(int(w) for w in val_rms.index)
    rms = {int(w): float(v) for w, v in val_rms.items()}
    w = widths[0]
    path = [w]
    while w + coarse_step in rms and rms[w + coarse_step] < rms[w]:
        w += coarse_step
        path.append(w)
    best = w
    for d in fine:
        for c in (w - d, w + d):
            if c in rms and c not in path:
                path.append(c)
                if rms[c] < rms[best]:
                    best = c
    return dict(width=best, path=path, val_rms=rms[best])
