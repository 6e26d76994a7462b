"""The subcommands: each reads its arguments, runs the library and prints where it wrote."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from .._strict import to_dict
from ..experiment import (
    absolute_paths,
    campaign_plots,
    database_summary,
    enable_compilation_cache,
    prepare_sweep,
    progress_bar,
    resolve_campaign,
    run_main_job,
    write_databases,
)
from ..io import claim_folder, new_file, own_folder


def _experiment(args):
    from ..config import ExperimentConfig, load_config

    cfg = load_config(args.config) if getattr(args, "config", None) else ExperimentConfig()
    if getattr(args, "campaign", None):  # --campaign replaces the config's [campaign] path
        cfg = cfg.with_(campaign=dataclasses.replace(cfg.campaign, path=str(args.campaign)))
    return absolute_paths(cfg)


def cmd_validate(args) -> int:
    from ..data.campaign import validate_campaign

    cfg = _experiment(args)
    problems = validate_campaign(args.campaign, cfg.campaign.columns, cfg.analysis.window_revs,
                                 progress=progress_bar("validating"), harmonic=cfg.analysis.harmonic)
    errors = [p for p in problems if not p.warning]
    if errors:
        print(f"{args.campaign}: {len(errors)} problem(s)")
    for p in problems:
        print(f"  - {p}")
    if errors:
        return 1
    print(f"{args.campaign}: valid" + (f" ({len(problems)} warning(s))" if problems else ""))
    return 0


def cmd_build_db(args) -> int:
    from ..analysis.databases import axis_peak_tables, build_databases
    from ..seat.report import axis_summary, write_axis_tables

    cfg = _experiment(args)
    campaign, _ = resolve_campaign(cfg, args.campaign)
    out = claim_folder(args.out, dict(command="build-db", analysis=to_dict(cfg.analysis),
                                      columns=to_dict(cfg.campaign)["columns"]), campaign.fingerprint,
                       kind="build-db")
    dbs = build_databases(campaign, cfg.analysis)
    write_databases(dbs, out, cfg)
    print(database_summary(dbs))
    tables = axis_peak_tables(campaign, cfg.analysis)
    names = write_axis_tables(tables, out / "axes", cfg)
    print(axis_summary(tables))
    print(f"wrote db1, db2, db3 and peaks (.csv, .parquet) to {out}; a peak table per axis and harmonic to "
          f"{out / 'axes'} ({', '.join(names)})")
    return 0


def cmd_synth(args) -> int:
    import dataclasses

    from ..synth import SynthConfig, load_synth_config, write_synthetic

    scfg = load_synth_config(args.config) if args.config else SynthConfig()
    if args.seed is not None:
        scfg = dataclasses.replace(scfg, seed=args.seed)
    plots_dir = own_folder(args.plots, "pvvjax synth --plots") if args.plots else None
    t0 = time.perf_counter()
    folder, truth = write_synthetic(args.out, scfg, args.truth, force=args.force)
    print(f"wrote campaign {folder} ({time.perf_counter() - t0:.1f} s); ground truth: {truth}")
    if args.plots:
        from ..config import ExperimentConfig

        cfg = ExperimentConfig()
        campaign, _ = resolve_campaign(cfg, folder)
        campaign_plots(campaign, cfg, plots_dir)  # the generator's check figures
    return 0


def cmd_plot(args) -> int:
    cfg = _experiment(args)
    out = own_folder(args.out, "pvvjax plot")
    campaign, _ = resolve_campaign(cfg, args.campaign)
    _, _, rows = campaign_plots(campaign, cfg, out, paper=args.paper)
    if rows is not None:
        from ..paper.comparison import comparison_markdown

        print(comparison_markdown(rows))
    return 0


def cmd_run(args) -> int:
    """The main job of an experiment config (`experiment.run_main_job`)."""

    run_main_job(_experiment(args), args.config)
    return 0


def cmd_sweep(args) -> int:
    """Train the config's family of nets; resumable; across processes with --coordinator."""
    t0 = time.perf_counter()
    cfg = _experiment(args)
    if not args.coordinator and (args.num_processes != 1 or args.process_id != 0):
        raise ValueError(f"--num-processes {args.num_processes} --process-id {args.process_id}: several processes "
                         "need --coordinator HOST:PORT (of process 0)")
    if args.coordinator:
        from ..experiment import start_distributed, use_cpu_cores

        use_cpu_cores(cfg.sweep.cpu_devices)  # before JAX starts, as prepare_sweep would
        start_distributed(args.coordinator, args.num_processes, args.process_id)
    _, _, res, out = prepare_sweep(cfg, args.out)
    cols = ["val_rms_g", "test_rms_g", "test_max_abs_g", "test_p95_abs_g", "steps"]
    print(res.groupby(["database", "architecture"])[cols].median().round(4).to_string())
    print(f"{len(res)} nets in {out / 'results.parquet'} ({time.perf_counter() - t0:.1f} s)")
    return 0


def _given_sweep(args, cfg) -> Path | None:
    """The config's replay settings checked and its named sweep (None: the config's own,
    trained when needed), before any campaign is loaded or folder claimed: a mistake is an
    error in a second."""
    from ..nets.sweep import finished_sweep

    cfg.check_replay()
    if not cfg.replay.sweep:
        return None
    sweep = Path(cfg.replay.sweep)
    try:
        finished_sweep(sweep)
    except FileNotFoundError as e:
        raise FileNotFoundError(f"{args.config}: replay.sweep: {e}") from None
    return sweep


def _replay_inputs(args, cfg):
    """Campaign, counters, held-out models of the config's replay (training the sweep first
    if the config names none)."""
    from ..replay.tables import load_replay_set, select_counters

    sweep = _given_sweep(args, cfg)
    enable_compilation_cache()
    campaign, _ = resolve_campaign(cfg)
    counters = select_counters(campaign, cfg.replay, getattr(args, "counters", None), "--counters")
    if sweep is None:
        _, _, _, sweep = prepare_sweep(cfg)
    info, batch, recs, models = load_replay_set(campaign, counters, sweep, cfg.replay.databases,
                                                cfg.replay.architecture, cfg.analysis)
    print(f"replaying {len(counters)} counters through the held-out nets of {sweep} ({', '.join(models)})")
    return info, batch, recs, models


def cmd_replay(args) -> int:
    """Quasi-static replay of recorded counters at a given offset and window length."""
    from .. import plots
    from ..io import write_config, write_table
    from ..replay.tables import peak_summary, replay_windows, settings_at

    cfg = _experiment(args)
    rc = cfg.replay
    tau = rc.offset_s if args.offset is None else args.offset
    L = rc.window_revs if args.window is None else args.window
    out = Path(args.out) if args.out else Path(cfg.out_dir) / cfg.name / "replay"
    _given_sweep(args, cfg)
    claim_folder(out, dict(config=to_dict(cfg), offset_s=tau, window_revs=L, counters=args.counters), "", kind="replay")
    info, batch, recs, models = _replay_inputs(args, cfg)
    theta = (tau, L, rc.stick_offset_s)
    windows = replay_windows(info, recs, models, theta, settings_at(batch, theta, rc.hop_revs))
    if windows.empty:
        raise ValueError(f"offset {tau:g} s, window {L:g} revs: no window of any counter lies within its record (the "
                         "offset shifts the inputs beyond it); give an offset of a few seconds (--offset, "
                         "replay.offset_s)")
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

    from .. import plots
    from ..io import write_config, write_table
    from ..replay.tables import calibration_table, grid_table

    cfg = _experiment(args)
    cc = cfg.calibration
    if args.groups or args.free:
        cc = dataclasses.replace(cc, groups=args.groups or cc.groups, free=tuple(args.free or cc.free))
        cfg = cfg.with_(calibration=cc)
    out = Path(args.out) if args.out else Path(cfg.out_dir) / cfg.name / "calibration"
    _given_sweep(args, cfg)
    claim_folder(out, dict(config=to_dict(cfg), counters=args.counters), "", kind="calibrate")
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

    from ..config import ExperimentConfig
    from ..realtime.element import AXIS_OUTPUTS, CHANNELS, VibrationElement

    if args.out:
        new_file(args.out)
    el = VibrationElement.load(args.model)
    cfg = ExperimentConfig()
    campaign, _ = resolve_campaign(cfg, args.campaign)
    if args.record not in campaign.records:
        raise KeyError(f"record {args.record!r} is not in the campaign")
    ac = campaign.aircraft
    if el.blades != ac.blades or abs(el.radius - ac.rotor_radius_ft) > 1e-6 * ac.rotor_radius_ft:
        raise ValueError(f"--model {args.model}: an element of a {el.blades}-bladed rotor of radius {el.radius:g} ft, "
                         f"but the campaign {campaign.source} declares {ac.blades} blades of "
                         f"{ac.rotor_radius_ft:g} ft; play a record of the element's own aircraft")
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
    names = ["pvv_g", "shake_g", "amplitude_g", "out_of_envelope"]
    if el.outputs != ("az_g",):  # every seat axis the element gives, as the simulator reads them
        names += [f"{k}_{AXIS_OUTPUTS[a]}_g" for a in el.outputs for k in ("pvv", "shake")]
    from ..realtime import stream

    out, lat = stream(el, t, az, x, names, f"record {args.record}")
    p50, p99, pmax = np.percentile(lat, [50, 99, 100])
    print(f"{t.size} frames at {rate:g} Hz from record {args.record} ({t[-1] - t[0]:.1f} s): latency per frame "
          f"median {p50:.1f} µs, 99th percentile {p99:.1f} µs, max {pmax:.0f} µs; "
          f"{(t[-1] - t[0]) / (lat.sum() / 1e6):.0f}x faster than real time")
    if args.out:
        df = pd.DataFrame({"time_s": t, "azimuth_deg": az, **{n: out[:, i] for i, n in enumerate(names)},
                           "latency_us": lat}).astype({"out_of_envelope": bool})
        df.to_csv(args.out, index=False)
        print(f"signal: {args.out}")
    return 0


def cmd_dynamic(args) -> int:
    """Train and compare the models of PVV through time (`dynamics.study.run_dynamic`)."""
    from ..dynamics.study import run_dynamic

    t0 = time.perf_counter()
    cfg = _experiment(args)
    if args.seeds is not None:
        cfg = cfg.with_(dynamic=dataclasses.replace(cfg.dynamic, seeds=args.seeds))
    enable_compilation_cache()
    campaign, folder = resolve_campaign(cfg, args.campaign)
    out, table = run_dynamic(cfg, campaign, folder, args.out)
    cols = ["database", "model", "rms_g", "peak_err_rms_g", "time_of_peak_err_median_s", "faa_pass_share",
            "kendall_tau", "best"]
    print(table[cols].round(4).to_string(index=False))
    print(f"wrote comparison.csv, predictions.parquet and report.md to {out} ({time.perf_counter() - t0:.1f} s)")
    return 0


def cmd_axes(args) -> int:
    """Which inputs each pilot-floor axis needs (`seat.run_study`)."""
    from ..seat import run_study

    t0 = time.perf_counter()
    cfg = _experiment(args)
    if args.no_discovery:
        cfg = cfg.with_(axes=dataclasses.replace(cfg.axes, discovery=False))
    enable_compilation_cache()
    campaign, folder = resolve_campaign(cfg, args.campaign)
    out, study, _ = run_study(cfg, campaign, folder, args.out)
    print(study.table.drop(columns="fails").round(4).to_string(index=False))
    print("\n".join(study.needs.text))
    print(f"wrote axes.csv, needs.csv, predictions.parquet and report.md to {out} ({time.perf_counter() - t0:.1f} s)")
    return 0


def cmd_discover(args) -> int:
    """Find, name, add and confirm the effects a static map misses (data-contract §3)."""
    from ..config import ExperimentConfig, load_config
    from ..discovery import discover
    from ..discovery.report import write_discovery

    cfg = absolute_paths(load_config(args.config) if args.config else ExperimentConfig(name="discovery"))
    enable_compilation_cache()
    if args.campaign:
        campaign, folder = resolve_campaign(cfg, args.campaign)
    else:
        campaign, folder = resolve_campaign(cfg)
    claim_folder(args.out, dict(discovery=to_dict(cfg.discovery), train=to_dict(cfg.train),
                                analysis=to_dict(cfg.analysis), columns=to_dict(cfg.campaign)["columns"]),
                 campaign.fingerprint, kind="discover")
    t0 = time.perf_counter()
    res = discover(campaign, cfg, name=str(folder))
    report = write_discovery(res, args.out, cfg)
    print(f"{len(res.effects)} effect(s) named; held-out RMS {res.before['rms_g']:.4f} -> {res.after['rms_g']:.4f} g "
          f"({time.perf_counter() - t0:.0f} s)")
    print(f"discovery: {Path(args.out) / 'discovery.json'}; report: {report}")
    return 0
