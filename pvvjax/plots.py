"""Matplotlib figures in the style of the paper (time histories, 4P PVV per window)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from .data.campaign import Campaign  # noqa: E402

__all__ = ["correlation", "cost_map", "offset_bars", "partial_dependence", "pvv_vs_airspeed", "replay", "residual_map",
           "save", "size_search", "through_time", "time_histories", "window_profile"]


def save(fig, path) -> Path:
    """Write `fig` as PNG (creating the folder), close it, and return the path. A figure
    with nothing drawn in any panel is written all the same and said in a warning naming it,
    so that an empty picture is never taken for a result."""
    path = Path(path)
    if not any(ax.has_data() for ax in fig.axes):
        import warnings

        warnings.warn(f"{path}: the figure has nothing to draw (no data in any panel)", stacklevel=2)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def pvv_vs_airspeed(peaks: pd.DataFrame, weights=(15000.0, 20000.0), tol_lb=600.0, title=None):
    """Peak PVV against airspeed in level flight, one series per weight (±tol_lb),
    sea level (density ratio ≥ 0.97) and rotor speed within 1 % of the median."""
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    level = peaks[(peaks.maneuver == "level") & (peaks.density_ratio >= 0.97)]
    rpm0 = level.rotor_rpm.median()
    level = level[(level.rotor_rpm - rpm0).abs() < 0.01 * rpm0]
    for w, marker in zip(weights, "os^v"):
        g = level[(level.gross_weight_lb - w).abs() <= tol_lb].sort_values("airspeed_kt")
        ax.plot(g.airspeed_kt, g.peak_pvv_g, marker=marker, label=f"GW {w / 1000:.0f} klb (n={len(g)})")
    ax.set_xlabel("true airspeed, kt")
    ax.set_ylabel("peak PVV (4P), g")
    ax.set_title(title or "Level flight: 4P pilot-floor vibration vs airspeed")
    ax.grid(alpha=0.3)
    ax.legend()
    return fig


def time_histories(campaign: Campaign, windows: pd.DataFrame, counters, panels, title=""):
    """Stacked time histories of one or more consecutive counters (paper Figs 1-9).

    Args:
        campaign: the campaign.
        windows: the long window table (`databases.window_table`).
        counters: counters drawn one after another (segments of one condition).
        panels: list of (label, [channels]); the channel "pvv" draws the 4P PVV per window.
    """
    fig, axes = plt.subplots(len(panels), 1, figsize=(7.5, max(2.8, 1.9 * len(panels))), sharex=True)
    axes = np.atleast_1d(axes)
    t0 = 0.0
    for k, counter in enumerate(counters):
        rec = campaign.records[counter]
        t = rec.time_s.to_numpy() + t0
        for ax, (label, chans) in zip(axes, panels):
            for ch in chans:
                if ch == "pvv":
                    w = windows[windows.counter == counter]
                    ax.step(w.time_s + t0, w.pvv_g, where="mid", color="C3", label="4P PVV" if k == 0 else None)
                    ax.plot(w.time_s + t0, w.pvv_g, "o", color="C3", ms=3)
                else:
                    ax.plot(t, rec[ch].to_numpy(), lw=0.6 if ch == "az_g" else 1.0,
                            label=ch if k == 0 else None)
            ax.set_ylabel(label)
        if k:
            for ax in axes:
                ax.axvline(t0, color="k", ls="--", lw=0.8)
        t0 = t[-1] + (t[-1] - t[-2])
    for ax in axes:
        ax.grid(alpha=0.3)
        if len(ax.get_legend_handles_labels()[0]) > 1:
            ax.legend(fontsize=7, loc="upper left")
    axes[-1].set_xlabel("time, s" + (" (segments joined; dashed line = counter boundary)" if len(counters) > 1 else ""))
    fig.suptitle(title)
    return fig


def correlation(pred: pd.DataFrame, title: str, band: float = 0.05):
    """Predicted vs measured peak PVV with the 45-degree line and the ±band (paper Figs 10-12);
    points outside the band are flagged (possible bad data) and labelled."""
    fig, ax = plt.subplots(figsize=(5.2, 5.0))
    lim = (0.0, max(0.35, float(max(pred.measured.max(), pred.predicted.max())) * 1.05))
    ax.plot(lim, lim, "k-", lw=1, label="45° line")
    for s in (band, -band):
        ax.plot(lim, (lim[0] + s, lim[1] + s), "k--", lw=0.8)
    inside = pred[~pred.outside_band]
    out = pred[pred.outside_band]
    ax.plot(inside.measured, inside.predicted, "o", ms=4, alpha=0.7, label=f"held out (n={len(inside)})")
    ax.plot(out.measured, out.predicted, "s", ms=6, mfc="none", color="C3",
            label=f"outside ±{band:g} g: possible bad data (n={len(out)})")
    for r in out.reindex(out.error.abs().sort_values(ascending=False).index).head(8).itertuples():
        ax.annotate(f"{r.condition} ({r.maneuver})", (r.measured, r.predicted), fontsize=6, xytext=(3, 2),
                    textcoords="offset points")  # the largest misses; the full list is in the results table
    rms = float(np.sqrt(np.mean(pred.error**2)))
    ax.set_xlim(lim)
    ax.set_ylim(lim)
    ax.set_xlabel("flight-test peak PVV, g")
    ax.set_ylabel("network peak PVV (held out), g")
    ax.set_title(f"{title}\nheld-out RMS {rms:.3f} g")
    ax.legend(fontsize=7, loc="upper left")
    ax.grid(alpha=0.3)
    return fig


def size_search(val: pd.DataFrame, chosen: dict, title: str):
    """Validation RMS against first-layer width (median and spread over seeds and folds),
    with the path of the paper's search rule and its choice."""
    fig, ax = plt.subplots(figsize=(6.0, 3.8))
    ax.fill_between(val.index, val["q25"], val["q75"], alpha=0.25, label="25-75 % over seeds and folds")
    ax.plot(val.index, val["median"], "o-", label="median validation RMS")
    path = chosen["path"]
    ax.plot(path, val.loc[path, "median"], "x", color="C3", ms=9, label="visited by the search rule")
    ax.axvline(chosen["width"], color="C2", ls="--", label=f"chosen: {chosen['width']} PEs")
    ax.set_xlabel("processing elements in the first hidden layer")
    ax.set_ylabel("validation RMS, g")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def _time_axes(fig, ax, ylabel: str, title: str):
    """Label a PVV-against-time panel; the figure if the plot made one, else the axes."""
    ax.set_xlabel("time, s")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return fig if fig is not None else ax


def replay(series: dict[str, pd.DataFrame], title: str, ax=None, measured_label="flight test (4P PVV)"):
    """Quasi-static replay of one counter (paper Figs 13-14): measured PVV per window and one
    predicted series per label (window tables of `replay_tables.replay_windows`)."""
    fig = None
    if ax is None:
        fig, ax = plt.subplots(figsize=(7.0, 3.6))
    first = next(iter(series.values()))
    full = first[first.weight >= 0.999]
    ax.plot(full.time_s, full.measured_g, "ko-", ms=3.5, lw=1.2, label=measured_label)
    for k, (label, w) in enumerate(series.items()):
        w = w[w.weight >= 0.999]
        ax.plot(w.time_s, w.predicted_g, "s--" if k % 2 else "^-", ms=3.5, lw=1.0, color=f"C{k}", label=label)
    return _time_axes(fig, ax, "PVV (4P), g", title)


def cost_map(grid: pd.DataFrame, optimum: tuple[float, float] | None, title: str, ax=None):
    """Replay cost over offset × window length (one database and group of `grid_table`),
    with the gradient optimum marked; a line against the offset when the grid has one length."""
    fig = None
    if ax is None:
        fig, ax = plt.subplots(figsize=(5.6, 4.0))
    piv = grid.pivot(index="window_revs", columns="offset_s", values="cost")
    if piv.shape[0] == 1:  # one window length: the cost against the offset
        fig = fig or ax.figure
        ax.plot(piv.columns, piv.values[0], "-", label=f"grid ({piv.index[0]:g} revs)")
        ax.plot(piv.columns[np.nanargmin(piv.values[0])], np.nanmin(piv.values[0]), "k+", ms=12, mew=2,
                label="grid minimum")
        if optimum is not None:
            ax.axvline(optimum[0], color="r", ls="--", label="gradient optimum")
        ax.set_xlabel("input-to-vibration offset, s")
        ax.set_ylabel("mean cost")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7)
        return fig
    im = ax.pcolormesh(piv.columns, piv.index, piv.values, shading="nearest", cmap="viridis")
    (fig or ax.figure).colorbar(im, ax=ax, label="mean cost")
    j, k = np.unravel_index(np.nanargmin(piv.values), piv.shape)
    ax.plot(piv.columns[k], piv.index[j], "w+", ms=12, mew=2, label="grid minimum")
    if optimum is not None:
        ax.plot(*optimum, "rx", ms=10, mew=2, label="gradient optimum")
    ax.set_xlabel("input-to-vibration offset, s")
    ax.set_ylabel("window length, revolutions")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    return fig if fig is not None else ax


def residual_map(localized: dict, title: str):
    """Where the held-out residual concentrates (`residuals.localize`): RMS residual and
    share of the squared residual by maneuver kind, by regime, and over time in maneuvers."""
    regimes = [k for k in localized if k.startswith("regime:")]
    fig, axes = plt.subplots(1, 2 + len(regimes), figsize=(4.2 * (2 + len(regimes)), 3.8))
    man = localized["maneuver"].sort_index()
    axes[0].bar(man.index.astype(str), man.rms_residual_g, color="C0")
    axes[0].set_ylabel("RMS residual, g")
    for x, (k, r) in enumerate(man.iterrows()):
        axes[0].text(x, r.rms_residual_g, f"{r.share_sq:.0%}", ha="center", va="bottom", fontsize=7)
    axes[0].set_title("by maneuver (labels: share of residual²)", fontsize=8)
    axes[0].tick_params(axis="x", rotation=60, labelsize=7)
    for ax, key in zip(axes[1:], regimes):
        r = localized[key]
        ax.bar([str(i) for i in r.index], r.mean_residual_g, color="C1", label="mean")
        ax.plot([str(i) for i in r.index], r.rms_residual_g, "ko-", ms=3, label="RMS")
        ax.set_title(f"by {key.split(':', 1)[1]} (quantile bins)", fontsize=8)
        ax.tick_params(axis="x", rotation=60, labelsize=6)
        ax.axhline(0, color="k", lw=0.5)
        ax.legend(fontsize=7)
    t = localized["time"].reset_index()
    t[["maneuver", "position"]] = t.key.str.split(" @ ", expand=True)
    piv = t.pivot(index="maneuver", columns="position", values="mean_residual_g")
    piv = piv[sorted(piv.columns, key=lambda s: float(s.strip("([").split(",")[0]))]
    lim = float(np.nanmax(np.abs(piv.values))) or 1.0
    im = axes[-1].imshow(piv.values, cmap="RdBu_r", vmin=-lim, vmax=lim, aspect="auto")
    axes[-1].set_yticks(range(len(piv.index)), piv.index, fontsize=7)
    axes[-1].set_xticks(range(len(piv.columns)), [c.split(",")[0].strip("([") for c in piv.columns], fontsize=7)
    axes[-1].set_xlabel("position inside the counter (0 = start)", fontsize=8)
    axes[-1].set_title("mean residual over time in maneuvers, g", fontsize=8)
    fig.colorbar(im, ax=axes[-1], shrink=0.8)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    return fig


def partial_dependence(x, residual, change, title: str, xlabel: str, bins: int = 12):
    """An effect's partial dependence: the baseline residual (measured − predicted) and the
    change the augmented model made, binned against the effect's value per window."""
    x, residual, change = map(np.asarray, (x, residual, change))
    edges = np.unique(np.quantile(x, np.linspace(0, 1, bins + 1)))
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    centre = np.array([x[idx == i].mean() for i in range(len(edges) - 1)])
    mean = lambda v: np.array([v[idx == i].mean() for i in range(len(edges) - 1)])  # noqa: E731
    fig, ax = plt.subplots(figsize=(5.8, 3.8))
    sub = np.random.default_rng(0).permutation(len(x))[:3000]
    ax.plot(x[sub], residual[sub], ".", ms=2, color="0.7", label="baseline residual (windows)")
    ax.plot(centre, mean(residual), "ko-", ms=4, label="baseline residual, binned mean")
    ax.plot(centre, mean(change), "s-", color="C3", ms=4, label="augmented − baseline prediction, binned")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("g")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return fig


def offset_bars(per_kind: pd.DataFrame, tau_all: pd.Series):
    """Fitted offset per maneuver kind (bars) and the common one (dashed) per database."""
    fig, ax = plt.subplots(figsize=(7.0, 3.6))
    kinds = list(dict.fromkeys(per_kind.group))
    dbs = list(dict.fromkeys(per_kind.database))
    x = np.arange(len(kinds))
    for k, db in enumerate(dbs):
        v = per_kind[per_kind.database == db].set_index("group").loc[kinds, "offset_s"]
        ax.bar(x + (k - 1) * 0.27, v, 0.27, color=f"C{k}", label=f"{db} per kind")
        ax.axhline(tau_all[db], color=f"C{k}", ls="--", lw=1, label=f"{db} one for all ({tau_all[db]:.2f} s)")
    ax.set_xticks(x, kinds)
    ax.set_ylabel("fitted offset, s")
    ax.set_title("Input-to-vibration offset: one per maneuver kind vs one for all", fontsize=9)
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=6, ncol=2)
    return fig


def window_profile(profiles: dict):
    """Replay cost minimised over the offset vs window length (grid) with the gradient optimum,
    one panel per set-up (label -> (profile table, calibration table))."""
    fig, axes = plt.subplots(1, len(profiles), figsize=(11.0, 3.8), sharey=False)
    for ax, (label, (prof, cal)) in zip(np.atleast_1d(axes), profiles.items()):
        for k, (db, g) in enumerate(prof.groupby("database")):
            ax.plot(g.window_revs, g.cost, "o-", ms=3, color=f"C{k}", label=f"{db}: min over offset (grid)")
            r = cal[cal.database == db].iloc[0]
            ax.plot(r.window_revs, r.cost, "x", color=f"C{k}", ms=10, mew=2, label=f"{db}: gradient optimum")
        ax.axvline(8.0, color="k", ls=":", lw=1, label="the paper's 8 revs")
        ax.set_xlabel("window length, revolutions")
        ax.set_ylabel("mean replay cost")
        ax.set_title(f"Window length, {label}", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    return fig


def through_time(time, measured, predicted: dict, title: str, ax=None):
    """PVV through a maneuver, window by window: the measured amplitude and one line per
    model (`predicted`: label -> values at the same window times, s)."""
    fig = None
    if ax is None:
        fig, ax = plt.subplots(figsize=(7.0, 3.4))
    ax.plot(time, measured, "k-", lw=1.6, label="measured")
    for k, (label, values) in enumerate(predicted.items()):
        ax.plot(time, values, "--" if k % 2 else "-", lw=1.1, color=f"C{k}", label=label)
    return _time_axes(fig, ax, "PVV (N/rev), g", title)
