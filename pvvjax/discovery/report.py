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


def write_discovery(res: Discovery, out, cfg=None, worst: int = 4) -> Path:
    """Write a discovery's outputs to `out`.

    Files: discovery.json, report.md, figures/*.png, windows.{parquet,csv} (held-out
    windows with predictions before and after), rounds.csv (every test of every round),
    localize_<table>.csv, config.toml (if `cfg` is given).

    Returns:
        The path of report.md.
    """
    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    js = summary(res)
    (out / "discovery.json").write_text(_json_text(js, out / "discovery.json"))
    write_table(res.windows, out / "windows", cfg)
    res.tries.to_csv(out / "rounds.csv", index=False)
    for k, t in res.localized.items():
        t.to_csv(out / f"localize_{k.replace(':', '_')}.csv")
    if cfg is not None:
        write_config(cfg, out / "config.toml")
    figs = _figures(res, out / "figures", worst)
    lines = _summary_lines(res, js) + _effect_lines(res, js) + _test_lines(res)
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
        + (f" Fitted lag τ = {res.final.lag_tau_s:.2f} s." if res.final.lag_tau_s > 0 else ""),
        "",
        "## Metrics (held-out counters, medians over seeds; `ensemble_rms_g`: of the median prediction)", "",
        _md(metrics), "",
        f"Gap shrink 1 − after/before RMS: **{js['gap_shrink']:.1%}**.", "",
        "## Effects", "",
    ]
    return lines


def _effect_lines(res: Discovery, js: dict) -> list[str]:
    cap = js["capacity"]
    lines = []
    if cap is not None:
        lines += [f"Capacity of the baseline (is its held-out residual predictable from its own inputs at all): "
                  f"t = {cap['statistic']:.2f}, p = {cap['p_value']:.3g}. Where it is, the misfit is named first "
                  f"by the forms of the inputs that carry it, and taken off the residual. Then the forms of the "
                  f"inputs' history (rates, spreads inside the window, lags of the prediction) are tested beyond "
                  f"the inputs' window values and their composites, and last every other candidate beyond both. "
                  f"Holm's first step at {res.level:g} family-wise over the candidates of each round, conditions "
                  f"as the units.", ""] + _nuisance_lines(js)
        if cap["tied_with_misfit"]:
            lines += ["Passed the screen but explain nothing beyond their shadow (the candidate as the inputs "
                      "predict it), so the data cannot tell them from a misfit of the inputs (tied with the misfit, "
                      "not named as missing): " + ", ".join(f"`{k}`" for k in cap["tied_with_misfit"]) + ".", ""]
    if not js["effects"]:
        return lines + [f"Nothing passed the test at {res.level:g}: the residual holds nothing that the "
                        "candidates explain beyond the model's inputs.", ""]
    eff = pd.DataFrame([dict(rank=e["rank"], name=e["name"], kind=e["kind"], channels=", ".join(e["channels"]),
                             parameters=json.dumps(e["parameters"]), intervals=json.dumps(e["intervals"]),
                             statistic=e["statistic"], adjusted_p=e["adjusted_p"],
                             explained_fraction=e["explained_fraction"], tied=", ".join(e["tied"]) or "none",
                             region=e["region"]["where"], region_before_rms_g=e["region"]["before_rms_g"],
                             region_after_rms_g=e["region"]["after_rms_g"]) for e in js["effects"]])
    if js["augmented"]["worse_than_baseline"]:
        lines += [f"**The model with the named effects predicts worse held out than the baseline** (RMS "
                  f"{res.before['rms_g']:.4f} -> {res.after['rms_g']:.4f} g): what the test named is listed, but "
                  "adding it as fitted did not help; do not take the augmented model as better.", ""]
    return lines + [_md(eff), "",
                    "`kind`: misfit (a function of the model's inputs that it did not learn), history (a form of "
                    "the inputs' history: a response or the window-averaging the model lacks) or missing (a "
                    "channel, or its history, beyond both). `intervals`: each fitted parameter's 5-95 % range over a "
                    "bootstrap of conditions. `tied`: candidates the data cannot tell from it (each has nothing "
                    "left given the other). `region`: where the model with all named effects (the misfit's forms "
                    "as a linear term fitted out of fold, the missing ones in the nets, retrained once) changed the "
                    "held-out prediction, and the RMS there before and after.", ""]


# The columns of a round's tests in the report.
_TEST_SHOWN = ("name", "kind", "statistic", "p_value", "adjusted_p", "theta", "left", "learner", "skill")


def _test_lines(res: Discovery, top: int = 8) -> list[str]:
    if res.tries.empty:
        return []
    lines = ["## The tests, by round", "",
             f"The {top} smallest p-values of each round (`left`: the share of a candidate's variance left after "
             "the model's inputs; a misfit's round: the forms of the inputs, each given the forms named before).", ""]
    for r in res.rounds:
        t = r.tries.sort_values("p_value").head(top)
        lines += [f"Round {r.number}" + (f": named {r.named.name}" if r.named is not None else ": nothing passed"),
                  "", _md(t[[c for c in _TEST_SHOWN if c in t]]), ""]
    return lines


def _nuisance_lines(js: dict) -> list[str]:
    """The nuisance regressions' out-of-fold skill per round (1 − SSE/SST: 0 is the mean's)."""
    rows = js.get("nuisance") or []
    if not rows:
        return []
    return ["The nuisance regressions, per round (out-of-fold skill 1 − SSE/SST; each target keeps the best of the "
            "mean, an additive spline and trees, so none is below 0):", "", _md(pd.DataFrame(rows)), ""]


def report_section(res: Discovery, scenario: str, hidden: list[str], folder: str = "discovery/") -> list[str]:
    """The main job's report section of a discovery on a hidden-effect scenario written to
    `folder` (relative to the report): what the generator hid (`hidden`, read after the
    run), the named effects, the gap it closed and its figures."""
    js = summary(res)
    lines = ["## Discovery on a hidden-effect scenario", "",
             f"Scenario `{scenario}`; generator settings that differ from the default physics (its ground truth, "
             f"read after the run): {', '.join(hidden) or 'none'}.", "",
             "| rank | named effect | kind | channels | adjusted p | region |", "|---|---|---|---|---|---|"]
    for e in js["effects"]:
        lines.append(f"| {e['rank']} | {e['name']} | {e['kind']} | {', '.join(e['channels'])} | "
                     f"{e['adjusted_p']:.3g} | {e['region']['where']} |")
    lines += ["", f"Held-out RMS {js['baseline']['metrics']['rms_g']:.4f} g before, "
                  f"{js['augmented']['metrics']['rms_g']:.4f} g after (gap shrink {js['gap_shrink']:.1%}). "
                  f"Full report: [{folder}report.md]({folder}report.md).", "",
              f"![residual map]({folder}figures/residual_map.png)", ""]
    for e in js["effects"]:
        lines += [f"![effect {e['rank']}]({folder}figures/effect_{e['rank']}.png)", ""]
    return lines
