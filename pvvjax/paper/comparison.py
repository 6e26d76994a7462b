"""The paper's numbers, and the result sections that put a reproduction beside them: Figs 1-9
drawn from a campaign, Figs 10-12 and Table 1 from a sweep, Figs 13-14 from a replay, and
`check` rows (the paper's number, the reproduction, the criterion, whether it agrees) for
every number the paper gives. Used by the main job, `notebooks/paper.py` and the experiments."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["AUTOROTATION", "PAPER_AUTOROTATION", "PAPER_PULLUP", "PAPER_REPLAY", "PAPER_T1", "PAPER_TABLE1", "PULLUP",
           "check", "comparison_markdown", "database_checks", "network_checks", "networks_results", "paper_figures",
           "pullup_replays", "replay_checks"]

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
    from .. import plots
    from ..io import markdown_table
    from ..nets.evaluation import attach_measured, heldout_predictions, table1

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
    lines = ["# Networks: held-out results", "",
             f"Config `{source}`; {len(res)} nets; predictions are the median over seeds of the net that held "
             f"each condition out ({res.test_fold.nunique()}-fold cross-validation by condition).", "",
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
    from .. import plots
    from ..data.batch import batch_rows
    from ..replay.tables import peak_summary, replay_windows, settings_at, take_counters

    i = [list(info.index).index(PULLUP)]
    batch = batch_rows(batch, i)  # its plan from its own samples
    one, rec1, models1 = info.loc[[PULLUP]], take_counters(recs, i), take_counters(models, i)
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


# ------------------------------------------------------------------ every number of the paper, checked
PAPER_PULLUP = {  # counter 11022, at the peak-PVV window unless noted
    "gross_weight_lb": 16055.0, "rotor_rpm": 255.0, "advance_ratio": 0.27, "record_s": 37.0, "record_revs": 156.0,
    "airspeed_kt": 120.0, "pitch_rate_dps": 9.6, "roll_angle_deg": 0.0, "mlf": 2.0, "collective_pct": 76.0,
    "lateral_pct": 60.0, "longitudinal_pct": 57.0, "peak_pvv_g": 0.22,
}
PAPER_AUTOROTATION = {  # condition AR60 = counters 11539 (segment 1) + 11540 (segment 2)
    "airspeed_kt": 60.0, "gross_weight_lb": 15910.0, "rotor_rpm": 256.0, "advance_ratio": 0.17, "segment_s": 27.0,
    "segment_revs": 115.0, "peak_pvv_g": 0.26,
}
AUTOROTATION = ("11539", "11540")


def check(section: str, item: str, paper, value, *, tol: float | None = None, accept: tuple | None = None,
          fmt: str = ".3f", source: str = "", note: str = "") -> dict:
    """One row of the paper comparison: the paper's number (or words), the reproduction, and
    whether it agrees: |value - paper| <= tol, or accept[0] <= value <= accept[1] for the
    paper's qualitative statements; no check when neither is given."""
    num = lambda v: isinstance(v, (int, float, np.floating, np.integer)) and not isinstance(v, bool)  # noqa: E731
    show = lambda v: "—" if v is None else (format(v, fmt) if num(v) else str(v))  # noqa: E731
    if value is None or (num(value) and not np.isfinite(value)):
        ok, crit = None, ""
    elif tol is not None:
        ok, crit = bool(abs(float(value) - float(paper)) <= tol + 1e-12), f"± {tol:g}"
    elif accept is not None:
        lo, hi = accept
        ok = bool(lo <= float(value) <= hi)
        crit = f"≥ {show(lo)}" if hi == np.inf else f"{show(lo)} to {show(hi)}"
    else:
        ok, crit = None, ""
    return {"section": section, "item": item, "paper": show(paper), "pvvjax": show(value), "criterion": crit,
            "agrees": {True: "yes", False: "no", None: "—"}[ok], "source": source, "note": note}


def _record_length(campaign, counter: str) -> tuple[float, float]:
    """(duration s, rotor revolutions) of one counter."""
    r = campaign.records[counter]
    t = r.time_s.to_numpy()
    dt = float(np.median(np.diff(t)))
    revs = float(np.trapezoid(r.rotor_rpm.to_numpy() / 60.0, t)) + float(r.rotor_rpm.iloc[-1]) / 60.0 * dt
    return float(t[-1] - t[0] + dt), revs


def _power_events(campaign) -> tuple[float, float]:
    """Autorotation power cut (segment 1) and power back (segment 2), s from the start of
    each segment: where the shaft power starts to fall (below 90 % of the powered level of
    the first 5 s) and starts to rise again (above 10 % of it)."""
    s1, s2 = (campaign.records[c] for c in AUTOROTATION)
    t1, p1 = s1.time_s.to_numpy(), s1.shaft_power_hp.to_numpy()
    level = float(np.median(p1[t1 < t1[0] + 5.0]))
    cut = t1[np.argmax(p1 < 0.9 * level)] - t1[0]
    t2, p2 = s2.time_s.to_numpy(), s2.shaft_power_hp.to_numpy()
    back = t2[np.argmax(p2 > 0.1 * level)] - t2[0]
    return float(cut), float(back)


def _condition_rows(sec: str, paper: dict, peak, mu_note: str = "") -> list[dict]:
    """Weight, rotor speed, airspeed (±10 kt of the paper's rounded value) and advance ratio."""
    v = paper["airspeed_kt"]
    return [check(sec, "gross weight, lb", paper["gross_weight_lb"], float(peak.gross_weight_lb), tol=50.0, fmt=".0f",
                  source="text"),
            check(sec, "rotor speed, rpm", paper["rotor_rpm"], float(peak.rotor_rpm), tol=2.0, fmt=".1f",
                  source="text"),
            check(sec, "airspeed at the peak, kt", f"~{v:g}", float(peak.airspeed_kt), accept=(v - 10.0, v + 10.0),
                  fmt=".1f", source="text"),
            check(sec, "advance ratio at the peak", paper["advance_ratio"], float(peak.advance_ratio), tol=0.01,
                  source="text", note=mu_note)]


def paper_figures(campaign, windows: pd.DataFrame, peaks: pd.DataFrame, figures: Path
                  ) -> tuple[list[tuple[str, Path]], pd.DataFrame]:
    """The paper's Figs 1-9 drawn from the campaign, one file each, and the numbers read off
    them beside the paper's (pull-up 11022: Figs 1-4; autorotation AR60: Figs 5-9).

    Args:
        windows, peaks: `databases.peak_table` of the campaign (8-rev windows for the paper's).
        figures: folder for the figures.

    Returns:
        ([(caption, path)], comparison rows (`check`)). Cases the campaign lacks are skipped.
    """
    from .. import plots

    figures = Path(figures)
    figs, rows = [], []
    conds = campaign.conditions()

    def draw(n: str, caption: str, counters, panels, name: str, mark=None):
        fig = plots.time_histories(campaign, windows, counters, panels, f"Fig. {n}. {caption}")
        if mark is not None:
            for ax in fig.axes:
                ax.axvline(mark, color="C3", ls=":", lw=1)
        figs.append((f"Fig. {n}. {caption}", plots.save(fig, figures / f"fig{n.zfill(2)}_{name}.png")))

    if PULLUP in conds:
        rows += _pullup_checks(campaign, peaks, draw)
    if "AR60" in conds and all(c in campaign.records for c in AUTOROTATION):
        rows += _autorotation_checks(campaign, windows, peaks, draw)
    return figs, pd.DataFrame(rows)


def _pullup_checks(campaign, peaks: pd.DataFrame, draw) -> list[dict]:
    """Figs 1-4 (drawn by `draw`) and the pull-up's numbers beside the paper's."""
    p = peaks.set_index("condition").loc[PULLUP]
    pk, sec = float(p.peak_time_s), "pull-up 11022 (Figs 1-4)"
    mark = "; dotted: the peak-PVV window"
    draw("1", "Pilot floor vertical acceleration, pull-up", [PULLUP], [("a_z, g", ["az_g"])], "az_11022", pk)
    draw("2", "Pitch rate, pull-up" + mark, [PULLUP], [("pitch rate, deg/s", ["pitch_rate_dps"])],
         "pitch_rate_11022", pk)
    draw("3", "Pilot control stick positions, pull-up" + mark, [PULLUP],
         [("sticks, %", ["collective_pct", "lateral_pct", "longitudinal_pct"])], "sticks_11022", pk)
    draw("4", "Pilot vertical vibration (4P, 8-rev windows), pull-up", [PULLUP], [("PVV, g", ["pvv"])],
         "pvv_11022", pk)
    dur, revs = _record_length(campaign, PULLUP)
    P = PAPER_PULLUP
    rows = [check(sec, "record length, s", P["record_s"], dur, tol=1.0, fmt=".1f", source="text"),
             check(sec, "record length, revolutions", P["record_revs"], revs, tol=4.0, fmt=".0f", source="text"),
             *_condition_rows(sec, P, p),
             check(sec, "pitch rate at the peak, deg/s", P["pitch_rate_dps"], float(p.pitch_rate_dps), tol=0.5,
                   fmt=".2f", source="Fig. 2"),
             check(sec, "roll angle at the peak, deg", P["roll_angle_deg"], float(p.roll_angle_deg), tol=3.0,
                   fmt=".1f", source="text"),
             check(sec, "maneuver load factor at the peak", P["mlf"], float(p.mlf), tol=0.1, fmt=".2f",
                   source="text"),
             *[check(sec, f"{s} stick at the peak, %", P[f"{s}_pct"], float(p[f"{s}_pct"]), tol=3.0,
                     fmt=".1f", source="Fig. 3") for s in ("collective", "lateral", "longitudinal")],
             check(sec, "peak PVV, g", P["peak_pvv_g"], float(p.peak_pvv_g), tol=0.02, source="Fig. 4")]
    return rows


def _autorotation_checks(campaign, windows: pd.DataFrame, peaks: pd.DataFrame, draw) -> list[dict]:
    """Figs 5-9 (drawn by `draw`) and the autorotation's numbers beside the paper's."""
    p = peaks.set_index("condition").loc["AR60"]
    s1, s2 = AUTOROTATION
    sec = "autorotation AR60 = 11539 + 11540 (Figs 5-9)"
    cut, back = _power_events(campaign)
    draw("5", "Pilot floor vertical acceleration and rotor shaft power, autorotation, segment 1", [s1],
         [("a_z, g", ["az_g"]), ("shaft power, hp", ["shaft_power_hp"])], "az_power_11539")
    draw("6", "Collective stick position, autorotation, segment 1", [s1], [("collective, %", ["collective_pct"])],
         "collective_11539")
    draw("7", "Pilot floor vertical acceleration and rotor shaft power, autorotation, segment 2", [s2],
         [("a_z, g", ["az_g"]), ("shaft power, hp", ["shaft_power_hp"])], "az_power_11540")
    draw("8", "Collective stick position, autorotation, segment 2", [s2], [("collective, %", ["collective_pct"])],
         "collective_11540")
    draw("9", "Pilot vertical vibration (4P), autorotation, segments 1 and 2", [s1, s2], [("PVV, g", ["pvv"])],
         "pvv_AR60")
    P = PAPER_AUTOROTATION
    seg_w = windows[windows.counter.isin(AUTOROTATION)]
    top = seg_w.loc[seg_w.pvv_g.idxmax()]
    rows = []
    for c in AUTOROTATION:
        dur, revs = _record_length(campaign, c)
        rows += [check(sec, f"segment {c} length, s", P["segment_s"], dur, tol=1.0, fmt=".1f", source="text"),
                 check(sec, f"segment {c} length, revolutions", P["segment_revs"], revs, tol=4.0, fmt=".0f",
                       source="text")]
    rows += [*_condition_rows(sec, P, p, "the paper's ~60 kt at 256 rpm is μ 0.14; its μ 0.17 would be ~73 kt"),
             check(sec, "power cut in segment 1, s", "just before 10 s", cut, accept=(8.0, 10.0), fmt=".1f",
                   source="Fig. 5"),
             check(sec, "power back in segment 2, s", "after 10 s", back, accept=(10.0, 12.5), fmt=".1f",
                   source="Fig. 7"),
             check(sec, "segment of the peak PVV", "2 (post-autorotation)",
                   AUTOROTATION.index(str(top.counter)) + 1, accept=(2, 2), fmt="d", source="Fig. 9"),
             check(sec, "peak PVV after power back (segment 2), s after", "> 0 (post-autorotation)",
                   float(top.time_s) - back if str(top.counter) == s2 else float("nan"), accept=(0.0, 27.0),
                   fmt=".1f", source="Fig. 9"),
             check(sec, "peak PVV, g", P["peak_pvv_g"], float(p.peak_pvv_g), tol=0.02, source="Fig. 9")]
    return rows


def database_checks(peaks: pd.DataFrame) -> pd.DataFrame:
    """The paper's database numbers: > 200 training points, ~25 % maneuvers (MLF != 1), and
    the measured peak PVV of the Table 1 conditions."""
    sec = "databases"
    n, man = len(peaks), float((np.abs(peaks.mlf - 1.0) > 0.05).mean())  # as the databases summary
    rows = [check(sec, "conditions (training points)", "> 200", n, accept=(201, np.inf), fmt="d", source="text"),
            check(sec, "share of maneuvers (MLF ≠ 1)", "~25 %", man, accept=(0.15, 0.35), fmt=".0%", source="text")]
    by = peaks.set_index("condition")
    for cid, (test, *_) in PAPER_T1.items():
        if cid in by.index:
            rows.append(check(sec, f"{cid}: measured peak PVV, g", test, float(by.loc[cid, "peak_pvv_g"]), tol=0.02,
                              source="Table 1"))
    return pd.DataFrame(rows)


def network_checks(pred: pd.DataFrame) -> pd.DataFrame:
    """Figs 10-12 and Table 1: architectures, the ±0.05 g band, the held-out predictions of
    the Table 1 conditions (the paper's nets saw every point in training; these did not)."""
    sec = "networks (Figs 10-12, Table 1)"
    paper_arch = {"db1": "6-10-5-1", "db2": "8-10-5-1", "db3": "7-10-5-1"}
    rows = []
    for db, g in pred.groupby("database"):
        fig = {"db1": "Fig. 10", "db2": "Fig. 11", "db3": "Fig. 12"}.get(db, "")
        rows.append(check(sec, f"{db}: architecture", paper_arch.get(db, ""), str(g.architecture.iloc[0]),
                          source=fig,
                          note="same" if paper_arch.get(db) == g.architecture.iloc[0] else "differs"))
        rows.append(check(sec, f"{db}: share within ±0.05 g", "all but a few (training fit)",
                          float((~g.outside_band).mean()), accept=(0.9, 1.0), fmt=".0%", source=fig,
                          note="held out by condition, a stricter test than the paper's training fit"))
    for cid in PAPER_T1:
        for k, db in enumerate(("db1", "db2", "db3"), start=1):
            s = pred[(pred.condition == cid) & (pred.database == db)]
            if len(s):
                rows.append(check(sec, f"{cid}: {db} prediction, g", PAPER_T1[cid][k], float(s.predicted.iloc[0]),
                                  tol=0.05, source="Table 1", note="held out; tolerance the paper's band"))
    return pd.DataFrame(rows)


def replay_checks(tab: pd.DataFrame) -> pd.DataFrame:
    """Figs 13-14: the pull-up replay at zero and half-segment offsets (`pullup_replays`)."""
    sec = "replay of the pull-up 11022 (Figs 13-14)"
    rows = []
    zero = tab[tab.offset == "zero offset"].set_index("database")
    half = tab[tab.offset.str.startswith("half segment")].set_index("database")
    note = "peak times resolve to one 8-rev window (~1.9 s)"
    if "db1" in zero.index:
        rows += [check(sec, "db1 peak error, zero offset, g", "within ±0.02", float(zero.loc["db1", "peak_error_g"]),
                       accept=(-0.02, 0.02), source="Fig. 13a"),
                 check(sec, "db1 peak time error, zero offset, s", "~1",
                       abs(float(zero.loc["db1", "phase_error_s"])),
                       accept=(0.5, 1.5), fmt=".1f", source="Fig. 13a", note=note),
                 check(sec, "db1 peak error, half segment, g", "within ±0.02", float(half.loc["db1", "peak_error_g"]),
                       accept=(-0.02, 0.02), source="Fig. 14a"),
                 check(sec, "db1 peak time error, half segment, s", "~0",
                       abs(float(half.loc["db1", "phase_error_s"])), accept=(0.0, 0.5), fmt=".1f", source="Fig. 14a")]
    for db, over in (("db2", 0.04), ("db3", 0.10)):
        if db in zero.index:
            rows += [check(sec, f"{db} overshoot, zero offset, g", over, float(zero.loc[db, "peak_error_g"]),
                           tol=0.03, source="Fig. 13b"),
                     check(sec, f"{db} peak time error, zero offset, s", "~3",
                           abs(float(zero.loc[db, "phase_error_s"])), accept=(2.0, 4.0), fmt=".1f",
                           source="Fig. 13b", note=note),
                     check(sec, f"{db} overshoot, half segment, g", over, float(half.loc[db, "peak_error_g"]),
                           tol=0.03, source="Fig. 14b"),
                     check(sec, f"{db} peak time error, half segment, s", "~2",
                           abs(float(half.loc[db, "phase_error_s"])), accept=(1.0, 3.0), fmt=".1f",
                           source="Fig. 14b", note=note)]
    return pd.DataFrame(rows)


def comparison_markdown(rows: pd.DataFrame) -> str:
    """The comparison rows as Markdown, one table per section, with a count of agreements."""
    from ..io import markdown_table

    if rows is None or rows.empty:  # a campaign without the paper's counters
        return ("No number to set beside the paper's: the campaign has neither the pull-up 11022 nor the "
                "autorotation AR60.")
    checked = rows[rows.agrees != "—"]
    lines = [f"{(checked.agrees == 'yes').sum()} of {len(checked)} checked numbers agree with the paper within the "
             "stated criterion; rows without a criterion are shown for the record.", ""]
    for sec, g in rows.groupby("section", sort=False):
        lines += [f"### {sec[0].upper() + sec[1:]}", "",
                  markdown_table(g[["item", "paper", "pvvjax", "criterion", "agrees", "source", "note"]]), ""]
    return "\n".join(lines)
