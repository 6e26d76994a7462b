"""The comparison of PVV models through time as files (`pvvjax dynamic`): every model of
`[dynamic] models`, for every database, trained on the same window sequences and held out
the same way, scored as a simulator is qualified, and written where a script reads it.

Each (database, split, model) is a part, saved in `parts/` as it finishes, so a stopped run
resumes where it stopped; the tables and the report are written from the parts at the end.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import NamedTuple

import jax
import numpy as np
import pandas as pd

from ..analysis.databases import DB_INPUTS, OUTPUT, build_databases
from ..config import DYNAMIC_MODELS
from ..interrupts import check_interrupt
from ..realtime.npnet import read_npz, write_npz
from . import compare
from .checks import ResponseLimits, check_dynamic, parameter_problems, prediction_problems, response_limits
from .models import identified
from .reporting import figures, report
from .scores import heldout_scores, nominal_cruise, rms_by_kind, row_peaks
from .sequences import Sequences, window_sequences

__all__ = ["EXPORTABLE", "Database", "ElementModel", "comparison_table", "element_model", "identified_rows",
           "kind_table", "predictions_table", "prepare_database", "run_comparison", "run_dynamic", "run_parts",
           "sequence_limits"]

# Models the real-time element runs (`pvvjax export --element`): every model compared.
EXPORTABLE = DYNAMIC_MODELS
# Models that map each window on its own: they train on the real windows alone.
POINTWISE = ("window_static", "window_static_rates")


def _terminal_progress(label: str):
    """On a terminal, a line that training rewrites as it goes: the model, the step, the
    best validation RMS and the nets still training (None elsewhere: logs keep the
    one line per part that `run_parts` writes)."""
    import sys

    if not sys.stderr.isatty():
        return None

    def show(step, best_val, running):
        end = "\n" if running == 0 else ""
        sys.stderr.write(f"\r{label}: step {step}, best validation RMS {best_val:.4f} g, {running} nets "
                         f"training{end}")
        sys.stderr.flush()
    return show


class Database(NamedTuple):
    """One database's sequences and what every model of it is judged on.

    Attributes:
        name: db1, db2 or db3.
        seq: the window sequences (rows: conditions, their segments joined).
        long: the same rows over the quasi-static map's long windows.
        peak_x: (R, C) the database's inputs at each condition's peak (the paper's rows).
        peak_y: (R,) their peak PVV, g.
        splits: the held-out splits (by condition, then by maneuver kind where the campaign
            allows one).
        nominal_g: the nominal cruise level of the FAA tolerance, g.
        skipped: why a split asked for is not there (e.g. the kind split of a campaign of
            one maneuver kind), for the report.
    """

    name: str
    seq: Sequences
    long: Sequences
    peak_x: np.ndarray
    peak_y: np.ndarray
    splits: tuple
    nominal_g: float
    skipped: tuple[str, ...] = ()


def prepare_database(campaign, cfg, db: str) -> Database:
    """The sequences, peaks, splits and cruise level of database `db` (`cfg`: an
    `ExperimentConfig`; its `[dynamic]`, `[analysis]` and `seed`)."""
    dc, inputs = cfg.dynamic, DB_INPUTS[db]
    seq = window_sequences(campaign, inputs, window_revs=dc.window_revs, hop_revs=dc.hop_revs, rates=True,
                           chain=True, harmonic=cfg.analysis.harmonic, axis=cfg.analysis.axis)
    long = window_sequences(campaign, inputs, window_revs=cfg.analysis.window_revs, hop_revs=dc.hop_revs,
                            chain=True, harmonic=cfg.analysis.harmonic, axis=cfg.analysis.axis)
    peaks = build_databases(campaign, cfg.analysis)["peaks"].set_index("condition").loc[list(seq.conditions)]
    measured, _ = row_peaks(seq.amplitude, seq.mask, seq.time)
    nominal = nominal_cruise(measured, seq.maneuvers, peaks["advance_ratio"].to_numpy(), dc.cruise_advance_ratio)
    splits, skipped = [compare.condition_split(seq.conditions, dc.folds, cfg.seed)], []
    if dc.kind_holdout:
        kinds = compare.kind_split(seq.conditions, seq.maneuvers, dc.folds, cfg.seed)
        why = compare.split_problem(kinds)
        if why:
            skipped.append(f"the split by maneuver kind (dynamic.kind_holdout) is not scored: {why}")
        else:
            splits.append(kinds)
    return Database(db, seq, long, peaks[list(inputs)].to_numpy(np.float64), peaks[OUTPUT].to_numpy(np.float64),
                    tuple(splits), nominal, tuple(skipped))


def _train(d: Database, split, model: str, cfg, progress=None) -> tuple[dict, dict]:
    """Train one model of one split: (stacked params, arrays: heldout (R, W) and per-net
    best_step, failed_step, and the quasi-static offsets)."""
    dc, seq = cfg.dynamic, d.seq
    if model == "quasi_static":
        t = compare.fit_peak_map(d.peak_x, d.peak_y, split, dc.seeds, dc.hidden, cfg.train)
        grid = np.arange(dc.offset_bounds[0], dc.offset_bounds[1] + 1e-9, dc.offset_step_s)
        every, offsets = compare.offset_replay(t.params, d.long.inputs, d.long.time, seq.time, seq.amplitude,
                                               seq.mask, split, grid)
        held = compare.heldout(every[:, None], split)
        extra = {"offset_s": offsets}
    else:
        x = compare.model_inputs(seq, model)
        if model == "dynamic":
            init = compare.dynamic_model_init(x.shape[-1] - 1, dc.hidden, dc)
        elif model == "rnn":
            init = compare.recurrent_init(x.shape[-1], dc.rnn_hidden)
        else:
            init = compare.static_init(x.shape[-1], dc.hidden)
        train_cfg = dataclasses.replace(cfg.train, learning_rate=dc.learning_rate)
        t = compare.fit_sequence_model(init, compare.APPLY[model], x, seq.amplitude, seq.mask, split, dc.seeds,
                                       train_cfg, pointwise=model in POINTWISE, progress=progress,
                                       pieces=None if model in POINTWISE else _pieces(seq, dc.burn_in_s))
        held, extra = compare.heldout(t.pred, split), {}
    return t.params, dict(heldout=held, best_step=t.best_step, failed_step=t.failed_step, **extra)


def _pieces(seq: Sequences, burn_in_s: float) -> tuple[int, int] | None:
    """`compare.fit_sequence_model`'s pieces for a burn-in of `burn_in_s` seconds: (3 burn-ins,
    a burn-in) in windows at the sequence's median window spacing; None (whole records) for 0."""
    if burn_in_s <= 0:
        return None
    steps = np.diff(seq.time, axis=1)[seq.mask[:, 1:]]
    burn = max(1, int(np.ceil(burn_in_s / float(np.median(steps)))))
    return 3 * burn, burn


def _part(folder: Path, d: Database, split, model: str, cfg, log) -> tuple:
    """A part from `folder` if a run saved it, else trained and saved (arrays first, the
    parameter file last: its presence marks the part done)."""
    stem = folder / f"{d.name}-{split.name}-{model}"
    if (stem.with_suffix(".params.npz")).exists():
        params, _ = read_npz(stem.with_suffix(".params.npz"))
        with np.load(stem.with_suffix(".arrays.npz"), allow_pickle=False) as z:
            arrays = dict(z)
        log(f"  {d.name} {split.name} {model}: saved part")
    else:
        t0 = time.perf_counter()
        params, arrays = _train(d, split, model, cfg, _terminal_progress(f"  {d.name} {split.name} {model}"))
        folder.mkdir(parents=True, exist_ok=True)
        tmp = stem.with_suffix(".arrays.tmp.npz")
        np.savez(tmp, **arrays)
        tmp.replace(stem.with_suffix(".arrays.npz"))
        write_npz(stem.with_suffix(".params.npz"), jax.tree.map(np.asarray, params), {"model": model})
        log(f"  {d.name} {split.name} {model}: trained in {time.perf_counter() - t0:.0f} s")
    return compare.Trained(params, arrays["heldout"], arrays["best_step"], arrays["failed_step"]), arrays


def run_parts(campaign, cfg, folder: Path, log=print) -> dict:
    """Every (database, split, model) part, resumed from `folder` or trained there.

    Returns:
        {database: (Database, {split name: {model: (Trained with `pred` the held-out (R, W)
        prediction, its arrays)}})}.
    """
    out = {}
    for db in cfg.dynamic.databases:
        d = prepare_database(campaign, cfg, db)
        by_split = {}
        for split in d.splits:
            done, arrays = {}, {}
            for model in cfg.dynamic.models:
                done[model], arrays[model] = _part(folder, d, split, model, cfg, log)
                check_interrupt()
            by_split[split.name] = {m: (done[m], arrays[m]) for m in done}
        out[db] = (d, by_split)
    return out


def comparison_table(parts: dict, cfg) -> pd.DataFrame:
    """One row per (database, model): the held-out scores by condition (`scores.heldout_scores`),
    the window RMS with each maneuver kind held out, the identified response (median over
    folds and seeds, with its range), `degenerate` (why the model cannot be trusted:
    `checks`; empty when it can), `notes` (why a score is NaN), and `best`: the model of
    the lowest window RMS among those not degenerate (none, when every one is); the
    element runs every one (`EXPORTABLE`)."""
    rows = []
    for db, (d, by_split) in parts.items():
        seq = d.seq
        limits = sequence_limits(seq)
        for model, (t, arrays) in by_split["condition"].items():
            held = arrays["heldout"]
            row = dict(database=db, model=model, **heldout_scores(held, seq.amplitude, seq.mask, seq.time,
                                                          seq.maneuvers, cfg.dynamic.transients, d.nominal_g))
            notes = [row.pop("notes")] if row["notes"] else []
            if "maneuver" in by_split:
                kind = by_split["maneuver"][model][1]["heldout"]
                row["rms_kind_holdout_g"] = heldout_scores(kind, seq.amplitude, seq.mask, seq.time, seq.maneuvers,
                                                   cfg.dynamic.transients, d.nominal_g)["rms_g"]
            elif cfg.dynamic.kind_holdout:
                row["rms_kind_holdout_g"] = float("nan")
                notes += list(d.skipped)
            row["nominal_cruise_g"] = d.nominal_g
            row["median_best_step"] = float(np.median(arrays["best_step"]))
            failed = int((np.asarray(arrays["failed_step"]) >= 0).sum())
            row["failed_nets"] = failed
            if model == "quasi_static":
                row["offset_s"] = float(np.median(arrays["offset_s"]))
            if model == "dynamic":
                row.update(_identified_summary(t.params))
            problems = (prediction_problems(held, seq.amplitude, seq.mask, seq.conditions)
                        + parameter_problems(t.params, limits if model == "dynamic" else None))
            if 2 * failed > np.size(arrays["failed_step"]):
                problems.append(f"{failed} of {np.size(arrays['failed_step'])} nets diverged")
            if not np.isfinite(row["rms_g"]):
                problems.append("no finite window RMS")
            row["degenerate"], row["notes"] = "; ".join(problems), "; ".join(notes)
            rows.append(row)
    table = pd.DataFrame(rows)
    ok = table[(table.degenerate == "") & np.isfinite(table.rms_g)]
    table["best"] = False
    if len(ok):
        table.loc[ok.rms_g.idxmin(), "best"] = True
    return table


def kind_table(parts: dict) -> pd.DataFrame:
    """Where each model wins or loses: one row per (database, model, maneuver kind) of the
    split by condition, its held-out window RMS (`scores.rms_by_kind`, g) and its real
    windows (`windows`)."""
    rows = []
    for db, (d, by_split) in parts.items():
        seq = d.seq
        kinds = np.asarray(seq.maneuvers)
        for model, (_, arrays) in by_split["condition"].items():
            for kind, rms in rms_by_kind(arrays["heldout"], seq.amplitude, seq.mask, seq.maneuvers).items():
                rows.append(dict(database=db, model=model, maneuver=kind, rms_g=rms,
                                 windows=int(seq.mask[kinds == kind].sum())))
    return pd.DataFrame(rows)


def sequence_limits(seq: Sequences) -> ResponseLimits:
    """The `checks.ResponseLimits` of a sequence's rows: their median duration and window
    spacing, s."""
    steps, durations = [], []
    for t, m in zip(seq.time, seq.mask):
        t = t[m]
        durations.append(t[-1] - t[0])
        steps.extend(np.diff(t))
    return response_limits(float(np.median(durations)), float(np.median(steps)) if steps else 1.0)


def _identified_summary(params: dict) -> dict:
    flat = jax.tree.map(lambda a: np.asarray(a).reshape((-1,) + np.shape(a)[2:]), params)
    ident = compare.identified_table(flat)
    out = {}
    for k in ("f_n_hz", "zeta", "delay_s", "tau_equivalent_s", "tau_slow_pole_s"):
        v = np.asarray(ident[k], float)
        out[k], out[f"{k}_lo"], out[f"{k}_hi"] = float(np.median(v)), float(v.min()), float(v.max())
    return out


def identified_rows(parts: dict) -> pd.DataFrame:
    """The dynamic model's identified response per (database, split, fold, seed)."""
    rows = []
    for db, (d, by_split) in parts.items():
        for split in d.splits:
            if "dynamic" not in by_split[split.name]:
                continue
            params = by_split[split.name]["dynamic"][0].params
            ident = compare.identified_table(params)
            for f, label in enumerate(split.labels):
                for s in range(np.shape(ident["zeta"])[1]):
                    rows.append(dict(database=db, split=split.name, fold=label, seed=s,
                                     **{k: float(np.asarray(v)[f, s]) for k, v in ident.items()}))
    return pd.DataFrame(rows)


def predictions_table(parts: dict) -> pd.DataFrame:
    """Every window of every held-out condition (by condition): counter, maneuver, fold,
    database, model, t_start_s, t_end_s (on the counter's own clock), pvv_g, measured_g."""
    frames = []
    for db, (d, by_split) in parts.items():
        seq, split = d.seq, d.splits[0]
        fold = np.argmax(split.test, axis=0)
        r, w = np.nonzero(seq.mask)
        base = dict(counter=seq.record[r, w].astype(str), maneuver=np.asarray(seq.maneuvers)[r], fold=fold[r],
                    database=db, t_start_s=seq.t_start[r, w], t_end_s=seq.t_end[r, w],
                    measured_g=seq.amplitude[r, w])
        for model, (t, arrays) in by_split["condition"].items():
            frames.append(pd.DataFrame({**base, "model": model, "pvv_g": arrays["heldout"][r, w]}))
    cols = ["counter", "maneuver", "fold", "database", "model", "t_start_s", "t_end_s", "pvv_g", "measured_g"]
    return pd.concat(frames, ignore_index=True)[cols]


def run_comparison(campaign, cfg, out: Path, log=print) -> pd.DataFrame:
    """Train (or resume) every part in `out/parts`, then write comparison.csv/.parquet (with
    `config_hash` and `campaign` fingerprint columns), identified.csv, by_kind.csv/.parquet
    (`kind_table`), predictions.parquet, the figures and report.md into `out`. Returns the
    comparison table."""
    from .._strict import to_dict
    from ..config import config_hash
    from ..io import write_table

    parts = run_parts(campaign, cfg, out / "parts", log)
    table = comparison_table(parts, cfg)
    table["config_hash"] = config_hash({k: to_dict(getattr(cfg, k)) for k in ("dynamic", "train", "analysis")},
                                       campaign.fingerprint)
    table["campaign"] = campaign.fingerprint
    write_table(table, out / "comparison", cfg.dynamic)
    ident = identified_rows(parts)
    if len(ident):
        write_table(ident, out / "identified", cfg.dynamic)
    kinds = kind_table(parts).assign(config_hash=table.config_hash.iloc[0], campaign=campaign.fingerprint)
    write_table(kinds, out / "by_kind", cfg.dynamic)
    pred = predictions_table(parts)
    tmp = out / "predictions.tmp.parquet"
    pred.to_parquet(tmp, index=False)
    tmp.replace(out / "predictions.parquet")
    report(table, ident, figures(parts, cfg, out), out, kinds)
    return table


class ElementModel(NamedTuple):
    """What the real-time element takes from a comparison folder (`element_model`).

    Attributes:
        model, database: which model of which database.
        nets: one (parameters, metadata) per fold and seed of the condition split: the
            static maps whose median the element predicts.
        response: the median identified response (omega_n_rad_s, zeta, delay_s), or None.
        window_revs, hop_revs, offset_s: the windows the model was judged on, and the
            quasi-static replay's calibrated offset (0 for the others).
    """

    model: str
    database: str
    nets: list
    response: dict | None
    window_revs: float
    hop_revs: float
    offset_s: float


def element_model(folder: Path, cfg, model: str | None = None, database: str | None = None) -> ElementModel:
    """A model of the comparison in `folder` for the element: the `best` row's (default; of
    `database` when given), or `model` of `database` (one of `EXPORTABLE`). `cfg`: the
    folder's config.toml. A degenerate model (`comparison_table`) is refused unless named
    with `model`, and then exported with a warning naming it and why."""
    import warnings

    where = Path(folder) / "comparison.parquet"
    table = pd.read_parquet(where)
    if "degenerate" not in table:
        table["degenerate"] = ""
    if model is None:
        pick = table[table.best & ((table.database == database) if database else True)]
        if pick.empty:
            pool = table if database is None else table[table.database == database]
            if pool.empty:
                raise ValueError(f"{where}: no model of {database}: it compares "
                                 f"{', '.join(dict.fromkeys(table.database))}")
            why = "; ".join(f"{r.model} ({r.database}): {r.degenerate or 'not marked best'}" for r in pool.itertuples())
            raise ValueError(f"{where}: no model is fit to export ({why}); name one with --model to export it "
                             "anyway")
        model, database = pick.model.iloc[0], pick.database.iloc[0]
    elif database is None:  # a named model of the best row's database (else the first compared)
        database = (table[table.best] if table.best.any() else table).database.iloc[0]
    if model not in EXPORTABLE:
        raise ValueError(f"--model {model}: the element runs {', '.join(EXPORTABLE)}")
    rows = table[(table.model == model) & (table.database == database)]
    if rows.empty:
        raise KeyError(f"{where}: no {model} model of {database}")
    if rows.degenerate.iloc[0]:
        warnings.warn(f"exporting {model} ({database}), a degenerate model: {rows.degenerate.iloc[0]}", stacklevel=2)
    stacked, _ = read_npz(Path(folder) / "parts" / f"{database}-condition-{model}.params.npz")
    folds, seeds = np.shape(stacked["y_scale"])[:2]
    inputs = list(DB_INPUTS[database])
    if model in compare.WITH_RATES:
        inputs += [f"d_{n}_dt" for n in inputs]
    meta = {"inputs": inputs, "model": model}
    nets = [({k: v for k, v in jax.tree.map(lambda a: a[f, s], stacked).items() if k != "response"}, meta)
            for f in range(folds) for s in range(seeds)]
    response = None
    if model == "dynamic":
        ident = identified({"response": stacked["response"]})
        response = {k: float(np.median(ident[k])) for k in ("omega_n_rad_s", "zeta", "delay_s")}
    quasi = model == "quasi_static"
    return ElementModel(model, database, nets, response,
                        cfg.analysis.window_revs if quasi else cfg.dynamic.window_revs, cfg.dynamic.hop_revs,
                        float(rows.offset_s.iloc[0]) if quasi else 0.0)


def run_dynamic(cfg, campaign, campaign_dir, out, log=print) -> tuple:
    """`pvvjax dynamic`: claim `out` for the config's `[dynamic]`, `[train]`, `[analysis]` and
    seed on this campaign, record the config there (`config.toml`, with the campaign's
    folder: what `export --element` reads) and train, resume and compare every model
    (`dynamics.run_comparison`). Returns (the folder, the comparison table)."""
    from .._strict import to_dict
    from ..io import claim_folder, write_config

    check_dynamic(cfg, campaign)
    settings = dict(command="dynamic", dynamic=to_dict(cfg.dynamic), train=to_dict(cfg.train),
                    analysis=to_dict(cfg.analysis), seed=cfg.seed, columns=to_dict(cfg.campaign)["columns"])
    out = claim_folder(out, settings, campaign.fingerprint, kind="dynamic")
    write_config(cfg.with_(campaign=dataclasses.replace(cfg.campaign, path=str(campaign_dir), synthetic="")),
                 out / "config.toml")
    return out, run_comparison(campaign, cfg, out, log)
