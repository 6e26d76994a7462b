"""The paper's numbers, and the result sections that put a reproduction beside them (used by
the main job and by `experiments/paper_networks.py`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["PAPER_REPLAY", "PAPER_T1", "PAPER_TABLE1", "PULLUP", "networks_results", "pullup_replays"]

PAPER_TABLE1 = {  # condition id -> the paper's measured peak PVV, g
    "T1-level-135": 0.10, "T1-descent-160": 0.25, "T1-climb-62": 0.12, "T1-turn45-145": 0.13,
    "11022": 0.22, "AR60": 0.26,
}
PAPER_T1 = {  # Table 1 of the paper: test and db1/db2/db3 predictions, g
    "T1-level-135": (0.10, 0.09, 0.10, 0.11), "T1-descent-160": (0.25, 0.24, 0.25, 0.26),
    "T1-climb-62": (0.12, 0.12, 0.12, 0.12), "T1-turn45-145": (0.13, 0.13, 0.13, 0.14),
}


def networks_results(res: pd.DataFrame, dbs: dict, figures: Path, source: str
                     ) -> tuple[str, list[Path], pd.DataFrame]:
    """Figs 10-12 (held-out correlation per database), the held-out error summary and
    Table 1 beside the paper's values.

    Args:
        res: sweep results (`sweep.run_sweep`). dbs: the databases. figures: folder for the
            figures. source: what produced the sweep (a config path), for the text.

    Returns:
        (Markdown, figure paths, held-out predictions).
    """
    from . import plots
    from .evaluation import attach_measured, heldout_predictions, table1
    from .io import markdown_table

    pred = attach_measured(heldout_predictions(res), dbs)
    figs = []
    for i, db in enumerate(("db1", "db2", "db3")):
        sel = pred[pred.database == db]
        if sel.empty:
            continue
        arch = sel.architecture.iloc[0]
        fig = plots.correlation(sel, f"Fig {10 + i}: {db}, {arch}, median of {sel.n_nets.max()} seeds")
        figs.append(plots.save(fig, Path(figures) / f"fig{10 + i}_correlation_{db}.png"))
    t1 = table1(pred, {k: v for k, v in PAPER_TABLE1.items() if k in PAPER_T1})
    dbs_here = [db for db in ("db1", "db2", "db3") if db in t1.columns and t1[db].notna().any()]
    for db_i, db in enumerate(("db1", "db2", "db3"), start=1):
        if db in dbs_here:
            t1[f"paper {db}"] = [PAPER_T1[c][db_i] for c in t1.condition]
    t1 = t1[["condition", "paper test", "test"] + [c for db in dbs_here for c in (f"paper {db}", db)]]
    lines = ["# Networks on the embedded campaign: held-out results", "",
             f"Config `{source}`; {len(res)} nets; predictions are the median over seeds of the net that held "
             "each condition out (5-fold cross-validation by condition).", "",
             "| database | architecture | held-out RMS (g) | max abs error (g) | 95th pct abs error (g) "
             "| within ±0.05 g |",
             "|---|---|---|---|---|---|"]
    for db, g in pred.groupby("database"):
        lines.append(f"| {db} | {g.architecture.iloc[0]} | {(g.error**2).mean() ** 0.5:.3f} | "
                     f"{g.error.abs().max():.3f} | {g.error.abs().quantile(0.95):.3f} | "
                     f"{(~g.outside_band).mean():.0%} |")
    lines += ["", "Table 1 (g): the paper's values beside the synthetic campaign's, held-out predictions.", "",
              markdown_table(t1)]
    flagged = pred[pred.outside_band].sort_values("error", key=abs, ascending=False)
    lines += ["", f"Points outside ±0.05 g (flagged as possible bad data, as the paper does): {len(flagged)}", "",
              "| database | condition | maneuver | measured | predicted |", "|---|---|---|---|---|"]
    for r in flagged.head(15).itertuples():
        lines.append(f"| {r.database} | {r.condition} | {r.maneuver} | {r.measured:.3f} | {r.predicted:.3f} |")
    return "\n".join(lines) + "\n", figs, pred


PULLUP = "11022"
PAPER_REPLAY = {  # the paper's replay of 11022 (Figs 13-14)
    "db1": "peak within 0.02 g; peak time ~1 s off at zero offset, about coincident at a half-segment offset",
    "db2": "overshoot ~0.04 g; peak time ~3 s off (zero offset), ~2 s (half segment)",
    "db3": "overshoot ~0.10 g; peak time ~3 s off (zero offset), ~2 s (half segment)",
}


def pullup_replays(campaign, info, batch, recs, models: dict, tau_all: dict, figures: Path, extra: dict | None = None
                   ) -> tuple[pd.DataFrame, list[Path]]:
    """Paper Figs 13-14: the pull-up 11022 replayed through the held-out nets at zero offset,
    at half an 8-rev segment, at the offset fitted on all maneuvers (and any `extra`
    variants: name -> database -> offset), consecutive 8-rev windows.

    Args:
        campaign, info, batch, recs, models: a replay set (`replay_tables.load_replay_set`)
            that contains 11022.
        tau_all: database -> offset fitted on all maneuvers, s.
        figures: folder for the figures.

    Returns:
        (peak summary per offset and database, figure paths).
    """
    import jax

    from . import plots
    from .replay_tables import peak_summary, replay_windows, settings_at

    counters = list(info.index)
    i = counters.index(PULLUP)
    take = lambda tree: jax.tree.map(lambda a: a[np.asarray([i])], tree)  # noqa: E731
    one, rec1, models1 = info.loc[[PULLUP]], take(recs), {db: take(m) for db, m in models.items()}
    half = 4.0 / (float(campaign.records[PULLUP].rotor_rpm.mean()) / 60.0)  # half of an 8-rev segment, s
    variants = {"zero offset": {db: 0.0 for db in models}, f"half segment ({half:.2f} s)": {db: half for db in models},
                "optimized, all maneuvers": dict(tau_all), **(extra or {})}
    rows, windows, figs = [], {}, []
    for name, taus in variants.items():
        settings = settings_at(batch, (max(max(taus.values()), 0.0), 8.0, 0.0))  # one plan for all databases
        w = replay_windows(one, rec1, models1, {db: (t, 8.0, 0.0) for db, t in taus.items()}, settings)
        windows[name] = w
        s = peak_summary(w)
        s.insert(0, "offset", name)
        rows.append(s)
    for name, tag in (("zero offset", "fig13"), (list(variants)[1], "fig14"), ("optimized, all maneuvers", "fig14opt")):
        w = windows[name]
        for sub, dbs in (("a", ["db1"]), ("b", ["db2", "db3"])):
            dbs = [db for db in dbs if db in models]
            if not dbs:
                continue
            series = {f"{db} (offset {w[w.database == db].offset_s.iloc[0]:.2f} s)": w[w.database == db] for db in dbs}
            inputs = "MLF" if sub == "a" else "sticks"
            title = f"{tag.replace('opt', ' (optimized)')}{sub}: pull-up {PULLUP}, {name}, {inputs}"
            figs.append(plots.save(plots.replay(series, title), Path(figures) / f"{tag}{sub}_replay_{PULLUP}.png"))
    return pd.concat(rows, ignore_index=True), figs
