"""Files of a discovery run: `discovery.json` (data-contract §3), `report.md` with its
plots, and the tables behind them (the imperative shell around `discovery`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from .. import plots
from ..io import markdown_table, write_config, write_table
from . import Discovery, summary

__all__ = ["report_section", "write_discovery"]


def _md(df: pd.DataFrame) -> str:
    return markdown_table(df, "{:.4g}")


def _metrics_row(label, m):
    return dict(model=label, rms_g=m["rms_g"], ensemble_rms_g=m["ensemble_rms_g"], peak_error_g=m["peak_error_g"],
                phase_error_s=m["phase_error_s"], rms_by_seed=", ".join(f"{v:.4f}" for v in m["rms_by_seed"]))


def _json_text(js: dict, path) -> str:
    """`js` as strict JSON: NaN is not JSON, and a reader of the contract would fail on the
    file rather than here."""
    try:
        return json.dumps(js, indent=2, allow_nan=False)
    except ValueError as e:
        raise ValueError(f"{path}: a value is not a finite number: {js}") from e


def _also_confirmed(rounds: pd.DataFrame, rnd: int, name: str) -> str:
    """The confirmed tries of a round other than the named effect, best first."""
    t = rounds[(rounds["round"] == rnd) & rounds["confirmed"] & (rounds["name"] != name)]
    t = t.sort_values("shrink", ascending=False).drop_duplicates("name")
    return "; ".join(f"{r.name} ({r.augment}, {r.shrink:.1%})" for r in t.itertuples()) or "none"


def write_discovery(res: Discovery, out, cfg=None, worst: int = 4) -> Path:
    """Write a discovery's outputs to `out`.

    Files: discovery.json, report.md, figures/*.png, windows.{parquet,csv} (held-out
    windows with predictions before and after), rounds.csv (every proposal tried),
    lag_test.csv (with the lag test), localize_<table>.csv, config.toml (if `cfg` is given).

    Returns:
        The path of report.md.
    """
    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    js = summary(res)
    (out / "discovery.json").write_text(_json_text(js, out / "discovery.json"))
    write_table(res.windows, out / "windows", cfg)
    res.tries.to_csv(out / "rounds.csv", index=False)
    if res.lag_test is not None:
        res.lag_test.to_csv(out / "lag_test.csv", index=False)
    for k, t in res.localized.items():
        t.to_csv(out / f"localize_{k.replace(':', '_')}.csv")
    if cfg is not None:
        write_config(cfg, out / "config.toml")
    figs = _figures(res, out / "figures", worst)
    lines = _summary_lines(res, js) + _effect_lines(res, js) + _lag_lines(res) + _round_lines(res)
    loc = res.localized["maneuver"].reset_index().rename(columns={"key": "maneuver"})
    lines += ["## Residual by maneuver (baseline)", "", _md(loc), ""]
    lines += ["## Wall time, s", "", _md(pd.DataFrame([res.seconds])), ""]
    for title, path in figs:
        lines += [f"### {title}", "", f"![{title}](figures/{path.name})", ""]
    (out / "report.md").write_text("\n".join(lines))
    return out / "report.md"


def _figures(res: Discovery, folder: Path, worst: int) -> list[tuple[str, Path]]:
    """The residual map, each effect's partial dependence and the `worst` counters' replays
    before and after: (title, file) each."""
    figs = []
    fig = plots.residual_map(res.localized, f"held-out residual of the {res.database} baseline "
                                            f"(offset {res.baseline.offset_s:.2f} s)")
    figs.append(("Where the baseline misses", plots.save(fig, folder / "residual_map.png")))
    w = res.windows[res.windows.weight >= 0.999]
    for e in res.effects:
        col = f"effect_{e.rank}"
        if col not in w:
            continue
        ok = w.predicted_after_g.notna()
        unit = " × prediction, g" if e.operator == "resonance" else ""
        fig = plots.partial_dependence(w[col][ok], (w.measured_g - w.predicted_before_g)[ok],
                                       (w.predicted_after_g - w.predicted_before_g)[ok],
                                       f"effect {e.rank}: {e.name}", f"{e.name} (window value{unit})")
        figs.append((f"Partial dependence of effect {e.rank}",
                     plots.save(fig, folder / f"effect_{e.rank}.png")))
    rms = w.groupby("counter").apply(lambda g: float(np.sqrt(np.mean((g.measured_g - g.predicted_before_g) ** 2))),
                                     include_groups=False).sort_values(ascending=False)
    for counter in rms.index[:worst]:
        g = w[w.counter == counter]
        series = {"baseline": g.assign(predicted_g=g.predicted_before_g),
                  "augmented": g.assign(predicted_g=g.predicted_after_g)}
        fig = plots.replay(series, f"counter {counter} ({g.maneuver.iloc[0]}): held-out replay before and after")
        figs.append((f"Before and after: {counter}", plots.save(fig, folder / f"replay_{counter}.png")))

    return figs


def _summary_lines(res: Discovery, js: dict) -> list[str]:
    metrics = pd.DataFrame([_metrics_row("baseline", res.before), _metrics_row("augmented", res.after)])
    lines = [
        "# Discovery report", "",
        f"Campaign: `{res.campaign}`. Model: {res.database} nets, held-out by condition, median over seeds. "
        f"Offset {res.baseline.offset_s:.2f} s (baseline) and {res.final.offset_s:.2f} s (augmented)."
        + (f" Learned lag τ = {res.final.lag_tau_s:.2f} s." if res.final.lag_tau_s > 0 else "")
        + (" The baseline is the lag test's reference: window nets"
           + (f" trained through a {res.baseline.lag_tau_s:g} s lag" if res.baseline.lag_tau_s > 0 else "")
           + ", so that before and after measure the lag, not the training rows." if res.baseline.through_lag else ""),
        "",
        "## Metrics (held-out counters, medians over seeds; `ensemble_rms_g`: of the median prediction)", "",
        _md(metrics), "",
        f"Gap shrink 1 − after/before RMS: **{js['gap_shrink']:.1%}**.", "",
        "## Effects", "",
    ]
    return lines


def _effect_lines(res: Discovery, js: dict) -> list[str]:
    if not js["effects"]:
        return ["No candidate was both significant and confirmed by retraining: the model explains this "
                "campaign as well as its error floor allows.", ""]
    eff = pd.DataFrame([dict(rank=e["rank"], name=e["name"], operator=e["operator"],
                             channels=", ".join(e["channels"]), parameters=json.dumps(e["parameters"]),
                             explained_fraction=e["explained_fraction"], p_value=e["p_value"],
                             region=e["region"]["where"], region_before_rms_g=e["region"]["before_rms_g"],
                             region_after_rms_g=e["region"]["after_rms_g"],
                             also_confirmed=_also_confirmed(res.tries, r.round, e["name"]))
                        for e, r in zip(js["effects"], res.effects)])
    return [_md(eff), "",
              "`also_confirmed`: the other tries of the same round that confirmed, with the drop of the held-out "
              "RMS over all windows each gave: the data may not tell them from the named effect (e.g. a "
              "collective knee and a shaft-power knee, when power follows collective).", ""]


def _lag_lines(res: Discovery) -> list[str]:
    if res.lag_test is None:
        return []
    return ["## Lag test (round 0)", "",
              "A lag is named if the time constant learned jointly with window nets at the lowest offset "
              "(row `learned`: the median over folds × seeds, and its range) is at least `lag_test.slow_s`: it "
              "takes the delay and the fast dynamics of inflow and wake as well. Window nets trained through "
              "a lag of each τ (the targets de-lagged), replayed with it, their offset refitted, add it: the "
              "reference is the best without a lag or with one of at most `LAG_FAST_S`, the slow lag the "
              "best above it (round 0 below; its gain and a sign-flip test by condition are reported, not "
              "required). Where no lag is confirmed those trainings decide nothing and are skipped, unless "
              "`discover(..., lag_trials=True)`.", "", _md(res.lag_test), ""]


def _round_lines(res: Discovery) -> list[str]:
    if res.tries.empty:
        return []
    controlled = "control_shrink" in res.tries and bool(res.tries.control_shrink.notna().any())
    refit = "window_refit_kept" in res.tries
    way_tie = "p_input_better" in res.tries and bool(res.tries.p_input_better.notna().any())
    lines = ["## Every proposal tried", "",
              "A round proposes the candidates the selection cannot tell apart (held-out errors within one "
              "standard error of the best's: the simplest, the one that explains most, then the others); each is "
              "added as a term (`additive`) and as a network `input`, "
              "a resonance as a learned `gain` on the nets' output, the nets retrained each time; of the "
              "confirmed tries the round names (`chosen`) the one that shrinks the held-out RMS most, unless "
              "others tie with it: within `SHRINK_NOISE` of its shrink, or not beaten by it at p < `selection.alpha` "
              "(`p_best_better`: a sign-flip test by condition of the two ensembles' squared errors) with at "
              "least `TIE_SHARE` of its shrink; of tied "
              "tries, those that lower the RMS by `min_shrink` on top of their floor control come first, then "
              "the one with the largest `cv_gain`. A weak name (none of its proposal's confirmed tries does so) "
              "gets a second opinion: the selection's best runner-up built from other channels than the round's "
              "proposals is retrained too (`source` rival) and the round chooses again. With `selection.source_tries`, "
              "the candidates of the best gain built only from channels a derived input hides (db1's load "
              "factor: the roll angle and the pitch rate) are tried too (`source` source).", "",
              "`rms_*`: held-out RMS, median over seeds (as the metrics above); `ensemble_rms_*`: the RMS of "
              "the ensemble's prediction (the median over seeds), whose change `shrink` (all windows) and "
              "`region_shrink` (where the effect acts, `judged_in`) decide the confirmation; `why_not`: "
              "why a try is not confirmed." + (
                  " `control_shrink`, `control_region_shrink`: the same try added to the floor control (the "
                  "model retrained with its selection's floor refinements as inputs), where it must confirm "
                  "again; `over_control_shrink`, `over_control_region_shrink`: the try's "
                  "own model against the control, which it may beat instead." if controlled else "") + (
                  " `window_refit_*`: the named term refitted on nets trained on the "
                  "windows, its coefficient and ensemble's RMS after, and whether that model confirmed too and "
                  "replaced the try." if refit else "") + (
                  " `p_input_better` (on a term's row): that its proposal's "
                  "input, confirmed, predicts better than the term (by condition); where the named input's "
                  "term ties with it, the term is named, confirmed alone or not." if way_tie else ""), "",
              _md(res.tries[["round", "name", *(["source"] if "source" in res.tries else []), "augment",
                              "p_value", "cv_gain", "rms_before_g", "rms_after_g",
                              "ensemble_rms_before_g", "ensemble_rms_after_g", "shrink", "judged_in",
                              "region_shrink", *(["control_shrink", "control_region_shrink", "over_control_shrink",
                                                "over_control_region_shrink"] if controlled else []),
                              "confirmed", "why_not", "p_best_better", *(["p_input_better"] if way_tie else []),
                              "chosen",
                              *(["window_refit_coefficient", "window_refit_ensemble_rms_g",
                                 "window_refit_kept"] if refit else [])]]), "",
              "Runners-up of each proposal (held-out gain):", ""]
    lines += [f"- round {r.round}, {r.name} ({r.cv_gain:.3f}): {r.runners_up}"
              for r in res.tries.drop_duplicates(["round", "name"]).itertuples()
              if isinstance(r.runners_up, str) and r.runners_up]
    lines += [""]
    first = res.tries.drop_duplicates("round")
    floor = [(r, t) for r, t in zip(first["round"], first.get("floor_terms", [""] * len(first)))
             if isinstance(t, str) and t]
    if floor:
        lines += ["Refinements of the model's own inputs that joined each round's floor covariates before the "
                  "candidates were asked (`FLOOR_REFINEMENTS`; held-out gain): the map's floor, not effects.", ""]
        lines += [f"- round {rnd}: {terms}" for rnd, terms in floor] + [""]
    return lines


def report_section(res: Discovery, scenario: str, hidden: list[str], folder: str = "discovery/") -> list[str]:
    """The main job's report section of a discovery on a hidden-effect scenario written to
    `folder` (relative to the report): what the generator hid (`hidden`, read after the
    run), the named effects, the gap it closed and its figures."""
    js = summary(res)
    lines = ["## Discovery on a hidden-effect scenario", "",
             f"Scenario `{scenario}`; generator settings that differ from the default physics (its ground truth, "
             f"read after the run): {', '.join(hidden) or 'none'}.", "",
             "| rank | named effect | operator | channels | p-value | region |", "|---|---|---|---|---|---|"]
    for e in js["effects"]:
        lines.append(f"| {e['rank']} | {e['name']} | {e['operator']} | {', '.join(e['channels'])} | "
                     f"{e['p_value']:.3g} | {e['region']['where']} |")
    lines += ["", f"Held-out RMS {js['baseline']['metrics']['rms_g']:.4f} g before, "
                  f"{js['augmented']['metrics']['rms_g']:.4f} g after (gap shrink {js['gap_shrink']:.1%}). "
                  f"Full report: [{folder}report.md]({folder}report.md).", "",
              f"![residual map]({folder}figures/residual_map.png)", ""]
    for e in js["effects"]:
        lines += [f"![effect {e['rank']}]({folder}figures/effect_{e['rank']}.png)", ""]
    return lines
