"""Where a model and the measurement disagree: window-level residuals of held-out replays,
located by maneuver kind, by flight regime and over time inside the maneuvers (the first
step of the discovery workflow).

Tables in, tables out (pandas). The residual of a window is measured − predicted PVV (g);
a group's `concentration` is its share of the total squared residual divided by its share
of the windows: above 1 the misfit gathers there, 1 is an even spread.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["by_group", "localize", "residual_windows"]


def residual_windows(windows: pd.DataFrame, min_weight: float = 0.999) -> pd.DataFrame:
    """Fully weighted windows of `replay_tables.replay_windows` with the residual (g) and
    each window's position inside its counter (0 at the first window, 1 at the last)."""
    w = windows[windows.weight >= min_weight].copy()
    w["residual_g"] = w.measured_g - w.predicted_g
    span = w.groupby(["database", "counter"]).time_s.transform(lambda t: (t - t.min()) / max(t.max() - t.min(), 1e-9))
    w["position"] = span
    return w.reset_index(drop=True)


def by_group(res: pd.DataFrame, key, total_sq: float | None = None) -> pd.DataFrame:
    """Residual statistics per group (`key`: a column name or a Series aligned with `res`):
    windows, counters, mean and RMS residual (g), share of the squared residual, concentration."""
    r2 = res.residual_g**2
    total_sq = float(r2.sum()) if total_sq is None else total_sq
    g = pd.DataFrame({"key": res[key] if isinstance(key, str) else key, "r": res.residual_g, "r2": r2,
                      "counter": res.counter})
    out = g.groupby("key", observed=True).agg(windows=("r", "size"), counters=("counter", "nunique"),
                                              mean_residual_g=("r", "mean"), r2=("r2", "sum"))
    out["rms_residual_g"] = np.sqrt(out.r2 / out.windows)
    out["share_sq"] = out.r2 / max(total_sq, 1e-30)
    out["concentration"] = out.share_sq / (out.windows / len(res))
    return out.drop(columns="r2").sort_values("share_sq", ascending=False)


def localize(windows: pd.DataFrame, regimes: dict[str, int] | None = None, time_bins: int = 5) -> dict:
    """Where the residual of one database's replays concentrates.

    Args:
        windows: `replay_tables.replay_windows` of one database.
        regimes: feature -> number of quantile bins (default advance ratio and MLF, 5 each).
        time_bins: bins of the position inside each counter.

    Returns:
        dict of tables: "maneuver"; "regime:<feature>" per feature; "time" (maneuver kind ×
        position bin); and "counter" (the worst counters first).
    """
    if windows.database.nunique() > 1:
        raise ValueError(f"localize one database at a time, got {sorted(windows.database.unique())}")
    res = residual_windows(windows)
    if res.empty:
        raise ValueError("no fully weighted windows to localize")
    out = {"maneuver": by_group(res, "maneuver")}
    for feat, bins in (regimes or {"advance_ratio": 5, "mlf": 5}).items():
        out[f"regime:{feat}"] = by_group(res, pd.qcut(res[feat], bins, duplicates="drop")).sort_index()
    pos = pd.cut(res.position, np.linspace(0, 1, time_bins + 1), include_lowest=True)
    total = float((res.residual_g**2).sum())
    out["time"] = by_group(res, res.maneuver.astype(str) + " @ " + pos.astype(str), total)
    out["counter"] = by_group(res, "counter")
    return out
