"""The replay studies the paper left open, as result sections (Markdown, figures, tables):
one input-to-vibration offset for all maneuvers vs one per maneuver kind, the harmonic
window length, and a separate lag for the stick inputs. Used by the main job
(`pvvjax run`) and by `experiments/replay_study.py`.

Each study takes a replay set (`replay_tables.load_replay_set`) and the calibration config,
and returns a `Study`; the numbers come from `calibration` (gradient) with a brute-force
grid beside it where the study is about an optimum.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
import pandas as pd

from ..config import CalibrationConfig
from ..data.batch import batch_rows
from ..io import markdown_table
from .tables import (
    calibration_settings,
    calibration_table,
    cost_weights,
    counter_cost_table,
    grid_table,
    peak_summary,
    replay_windows,
    settings_at,
    take_counters,
)

__all__ = ["Study", "offset_per_kind", "one_offset", "stick_lag", "window_length"]


@dataclasses.dataclass(frozen=True)
class Study:
    """One result section.

    Attributes:
        markdown: the section (starts with a `##` heading; figures linked as `figures/NAME`).
        figures: the figure files it wrote.
        tables: name -> table, for `io.write_table`.
    """

    markdown: str
    figures: tuple[Path, ...]
    tables: dict


def _figure_links(figs) -> list[str]:
    return [f"![{f.stem}](figures/{f.name})" for f in figs]


def one_offset(info, batch, recs, models: dict, cc: CalibrationConfig, *, log=print) -> pd.DataFrame:
    """The offset fitted by gradient on every counter of the set together (8-rev windows).

    Returns:
        the calibration table indexed by database (`offset_s`, `cost`, ...).
    """
    off_cfg = dataclasses.replace(cc, free=("offset_s",), groups="all")
    return calibration_table(info, batch, recs, models, off_cfg, (0.0, 8.0, 0.0), log=log).set_index("database")


def offset_per_kind(info, batch, recs, models: dict, cc: CalibrationConfig, common: pd.DataFrame, figures: Path,
                    *, log=print) -> Study:
    """One offset for all maneuvers vs one per maneuver kind (8-rev windows, the config's hop),
    compared on every counter at zero offset, the common offset and the per-kind offsets.

    Args:
        common: the common offset per database (`one_offset`).
        figures: folder for the bar chart.
    """
    from .. import plots

    tau_all = common.offset_s
    off_cfg = dataclasses.replace(cc, free=("offset_s",), groups="all")
    per_kind = calibration_table(info, batch, recs, models, off_cfg, (0.0, 8.0, 0.0), groups="maneuver", log=log)
    weights = cost_weights(cc)
    settings = calibration_settings(batch, off_cfg, False)
    n = len(info)
    kind_tau = {db: per_kind[per_kind.database == db].set_index("group").offset_s.loc[info.maneuver].to_numpy()
                for db in models}

    def theta(tau):  # (N, 3) per counter: offset, 8 revs, no stick lag
        return np.stack([np.broadcast_to(tau, (n,)), np.full(n, 8.0), np.zeros(n)], 1)

    per_counter = []
    for name, tau in (("zero", {db: 0.0 for db in models}), ("one for all", tau_all.to_dict()),
                      ("one per kind", kind_tau)):
        c = counter_cost_table(info, recs, models, {db: theta(tau[db]) for db in models}, settings, weights)
        c["offsets"] = name
        per_counter.append(c)
    per_counter = pd.concat(per_counter, ignore_index=True)
    kind_tab = (per_counter.assign(abs_peak=per_counter.peak_error_g.abs(), abs_phase=per_counter.phase_error_s.abs())
                .groupby(["database", "maneuver", "offsets"])
                .agg(cost=("cost", "mean"), median_abs_peak_error_g=("abs_peak", "median"),
                     median_abs_phase_error_s=("abs_phase", "median"), rms_g=("rms_g", "median")).reset_index())
    kind_tab = kind_tab.merge(per_kind[["database", "group", "offset_s"]].rename(
        columns={"group": "maneuver", "offset_s": "kind_offset_s"}), on=["database", "maneuver"])
    totals = per_counter.groupby(["database", "offsets"]).cost.mean().unstack().reset_index()
    fig = plots.save(plots.offset_bars(per_kind, tau_all), Path(figures) / "offset_per_kind.png")
    md = ["## One offset for all maneuvers vs one per maneuver kind (8-rev windows, hop "
          f"{cc.hop_revs:g} rev)\n",
          "Offsets fitted by gradient (Levenberg-Marquardt from the best point of a 0.25 s grid):\n",
          markdown_table(per_kind[["database", "group", "n_counters", "offset_s", "cost", "steps"]]), "",
          "One offset for all maneuvers: " + ", ".join(f"{db} {t:.2f} s" for db, t in tau_all.items()) + ".\n",
          "Mean cost over all maneuver counters:\n", markdown_table(totals), "",
          "Per kind (median absolute errors; cost is the mean):\n", markdown_table(kind_tab), "",
          *_figure_links([fig]), ""]
    return Study("\n".join(md), (fig,), {"offset_per_kind": kind_tab, "offset_per_kind_fit": per_kind,
                                         "offset_per_counter": per_counter})


def window_length(info, batch, recs, models: dict, cc: CalibrationConfig, figures: Path, *,
                  bounds=(2.0, 24.0), log=print) -> Study:
    """The harmonic window length L and the offset fitted together by gradient, beside a
    brute-force grid (the config's offset step × 1 rev), in two set-ups: (a) inputs and
    vibration share the window (the paper's); (b) the measured PVV keeps 8-rev windows and
    only the input averaging length varies.

    Args:
        bounds: the window lengths studied, revolutions.
    """
    from .. import plots

    flat, profiles, grids, figs, t_grid = [], {}, {}, [], 0.0
    for label, ref in (("shared windows", 0.0), ("8-rev reference, input window varies", 8.0)):
        wl_cfg = dataclasses.replace(cc, free=("offset_s", "window_revs"), window_bounds=tuple(bounds),
                                     grid_window_step_revs=1.0, coarse_window_step_revs=2.0, reference_revs=ref,
                                     groups="all")
        cal = calibration_table(info, batch, recs, models, wl_cfg, (0.0, 8.0, 0.0), log=log)
        t0 = time.perf_counter()
        grid = grid_table(info, recs, models, wl_cfg, batch)
        t_grid += time.perf_counter() - t0
        grids[f"window_grid_ref{ref:g}"] = grid
        prof = grid.groupby(["database", "window_revs"]).cost.min().reset_index()
        profiles[label] = (prof, cal)
        for db, g in prof.groupby("database"):
            near = g[g.cost <= g.cost.min() * 1.05].window_revs
            r = cal[cal.database == db].iloc[0]
            gd = grid[grid.database == db]
            gb = gd.loc[gd.cost.idxmin()]
            at8 = g[np.isclose(g.window_revs, 8.0)].cost
            flat.append(dict(windows=label, database=db, gradient_window_revs=r.window_revs,
                             gradient_offset_s=r.offset_s, gradient_cost=r.cost, grid_window_revs=gb.window_revs,
                             grid_offset_s=gb.offset_s, grid_cost=gb.cost,
                             cost_at_8_revs=float(at8.iloc[0]) if len(at8) else float("nan"),
                             within_5pct_of_min=f"{near.min():g}-{near.max():g} revs"))
            if ref:
                f = plots.cost_map(gd, (r.offset_s, r.window_revs), f"{db}: cost, 8-rev reference windows")
                figs.append(plots.save(f, Path(figures) / f"cost_map_{db}.png"))
    flat = pd.DataFrame(flat)
    figs.insert(0, plots.save(plots.window_profile(profiles), Path(figures) / "window_length.png"))
    md = ["## Window length\n",
          "Offset and window length fitted together by gradient, and a brute-force grid "
          f"({cc.grid_offset_step_s:g} s × 1 rev, {t_grid:.0f} s in all) for reference; the profile is the cost "
          "minimised over the offset at each length. With shared windows both sides smooth together as L grows; "
          "with an 8-rev reference the measured PVV stays fixed and L is the input averaging alone.\n",
          markdown_table(flat), "", *_figure_links(figs), ""]
    return Study("\n".join(md), tuple(figs), {"window_length": flat, **grids})


def stick_lag(info, batch, recs, models: dict, cc: CalibrationConfig, common: pd.DataFrame, counter: str,
              figures: Path, *, log=print) -> Study | None:
    """A separate lag for the stick inputs (db2, db3): offset and stick lag fitted together
    over all counters, then `counter` replayed with and without it (consecutive 8-rev
    windows). None when the set has no stick database."""
    from .. import plots

    stick_dbs = {db: models[db] for db in ("db2", "db3") if db in models}
    if not stick_dbs:
        return None
    st_cfg = dataclasses.replace(cc, free=("offset_s", "stick_offset_s"), groups="all")
    cal = calibration_table(info, batch, recs, stick_dbs, st_cfg, (0.0, 8.0, 0.0), log=log).set_index("database")
    i = [list(info.index).index(counter)]
    one, rec1, batch1 = info.loc[[counter]], take_counters(recs, i), batch_rows(batch, i)
    rows, pu, windows = [], [], {}
    for db in stick_dbs:
        s = cal.loc[db]
        b = common.loc[db]
        rows.append(dict(database=db, offset_only_s=b.offset_s, cost_offset_only=b.cost, offset_s=s.offset_s,
                         stick_offset_s=s.stick_offset_s, cost_with_stick_lag=s.cost))
        for name, th in (("offset only", (b.offset_s, 8.0, 0.0)),
                         ("offset + stick lag", (s.offset_s, 8.0, s.stick_offset_s))):
            w = replay_windows(one, rec1, {db: take_counters(models[db], i)}, th, settings_at(batch1, th))
            sm = peak_summary(w)
            sm.insert(0, "model", name)
            pu.append(sm)
            windows[f"{db}, {name}"] = w
    tab, pu = pd.DataFrame(rows), pd.concat(pu, ignore_index=True)
    fig = plots.save(plots.replay(windows, f"pull-up {counter}: sticks with their own lag (db2/db3)"),
                     Path(figures) / f"stick_lag_{counter}.png")
    md = ["## A separate lag for the stick inputs (db2, db3)\n",
          "Offset and stick lag fitted together over all maneuvers (the sticks see the state offset plus their "
          "own):\n", markdown_table(tab), "",
          f"Counter {counter} at those values (consecutive 8-rev windows):\n",
          markdown_table(pu[["model", "database", "offset_s", "stick_offset_s", "predicted_peak_g", "peak_error_g",
                             "phase_error_s", "rms_g"]]), "", *_figure_links([fig]), ""]
    return Study("\n".join(md), (fig,), {"stick_lag": tab, "stick_lag_pullup": pu})
