"""The `pvvjax` command line: one subcommand per pipeline stage, plus `run` (the main job).

Errors from bad input (campaign problems, config mistakes, missing files) are printed as
plain messages naming the file and field, with a non-zero exit; never a traceback.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from ._apidoc import api_reference
from .experiment import (
    _progress,
    campaign_plots,
    database_summary,
    enable_compilation_cache,
    prepare_sweep,
    resolve_campaign,
    run_main_job,
    use_deterministic_gpu,
    write_databases,
)

__all__ = ["api_reference", "cli_reference", "main"]


def _experiment(args):
    from .config import ExperimentConfig, load_config

    return load_config(args.config) if getattr(args, "config", None) else ExperimentConfig()


def cmd_validate(args) -> int:
    from .data.campaign import validate_campaign

    cfg = _experiment(args)
    problems = validate_campaign(args.campaign, cfg.campaign.columns, cfg.analysis.window_revs,
                                 progress=_progress("validating"))
    if problems:
        print(f"{args.campaign}: {len(problems)} problem(s)")
        for p in problems:
            print(f"  - {p}")
        return 1
    print(f"{args.campaign}: valid")
    return 0


def cmd_build_db(args) -> int:
    from .analysis.databases import build_databases

    cfg = _experiment(args)
    campaign, _ = resolve_campaign(cfg, args.campaign)
    dbs = build_databases(campaign, cfg.analysis)
    out = Path(args.out)
    write_databases(dbs, out, cfg)
    print(database_summary(dbs))
    print(f"wrote db1, db2, db3 and peaks (.csv, .parquet) to {out}")
    return 0


def cmd_synth(args) -> int:
    import dataclasses

    from .synth import SynthConfig, load_synth_config, write_synthetic

    scfg = load_synth_config(args.config) if args.config else SynthConfig()
    if args.seed is not None:
        scfg = dataclasses.replace(scfg, seed=args.seed)
    t0 = time.perf_counter()
    folder, truth = write_synthetic(args.out, scfg, args.truth)
    print(f"wrote campaign {folder} ({time.perf_counter() - t0:.1f} s); ground truth: {truth}")
    if args.plots:
        from .config import ExperimentConfig

        cfg = ExperimentConfig()
        campaign, _ = resolve_campaign(cfg, folder)
        campaign_plots(campaign, cfg, Path(args.plots))  # the generator's check figures
    return 0


def cmd_plot(args) -> int:
    cfg = _experiment(args)
    campaign, _ = resolve_campaign(cfg, args.campaign)
    _, _, rows = campaign_plots(campaign, cfg, Path(args.out), paper=args.paper)
    if rows is not None:
        from .paper.comparison import comparison_markdown

        print(comparison_markdown(rows))
    return 0


def cmd_run(args) -> int:
    """The main job of an experiment config (`experiment.run_main_job`)."""
    from .config import load_config

    run_main_job(load_config(args.config), args.config)
    return 0


def cmd_sweep(args) -> int:
    """Train the config's family of nets; resumable."""
    t0 = time.perf_counter()
    _, _, res, out = prepare_sweep(args.config, args.out)
    cols = ["val_rms_g", "test_rms_g", "test_max_abs_g", "test_p95_abs_g", "steps"]
    print(res.groupby(["database", "architecture"])[cols].median().round(4).to_string())
    print(f"{len(res)} nets in {out / 'results.parquet'} ({time.perf_counter() - t0:.1f} s)")
    return 0


def _export_element(args, res, sweep: Path) -> int:
    """Every net of one database (all seeds and folds: their median) with the replay
    settings and the training envelope, as a NumPy real-time element."""
    import json
    import shutil

    from .analysis.databases import DB_INPUTS
    from .config import load_config
    from .realtime import element as rtelement
    from .realtime import npnet

    sel = res[res.database == args.database]
    if sel.empty:
        raise KeyError(f"{sweep / 'results.parquet'}: no net for database {args.database!r}")
    archs = sorted(set(sel.architecture))
    if len(archs) > 1:
        raise ValueError(f"{sweep}: {args.database} has several architectures {archs}; export one with --net")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    names = []
    for r in sel.sort_values(["test_fold", "seed"]).itertuples():
        names.append(f"net_{r.net_id}.npz")
        shutil.copy(sweep / "params" / f"{r.net_id}.npz", out / names[-1])
    import numpy as np

    from .analysis.databases import peak_table

    cfg = load_config(sweep / "config.toml")
    campaign, _ = resolve_campaign(cfg)
    db = peak_table(campaign, cfg.analysis)[0][list(DB_INPUTS[args.database])]
    # The seat shake's 4/rev phase: the flight test's, amplitude-weighted over every window;
    # and its 1P, 2P and 8P content: median ratio to the 4/rev amplitude, weighted phase.
    from .analysis.harmonics import analyze
    from .data.batch import to_batch

    batch = to_batch(campaign, [])
    w4 = analyze(batch, cfg.analysis.window_revs, harmonic=4)
    valid = np.asarray(w4.valid)
    a4 = np.asarray(w4.amplitude)[valid]
    phase = float(np.angle(np.sum(a4 * np.exp(1j * np.asarray(w4.phase)[valid]))))
    harmonics = {}
    for k in (1, 2, 8):
        wk = analyze(batch, cfg.analysis.window_revs, harmonic=k)
        ak, pk = np.asarray(wk.amplitude)[valid], np.asarray(wk.phase)[valid]
        harmonics[k] = [float(np.median(ak / a4)), float(np.angle(np.sum(ak * np.exp(1j * pk))))]
    spec = dict(nets=names, inputs=list(DB_INPUTS[args.database]), window_revs=args.window, hop_revs=args.hop,
                offset_s=args.offset, stick_offset_s=args.stick_offset, phase_rad=phase, harmonics=harmonics,
                envelope=dict(lo=db.min().tolist(), hi=db.max().tolist()),
                aircraft=dict(rotor_radius_ft=campaign.aircraft.rotor_radius_ft, g_ft_s2=campaign.aircraft.g_ft_s2))
    (out / "element.json").write_text(json.dumps(spec, indent=2))
    shutil.copy(npnet.__file__, out / "npnet.py")
    shutil.copy(rtelement.__file__, out / "rtelement.py")
    print(f"exported a real-time element: {len(names)} {archs[0]} nets ({args.database}), window {args.window:g} revs, "
          f"hop {args.hop:g} revs, offset {args.offset:g} s, to {out}")
    return 0


def cmd_export(args) -> int:
    """Copy a trained net and the NumPy evaluator into a folder a simulator host can use."""
    import shutil

    import pandas as pd

    from .nets.sweep import load_params
    from .realtime import npnet

    sweep = Path(args.sweep)
    res = pd.read_parquet(sweep / "results.parquet")
    if args.element:
        return _export_element(args, res, sweep)
    if args.net:
        sel = res[res.net_id == args.net]
        if sel.empty:
            raise KeyError(f"{sweep / 'results.parquet'}: no net {args.net!r}")
    else:  # best held-out net of the requested database
        sel = res[res.database == args.database].sort_values("test_rms_g").head(1)
        if sel.empty:
            raise KeyError(f"{sweep / 'results.parquet'}: no net for database {args.database!r}")
    row = sel.iloc[0]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    shutil.copy(sweep / "params" / f"{row.net_id}.npz", out / "net.npz")
    shutil.copy(npnet.__file__, out / "npnet.py")
    _, meta = load_params(out / "net.npz")
    (out / "README.md").write_text(
        f"# Exported network {row.architecture} ({row.database}, net {row.net_id})\n\n"
        f"Held-out RMS {row.test_rms_g:.4f} g. Needs NumPy only.\n\n"
        "```python\nfrom npnet import NumpyNet\nnet = NumpyNet.load('net.npz')\n"
        f"pvv_g = net([{', '.join(meta['inputs'])}])\n```\n\nInputs in this order, canonical units "
        "(kt, lb, rpm, -, -, ft/min, %).\n")
    print(f"exported {row.database} {row.architecture} (net {row.net_id}, held-out RMS {row.test_rms_g:.4f} g) "
          f"to {out}")
    print(f"inputs: {', '.join(meta['inputs'])}")
    return 0


def _replay_inputs(args, cfg):
    """Campaign, counters, held-out models of the config's replay (training the sweep first
    if the config names none)."""
    from .replay.tables import load_replay_set, select_counters

    enable_compilation_cache()
    if cfg.replay.sweep:
        sweep = Path(cfg.replay.sweep)
        if not (sweep / "parts").is_dir():
            raise FileNotFoundError(f"{args.config}: replay.sweep = {cfg.replay.sweep!r} is not a sweep folder")
    else:
        _, _, _, sweep = prepare_sweep(args.config)
    campaign, _ = resolve_campaign(cfg)
    counters = list(args.counters) if getattr(args, "counters", None) else select_counters(campaign, cfg.replay)
    info, batch, recs, models = load_replay_set(campaign, counters, sweep, cfg.replay.databases,
                                                cfg.replay.architecture)
    print(f"replaying {len(counters)} counters through the held-out nets of {sweep} ({', '.join(models)})")
    return info, batch, recs, models


def cmd_replay(args) -> int:
    """Quasi-static replay of recorded counters at a given offset and window length."""
    from . import plots
    from .config import load_config
    from .io import write_config, write_table
    from .replay.tables import peak_summary, replay_windows, settings_at

    cfg = load_config(args.config)
    rc = cfg.replay
    tau = rc.offset_s if args.offset is None else args.offset
    L = rc.window_revs if args.window is None else args.window
    out = Path(args.out) if args.out else Path(cfg.out_dir) / cfg.name / "replay"
    info, batch, recs, models = _replay_inputs(args, cfg)
    theta = (tau, L, rc.stick_offset_s)
    windows = replay_windows(info, recs, models, theta, settings_at(batch, theta, rc.hop_revs))
    summary = peak_summary(windows)
    write_table(windows, out / "windows", cfg)
    write_table(summary, out / "summary", cfg)
    write_config(cfg, out / "config.toml")
    cols = ["peak_error_g", "phase_error_s", "rms_g"]
    print(f"offset {tau:g} s, window {L:g} revs, stick offset {rc.stick_offset_s:g} s; median over counters:")
    print(summary.groupby("database")[cols].median().round(3).to_string())
    for counter in list(info.index)[: args.plots]:
        series = {db: windows[(windows.database == db) & (windows.counter == counter)] for db in models}
        fig = plots.replay(series, f"counter {counter} ({info.loc[counter, 'maneuver']}): offset {tau:g} s, "
                                   f"{L:g}-rev windows")
        print(f"figure: {plots.save(fig, out / f'replay_{counter}.png')}")
    print(f"tables: {out / 'windows.parquet'}, {out / 'summary.csv'}")
    return 0


def cmd_calibrate(args) -> int:
    """Fit offset / window length / stick lag by gradient; check against a brute-force grid."""
    import dataclasses

    import numpy as np

    from . import plots
    from .config import load_config
    from .io import write_config, write_table
    from .replay.tables import calibration_table, grid_table

    cfg = load_config(args.config)
    cc = cfg.calibration
    if args.groups or args.free:
        cc = dataclasses.replace(cc, groups=args.groups or cc.groups, free=tuple(args.free or cc.free))
        cfg = cfg.with_(calibration=cc)
    out = Path(args.out) if args.out else Path(cfg.out_dir) / cfg.name / "calibration"
    info, batch, recs, models = _replay_inputs(args, cfg)
    init = (cfg.replay.offset_s, cfg.replay.window_revs, cfg.replay.stick_offset_s)
    table = calibration_table(info, batch, recs, models, cc, init)
    if cc.grid_offset_step_s > 0 and cc.grid_window_step_revs > 0 and "stick_offset_s" not in cc.free \
            and cc.groups != "counter":
        grid = grid_table(info, recs, models, cc, batch, init)
        write_table(grid, out / "grid", cfg)
        best = grid.loc[grid.groupby(["database", "group"]).cost.idxmin()].set_index(["database", "group"])
        table["grid_offset_s"] = [best.loc[(r.database, r.group), "offset_s"] for r in table.itertuples()]
        table["grid_window_revs"] = [best.loc[(r.database, r.group), "window_revs"] for r in table.itertuples()]
        table["grid_cost"] = [best.loc[(r.database, r.group), "cost"] for r in table.itertuples()]
        table["cost_minus_grid"] = table.cost - table.grid_cost  # < 0: better than every grid point
        table["within_one_grid_step"] = (
            (np.abs(table.offset_s - table.grid_offset_s) <= cc.grid_offset_step_s + 1e-6)
            | ~np.isin("offset_s", list(cc.free)))
        if "window_revs" in cc.free:
            table["within_one_grid_step"] &= np.abs(table.window_revs - table.grid_window_revs) <= \
                cc.grid_window_step_revs + 1e-6
        for r in table[table.group == table.group.iloc[0]].itertuples():
            g = grid[(grid.database == r.database) & (grid.group == r.group)]
            fig = plots.cost_map(g, (r.offset_s, r.window_revs), f"{r.database}, group {r.group}: replay cost")
            print(f"figure: {plots.save(fig, out / f'cost_map_{r.database}_{r.group}.png')}")
    write_table(table, out / "calibration", cfg)
    write_config(cfg, out / "config.toml")
    show = ["database", "group", "n_counters", *cc.free, "cost", "start_cost", "steps"]
    show += [c for c in ("grid_offset_s", "grid_window_revs", "grid_cost", "within_one_grid_step", "cost_minus_grid")
             if c in table]
    print(table[show].round(3).to_string(index=False))
    print(f"table: {out / 'calibration.csv'}")
    return 0


def cmd_realtime(args) -> int:
    """Feed a recorded counter to an exported element frame by frame (an example host loop)."""
    import numpy as np
    import pandas as pd

    from .config import ExperimentConfig
    from .realtime.element import CHANNELS, VibrationElement

    el = VibrationElement.load(args.model)
    cfg = ExperimentConfig()
    campaign, _ = resolve_campaign(cfg, args.campaign)
    if args.record not in campaign.records:
        raise KeyError(f"record {args.record!r} is not in the campaign")
    rec = campaign.records[args.record]
    t0 = rec.time_s.to_numpy(float)
    rev = np.unwrap(rec.azimuth_deg.to_numpy(float), period=360.0)
    x0 = rec[list(CHANNELS)].to_numpy(float)
    rate = args.rate or 1.0 / float(np.median(np.diff(t0)))
    rng = np.random.default_rng(0)
    t = np.arange(t0[0], t0[-1], 1.0 / rate)
    if args.jitter:  # frame times jitter by up to ±jitter of a frame
        t = np.sort(np.clip(t + rng.uniform(-args.jitter, args.jitter, t.size) / rate, t0[0], t0[-1]))
    az = np.mod(np.interp(t, t0, rev), 360.0)
    x = np.stack([np.interp(t, t0, x0[:, c]) for c in range(x0.shape[1])], 1)
    out = np.zeros((t.size, 4))
    lat = np.empty(t.size)
    clock = time.perf_counter_ns
    for i in range(t.size):
        s0 = clock()
        o = el.step(t[i], az[i], x[i])
        lat[i] = (clock() - s0) / 1e3
        out[i] = (o.pvv_g, o.shake_g, o.amplitude_g, o.out_of_envelope)
    p50, p99, pmax = np.percentile(lat, [50, 99, 100])
    print(f"{t.size} frames at {rate:g} Hz from record {args.record} ({t[-1] - t[0]:.1f} s): latency per frame "
          f"median {p50:.1f} µs, 99th percentile {p99:.1f} µs, max {pmax:.0f} µs; "
          f"{(t[-1] - t[0]) / (lat.sum() / 1e6):.0f}x faster than real time")
    if args.out:
        df = pd.DataFrame({"time_s": t, "azimuth_deg": az, "pvv_g": out[:, 0], "shake_g": out[:, 1],
                           "amplitude_g": out[:, 2], "out_of_envelope": out[:, 3].astype(bool), "latency_us": lat})
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        df.to_csv(args.out, index=False)
        print(f"signal: {args.out}")
    return 0


def cmd_discover(args) -> int:
    """Find, name, add and confirm the effects a static map misses (data-contract §3)."""
    from .config import ExperimentConfig, load_config
    from .discovery import discover
    from .discovery.report import write_discovery

    cfg = load_config(args.config) if args.config else ExperimentConfig(name="discovery")
    enable_compilation_cache()
    if args.campaign:
        campaign, folder = resolve_campaign(cfg, args.campaign)
    else:
        campaign, folder = resolve_campaign(cfg)
    t0 = time.perf_counter()
    res = discover(campaign, cfg, name=str(folder))
    report = write_discovery(res, args.out, cfg)
    print(f"{len(res.effects)} effect(s) named; held-out RMS {res.before['rms_g']:.4f} -> {res.after['rms_g']:.4f} g "
          f"({time.perf_counter() - t0:.0f} s)")
    print(f"discovery: {Path(args.out) / 'discovery.json'}; report: {report}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="pvvjax", description="Helicopter pilot-floor 4/rev vibration (PVV) toolkit.")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    s = sub.add_parser("validate", help="check a campaign folder against the data contract",
                       description="Report every problem in a campaign folder (exit 1), or exit 0 if valid.")
    s.add_argument("campaign", help="campaign folder")
    s.add_argument("--config", help="experiment config (column mapping, window length)")
    s.set_defaults(fn=cmd_validate)

    def campaign_command(name, fn, help, description, out_help):
        s = sub.add_parser(name, help=help, description=description)
        s.add_argument("campaign", nargs="?", default=None, help="campaign folder (default: embedded synthetic)")
        s.add_argument("--out", required=True, help=out_help)
        s.add_argument("--config", help="experiment config")
        s.set_defaults(fn=fn)
        return s

    campaign_command("build-db", cmd_build_db, "build databases 1-3 from a campaign",
                     "Harmonic analysis, peak PVV per condition and db1-db3 as CSV and Parquet.", "output folder")

    s = sub.add_parser("synth", help="generate a synthetic UH-60A campaign",
                       description="Write a synthetic campaign (and its ground truth beside it).")
    s.add_argument("--out", required=True, help="campaign folder to write")
    s.add_argument("--config", help="generator config (TOML), e.g. a hidden-effect scenario")
    s.add_argument("--seed", type=int, default=None, help="random seed (overrides the config)")
    s.add_argument("--truth", default=None, help="ground-truth file (default: OUT.truth.json, beside OUT)")
    s.add_argument("--plots", default=None, metavar="DIR", help="also write the check figures to DIR")
    s.set_defaults(fn=cmd_synth)

    s = campaign_command("plot", cmd_plot, "figures of a campaign (PVV vs airspeed, pull-up, autorotation)",
                     "PVV vs airspeed in level flight and paper-style time histories.", "output folder for PNG files")
    s.add_argument("--paper", action="store_true",
                   help="also the paper's Figs 1-9, one file each, and their numbers beside the paper's")

    s = sub.add_parser("sweep", help="train a sweep of networks (databases x architectures x seeds x folds)",
                       description="Train every net of the config's [sweep] with its [train] settings. "
                                   "Resumable: run it again after an interruption to finish the rest.")
    s.add_argument("config", help="experiment config (TOML), e.g. experiments/configs/sweep-small.toml")
    s.add_argument("--out", default=None, help="sweep folder (default: OUT_DIR/NAME/sweep)")
    s.set_defaults(fn=cmd_sweep)

    s = sub.add_parser("export", help="export a trained net as a NumPy evaluator for a simulator host",
                       description="Copy a net's parameters and the NumPy evaluator (no JAX) into a folder.")
    s.add_argument("sweep", help="sweep folder (with results.parquet and params/)")
    s.add_argument("--out", required=True, help="output folder")
    s.add_argument("--net", default=None, help="net id (default: the best held-out net of --database)")
    s.add_argument("--database", default="db1", choices=["db1", "db2", "db3"])
    s.add_argument("--element", action="store_true",
                   help="export a real-time vibration element (all nets of --database, their median)")
    s.add_argument("--offset", type=float, default=0.0, help="element: input-to-vibration offset, s")
    s.add_argument("--stick-offset", type=float, default=0.0, help="element: extra offset of the sticks, s")
    s.add_argument("--window", type=float, default=8.0, help="element: window length, revolutions")
    s.add_argument("--hop", type=float, default=1.0, help="element: window spacing (update interval), revolutions")
    s.set_defaults(fn=cmd_export)

    s = sub.add_parser("realtime", help="feed a recorded counter to a real-time element frame by frame",
                       description="An example simulator host: resample a record to a frame rate, step the "
                                   "exported NumPy element once per frame, report latency percentiles.")
    s.add_argument("--model", required=True, help="element folder (pvvjax export --element)")
    s.add_argument("--record", required=True, help="counter to play, e.g. 11022")
    s.add_argument("--campaign", default=None, help="campaign folder (default: embedded synthetic)")
    s.add_argument("--rate", type=float, default=None, help="frame rate, Hz (default: the record's)")
    s.add_argument("--jitter", type=float, default=0.0, help="random frame-time jitter, fraction of a frame")
    s.add_argument("--out", default=None, help="CSV of the output signal")
    s.set_defaults(fn=cmd_realtime)

    s = sub.add_parser("replay", help="quasi-static replay of recorded maneuvers through the trained nets",
                       description="Replay counters through the nets that held them out ([replay] of the config; "
                                   "trains the config's sweep first when [replay] sweep is empty).")
    s.add_argument("config", help="experiment config (TOML), e.g. experiments/configs/replay.toml")
    s.add_argument("--offset", type=float, default=None, help="input-to-vibration offset, s (overrides the config)")
    s.add_argument("--window", type=float, default=None, help="window length, revolutions (overrides the config)")
    s.add_argument("--counters", nargs="+", default=None, help="counters to replay (overrides the config)")
    s.add_argument("--plots", type=int, default=4, help="figures for the first N counters (default 4)")
    s.add_argument("--out", default=None, help="output folder (default: OUT_DIR/NAME/replay)")
    s.set_defaults(fn=cmd_replay)

    s = sub.add_parser("calibrate", help="fit the offset, window length and stick lag by gradient",
                       description="Levenberg-Marquardt from the best point of a coarse grid, per database and "
                                   "group ([calibration] of the config), checked against a brute-force grid.")
    s.add_argument("config", help="experiment config (TOML), e.g. experiments/configs/replay.toml")
    s.add_argument("--groups", choices=["all", "maneuver", "counter"], default=None,
                   help="one fit for all counters, per maneuver kind, or per counter (overrides the config)")
    s.add_argument("--free", nargs="+", choices=["offset_s", "window_revs", "stick_offset_s"], default=None,
                   help="parameters to fit (overrides the config)")
    s.add_argument("--counters", nargs="+", default=None, help="counters to calibrate on (overrides the config)")
    s.add_argument("--out", default=None, help="output folder (default: OUT_DIR/NAME/calibration)")
    s.set_defaults(fn=cmd_calibrate)

    s = sub.add_parser("discover", help="find, name, add and confirm effects the static map misses",
                       description="Replay every counter through held-out nets, locate the residual, rank "
                                   "candidate effects (cross-validated, permutation-tested), add each to the "
                                   "model, retrain and keep it only if the held-out error drops. Writes "
                                   "OUT/discovery.json (data contract section 3) and OUT/report.md.")
    s.add_argument("--campaign", default=None, help="campaign folder (default: embedded synthetic)")
    s.add_argument("--out", required=True, help="output folder")
    s.add_argument("--config", default=None, help="experiment config ([discovery], [train], [analysis] sections)")
    s.set_defaults(fn=cmd_discover)

    s = sub.add_parser("run", help="run an experiment config end to end (the main job)",
                       description="Campaign, databases and figures for one experiment config; with [run] "
                                   "networks the paper's networks (Figs 10-12, Table 1), with [run] "
                                   "discovery_scenario a hidden-effect discovery; writes report.md and report.html.")
    s.add_argument("config", help="experiment config (TOML)")
    s.set_defaults(fn=cmd_run)
    return p


def cli_reference(width: int = 96) -> str:
    """The command-line reference as Markdown, generated from the parser itself (every
    subcommand's `--help`), so that the docs cannot drift from the CLI."""
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(width)  # argparse wraps to the terminal width
    try:
        p = build_parser()
        parts = ["# Command-line reference", "",
                 "Generated from the CLI itself (`python experiments/reference_docs.py --docs`); "
                 "every subcommand also has `--help`.", "", "```", p.format_help().rstrip(), "```", ""]
        sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
        for name, sp in sub.choices.items():
            parts += [f"## pvvjax {name}", "", "```", sp.format_help().rstrip(), "```", ""]
        return "\n".join(parts)
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old


def main(argv=None) -> int:
    """Run the CLI on `argv` (default: the process's arguments); returns the exit status
    (2 for bad input, reported as one clear message rather than a traceback)."""
    from ._strict import ConfigError
    from .data.campaign import CampaignError

    args = build_parser().parse_args(argv)
    use_deterministic_gpu()  # before any command starts JAX
    try:
        return args.fn(args)
    except (CampaignError, ConfigError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except RuntimeError as e:  # TrainingError (imported lazily: JAX may not be started yet)
        if type(e).__name__ != "TrainingError" or os.environ.get("PVVJAX_DEBUG"):
            raise
        print(f"error: {e}", file=sys.stderr)
        return 2
    except (FileNotFoundError, KeyError, ValueError) as e:
        if os.environ.get("PVVJAX_DEBUG"):
            raise
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
