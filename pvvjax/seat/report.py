"""The three-axis study's files and report (`pvvjax axes`, the main job's `[run] axes`), and
`build-db`'s per-axis peak tables: the imperative shell around `seat.study`."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from ..io import markdown_table, write_table
from .study import AxesStudy, run_axes

__all__ = ["axis_summary", "axis_table_name", "report_section", "run_study", "write_axis_tables"]


def axis_table_name(axis: str, harmonic: int) -> str:
    """File stem of the peak table of one axis and harmonic, e.g. `peaks-ay_g-4rev`."""
    return f"peaks-{axis}-{harmonic}rev"


def write_axis_tables(tables: dict, out: Path, cfg) -> list[str]:
    """Each table of `analysis.axis_peak_tables` as `out/peaks-AXIS-Krev.csv` and `.parquet`.

    Returns:
        The stems written."""
    names = []
    for (axis, k), df in tables.items():
        names.append(axis_table_name(axis, k))
        write_table(df, out / names[-1], cfg)
    return names


def axis_summary(tables: dict) -> str:
    """One line per axis and harmonic: the range of the condition peaks and the maneuver kind
    whose median peak is highest."""
    from ..analysis.databases import OUTPUT

    lines = ["peaks per axis and harmonic (g):"]
    for (axis, k), df in tables.items():
        by_kind = df.groupby("maneuver")[OUTPUT].median()
        lines.append(f"  {axis} {k}/rev: {df[OUTPUT].min():.3f}-{df[OUTPUT].max():.3f}, median "
                     f"{df[OUTPUT].median():.3f}; highest median: {by_kind.idxmax()} {by_kind.max():.3f}")
    return "\n".join(lines)


def run_study(cfg, campaign, campaign_dir, out, *, log=print) -> tuple:
    """`pvvjax axes`: claim `out` for the config's `[axes]`, `[train]`, `[analysis]` and seed
    on this campaign, record the config (`config.toml`, with the campaign's folder: what
    `export --element` reads), run the study (`seat.run_axes`) and, with `[axes] discovery`,
    the discovery on every axis no database suffices for (`discovery-<axis>/`).

    Returns:
        (the folder, `AxesStudy`, {axis: the discovery's summary}).
    """
    from .._strict import to_dict
    from ..io import claim_folder, write_config

    n_cond = len(campaign.conditions())
    if cfg.axes.folds > n_cond:  # refused before the folder is claimed
        raise ValueError(f"axes.folds = {cfg.axes.folds}: campaign {campaign.source} has {n_cond} condition(s); a "
                         "k-fold split by condition needs at least k")
    settings = dict(command="axes", axes=to_dict(cfg.axes), train=to_dict(cfg.train), analysis=to_dict(cfg.analysis),
                    seed=cfg.seed, columns=to_dict(cfg.campaign)["columns"])
    out = claim_folder(out, settings, campaign.fingerprint, kind="axes")
    write_config(cfg.with_(campaign=dataclasses.replace(cfg.campaign, path=str(campaign_dir), synthetic="")),
                 out / "config.toml")
    study = run_axes(campaign, cfg, out, log)
    write_table(study.table, out / "axes", cfg)
    write_table(study.needs, out / "needs", cfg)
    study.predictions.to_parquet(out / "predictions.parquet", index=False)
    found = {}
    if cfg.axes.discovery:
        from ..discovery import discover, summary
        from ..discovery.report import write_discovery

        quiet = set(study.table.axis[study.table.status == "no vibration"])
        for axis in [a for a in study.needs.axis[study.needs.database == ""] if a not in quiet]:
            log(f"axes: no database suffices for {axis}: discovery on it")
            acfg = cfg.with_(analysis=dataclasses.replace(cfg.analysis, axis=axis))
            res = discover(campaign, acfg, name=str(campaign_dir), log=log)
            write_discovery(res, out / f"discovery-{axis}", acfg)
            found[axis] = summary(res)
    (out / "report.md").write_text("\n".join(_markdown(study, found, cfg)))
    return out, study, found


def _markdown(study: AxesStudy, found: dict, cfg, folder: str = "", level: str = "#") -> list[str]:
    ac = cfg.axes
    lines = [f"{level} The pilot's seat in three axes: which inputs each axis needs", "",
             f"Nets of one output per axis ({'-'.join(map(str, ac.hidden))} hidden), {ac.folds}-fold by condition x "
             f"{ac.seeds} seeds, each axis judged on its own peaks of held-out conditions: RMS error, FAA Part 60 test "
             "3.f.1 pass share (+3/-6 dB, or 10 % of the axis's nominal cruise level: the median peak of level flights "
             f"at advance ratio {ac.cruise_advance_ratio[0]:g}-{ac.cruise_advance_ratio[1]:g}) and Kendall's tau. An "
             f"axis needs the first database that passes on {ac.pass_share:.0%} of conditions.", "",
             markdown_table(study.table.drop(columns="fails"), "{:.4g}"), ""]
    lines += [f"- {t}" for t in study.needs.text] + [""]
    lines += ["Held-out FAA 3.f.1 failures by maneuver kind:", "",
              markdown_table(study.table[["axis", "database", "fails"]]), ""]
    for axis, js in found.items():
        named = ", ".join(f"{e['name']} ({e['operator']})" for e in js["effects"]) or "nothing"
        lines += [f"Discovery on {axis} ([{folder}discovery-{axis}/report.md]({folder}discovery-{axis}/report.md)): "
                  f"names {named}; held-out RMS {js['baseline']['metrics']['rms_g']:.4f} g -> "
                  f"{js['augmented']['metrics']['rms_g']:.4f} g (gap shrink {js['gap_shrink']:.1%}).", ""]
    return lines


def report_section(study: AxesStudy, found: dict, cfg, folder: str = "axes/") -> list[str]:
    """The main job's report section of a study written to `folder` (relative to the report)."""
    return _markdown(study, found, cfg, folder, level="##") + [
        f"Full tables: [{folder}axes.csv]({folder}axes.csv), every row's held-out prediction: "
        f"[{folder}predictions.parquet]({folder}predictions.parquet).", ""]
