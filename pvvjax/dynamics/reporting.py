"""The report of a `pvvjax dynamic` comparison: its figures (the shown conditions through
time, held out, against every model), `report.md` and the main job's section of it, and the
notes on flagged results (a degenerate model, a NaN score, no `best`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ..io import markdown_table
from .scores import row_peaks

if TYPE_CHECKING:
    from .study import Database

__all__ = ["PAPER_PULLUP", "figures", "report", "report_section", "result_notes", "shown_conditions"]

PAPER_PULLUP = ("11022", "AR60")  # the paper's pull-up and autorotation (Figs 1-9, 13-14)
_REPORT_COLUMNS = ("model", "rms_g", "rms_transient_g", "peak_err_rms_g", "peak_err_median_pct", "within_10pct_share",
                   "time_of_peak_err_median_s", "faa_pass_share", "kendall_tau", "rms_kind_holdout_g", "best")


def shown_conditions(d: Database, transients) -> list[str]:
    """The conditions the report draws: the paper's pull-up 11022 and autorotation AR60
    where the campaign has them, else its two transient conditions of highest peak."""
    named = [c for c in PAPER_PULLUP if c in d.seq.conditions]
    if named:
        return named
    peaks, _ = row_peaks(d.seq.amplitude, d.seq.mask, d.seq.time)
    order = [i for i in np.argsort(-peaks) if d.seq.maneuvers[i] in transients]
    return [d.seq.conditions[i] for i in order[:2]]


def figures(parts: dict, cfg, out: Path) -> list[Path]:
    """One figure per database: the shown conditions through time, held out, measured
    against every model."""
    from .. import plots

    paths = []
    for db, (d, by_split) in parts.items():
        shown = shown_conditions(d, cfg.dynamic.transients)
        if not shown:  # no paper condition and no transient: `report` says so
            continue
        fig, axes = plots.plt.subplots(len(shown), 1, figsize=(7.5, 3.2 * len(shown)), squeeze=False)
        for ax, cond in zip(axes[:, 0], shown):
            r = d.seq.conditions.index(cond)
            n = int(d.seq.mask[r].sum())
            pred = {m: a["heldout"][r, :n] for m, (_, a) in by_split["condition"].items()}
            plots.through_time(d.seq.time[r, :n], d.seq.amplitude[r, :n], pred,
                               f"{cond} ({d.seq.maneuvers[r]}, {d.seq.counters[r]}), held out: {db}", ax=ax)
        fig.tight_layout()
        paths.append(plots.save(fig, out / "figures" / f"through_time_{db}.png"))
    return paths


def report(table: pd.DataFrame, ident: pd.DataFrame, figs: list[Path], out: Path,
           kinds: pd.DataFrame | None = None) -> Path:
    """`report.md`: the comparison, the window RMS by maneuver kind (`kind_table`), the
    identified response and the figures."""
    lines = ["# PVV through time: dynamic models against the quasi-static map", "",
             "Held out by condition (every condition once); `rms_kind_holdout_g` holds out one maneuver kind at a "
             "time. FAA 14 CFR Part 60 App. C test 3.f.1: a condition passes when its predicted peak lies within "
             "+3/-6 dB of the measured one, or within 10 % of the nominal cruise level "
             f"({table.nominal_cruise_g.iloc[0]:.3f} g: the median measured peak of level flights in the cruise "
             "advance-ratio band). Kendall's tau: the correct trend over conditions. The paper's pull-up (Figs 13-14): "
             "peak within 0.02 g, phase within about 1 s.", ""]
    for db, rows in table.groupby("database", sort=False):
        cols = [c for c in _REPORT_COLUMNS if c in rows]
        lines += [f"## {db}", "", markdown_table(rows[cols], "{:.4g}"), "", *result_notes(rows)]
        if not any(p.stem == f"through_time_{db}" for p in figs):
            lines += [f"No figure of {db}: the campaign has neither the paper's conditions ({', '.join(PAPER_PULLUP)}) "
                      "nor a transient maneuver to draw.", ""]
    if kinds is not None and len(kinds):
        lines += ["## Window RMS by maneuver kind", "",
                  "Held out by condition, g; level flight is most of a campaign's windows, the transients the rest.",
                  ""]
        for db, rows in kinds.groupby("database", sort=False):
            wide = rows.pivot(index="model", columns="maneuver", values="rms_g")  # models down, kinds across
            wide = wide.loc[list(dict.fromkeys(rows.model)), list(dict.fromkeys(rows.maneuver))].reset_index()
            lines += [f"### {db}", "", markdown_table(wide, "{:.4g}"), ""]
    if len(ident):
        cols = ["f_n_hz", "zeta", "delay_s", "tau_equivalent_s", "tau_slow_pole_s"]
        g = ident.groupby(["database", "split"], sort=False)[cols]
        summary = pd.concat([g.median().add_suffix(" median"), g.min().add_suffix(" min"), g.max().add_suffix(" max")],
                            axis=1)[[f"{c} {s}" for c in cols for s in ("median", "min", "max")]].reset_index()
        lines += ["## Identified response over folds and seeds", "",
                  "f_n_hz: natural frequency, Hz; zeta: damping ratio; delay_s: delay, s; tau_equivalent_s: "
                  "2 zeta / omega_n, s; tau_slow_pole_s: the slow pole's time constant, s.", "",
                  markdown_table(summary), ""]
    lines += [f"![{p.stem}](figures/{p.name})" for p in figs]
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def result_notes(rows: pd.DataFrame) -> list[str]:
    """Markdown lines for a comparison's flagged rows: each degenerate model and why (it is
    never `best`), each reason a score is NaN (once where every model of a database shares
    it), and a missing `best`."""
    lines = []
    for db, group in rows.groupby("database", sort=False):
        for r in group.itertuples():
            if getattr(r, "degenerate", ""):
                lines.append(f"- **{r.model}** ({db}) is degenerate and never `best`: {r.degenerate}.")
        notes = group.notes if "notes" in group else pd.Series([], dtype=str)
        shared = notes.iloc[0] if len(notes) and notes.nunique() == 1 else ""
        if shared:
            lines.append(f"- Every model of {db}: {shared}.")
        lines += [f"- {r.model} ({db}): {r.notes}." for r in group.itertuples() if not shared and r.notes]
        if "best" in group and not group.best.any():
            lines.append(f"- No model of {db} is `best`: none holds a finite RMS without being degenerate.")
    return lines + [""] if lines else []


def report_section(table: pd.DataFrame, folder: str = "") -> list[str]:
    """The main job's report section of a comparison written to `folder` (relative to the
    report, e.g. "dynamic/"): its table and figures."""
    cols = ["database", "model", "rms_g", "rms_transient_g", "peak_err_rms_g", "time_of_peak_err_median_s",
            "faa_pass_share", "kendall_tau", "rms_kind_holdout_g", "best"]
    lines = ["## PVV through time: dynamic models against the quasi-static map", "",
             "Held out by condition; `rms_kind_holdout_g` holds out a maneuver kind at a time; FAA Part 60 test "
             "3.f.1 pass share per condition (+3/-6 dB, or 10 % of the nominal cruise level). Full tables, the "
             f"identified response and every window: [{folder}report.md]({folder}report.md).", "",
             markdown_table(table[[c for c in cols if c in table]], "{:.4g}"), "", *result_notes(table)]
    for db in dict.fromkeys(table.database):
        lines += [f"![through time, {db}]({folder}figures/through_time_{db}.png)", ""]
    return lines
