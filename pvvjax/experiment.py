"""The imperative shell of an experiment: its campaign, its compiled-program cache and CPU
devices, its sweep, and its main job (campaign → databases → the paper's figures → networks
→ replay → studies → a discovery scenario, one report beside the paper).

The command line (`cli`) and the experiment scripts (`experiments/`) call these; nothing in
the numerical core does. JAX is imported inside the functions, so that `use_cpu_cores` and
`use_deterministic_gpu` can still set XLA's flags before it starts.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from .interrupts import check_interrupt
from .paper.comparison import PAPER_TABLE1  # the paper's numbers (no JAX, no plotting)

__all__ = [
    "absolute_paths",
    "campaign_plots",
    "database_summary",
    "enable_compilation_cache",
    "prepare_sweep",
    "progress_bar",
    "resolve_campaign",
    "run_main_job",
    "use_cpu_cores",
    "use_deterministic_gpu",
    "write_databases",
]


def absolute_paths(cfg):
    """`cfg` with its paths (the campaign folder, the synthetic campaign's config, the
    replay's sweep, the discovery scenario) made absolute against the working directory, once, where the config is
    read: the config a results folder records then names the same files from anywhere, so
    that `pvvjax export` run elsewhere cannot load another campaign of the same name."""
    import dataclasses

    def absolute(p: str) -> str:
        return str(Path(p).resolve()) if p else p

    campaign = dataclasses.replace(cfg.campaign, path=absolute(cfg.campaign.path),
                                   synthetic=absolute(cfg.campaign.synthetic))
    return cfg.with_(campaign=campaign, replay=dataclasses.replace(cfg.replay, sweep=absolute(cfg.replay.sweep)),
                     run=dataclasses.replace(cfg.run, discovery_scenario=absolute(cfg.run.discovery_scenario)))


def resolve_campaign(cfg, campaign_dir=None, log=print):
    """The campaign an experiment uses: a folder, or the embedded synthetic campaign
    (generated once and cached).

    Args:
        cfg: `ExperimentConfig` (`campaign` section: folder, column mapping or synthetic
            config; `analysis.window_revs`; `seed` of the default synthetic campaign).
        campaign_dir: a folder that replaces `cfg.campaign.path`.
        log: progress messages.

    Returns:
        (Campaign, its folder).
    """
    from .data.campaign import load_campaign

    folder = campaign_dir or cfg.campaign.path
    if not folder:
        from .synth import SynthConfig, cached_campaign, load_synth_config

        scfg = load_synth_config(cfg.campaign.synthetic) if cfg.campaign.synthetic else SynthConfig(seed=cfg.seed)
        t0 = time.perf_counter()
        folder = cached_campaign(scfg)
        log(f"embedded synthetic campaign: {folder} ({time.perf_counter() - t0:.1f} s)")
    t0 = time.perf_counter()
    campaign = load_campaign(folder, cfg.campaign.columns, cfg.analysis.window_revs, progress=progress_bar("loading"),
                             harmonic=cfg.analysis.harmonic)
    log(f"loaded {len(campaign)} counters, {len(campaign.conditions())} conditions ({time.perf_counter() - t0:.1f} s)")
    from .analysis import require_axis

    require_axis(campaign, cfg.analysis.axis)  # before any work: the axis every stage analyses
    return campaign, Path(folder)


def progress_bar(desc):
    """A progress callback (`fn(iterable, total=None)`) that shows a bar on a terminal only."""
    from tqdm.auto import tqdm

    return lambda it, total=None: tqdm(it, total=total, desc=desc, unit="counter", leave=False,
                                       disable=not sys.stderr.isatty())


def enable_compilation_cache():
    """Reuse compiled XLA programs across runs and checkouts (`~/.cache/pvvjax/jax`, or
    `$PVVJAX_CACHE/jax`; pruned to 2 GiB here, least recently used first), unless the user
    set a cache of their own (`JAX_COMPILATION_CACHE_DIR`)."""
    import jax

    from ._cache import compile_cache_dir, prune_compile_cache

    if not os.environ.get("JAX_COMPILATION_CACHE_DIR"):
        prune_compile_cache()
        jax.config.update("jax_compilation_cache_dir", str(compile_cache_dir()))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)


def start_distributed(coordinator: str, num_processes: int, process_id: int) -> None:
    """Join a multi-process JAX run (one process per host, `jax.distributed`): afterwards
    `jax.devices()` spans every process, a sweep shards its nets over all of them and process
    0 writes the files. Call it before JAX computes anything. On CPU the processes exchange
    arrays through gloo (TCP), so several processes on one machine work too.

    Args:
        coordinator: "host:port" of process 0, reachable from every process.
        num_processes: how many processes take part. process_id: this one's, 0..N-1.
    """
    if not 0 <= process_id < num_processes:
        raise ValueError(f"--process-id {process_id}: must be within 0 to {num_processes - 1} (--num-processes)")
    import jax

    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator_address=coordinator, num_processes=num_processes, process_id=process_id)


def use_cpu_cores(n: int = 0) -> None:
    """Expose `n` host devices (0: one per core) to XLA on CPU, so that sharded work runs
    on every core. Only possible before JAX starts; otherwise a no-op."""
    n = n or (os.cpu_count() or 1)
    if n > 1:
        _add_xla_flag("xla_force_host_platform_device_count", n)


def _add_xla_flag(name: str, value) -> None:
    """Add `--name=value` to `XLA_FLAGS` unless JAX has started (XLA reads them once) or
    the flag is set there already (a user's setting wins)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "jax" not in sys.modules and name not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} --{name}={value}".strip()


def use_deterministic_gpu() -> None:
    """Ask XLA for deterministic reductions on a GPU, so that the same config and seed give
    the same numbers there too (on an H100 without it, one calibration took 7, 15 or 17
    Levenberg-Marquardt steps in three runs of the same program; with it, 11 every time).
    No effect on CPU. Only possible before JAX starts (otherwise a no-op); a setting of
    the flag already in `XLA_FLAGS` wins."""
    _add_xla_flag("xla_gpu_deterministic_ops", "true")


def write_databases(dbs, out: Path, cfg) -> None:
    """Each database of `build_databases` as `out/NAME.csv` and `.parquet`, beside the config
    that built them (`out/config.toml`)."""
    from .io import write_config, write_table

    for name, df in dbs.items():
        write_table(df, out / name, cfg)
    write_config(cfg, out / "config.toml")


def database_summary(dbs) -> str:
    """A plain-text summary of the databases: conditions, rows and inputs per database, peak
    PVV by maneuver kind, and the paper's Table 1 conditions beside their peaks here."""
    from .analysis.databases import OUTPUT

    pk = dbs["peaks"]
    lines = [f"{len(pk)} conditions; {int((abs(pk.mlf - 1) > 0.05).sum())} with MLF != 1 "
             f"({(abs(pk.mlf - 1) > 0.05).mean():.0%}); peak PVV {pk[OUTPUT].min():.3f}-{pk[OUTPUT].max():.3f} g"]
    for name in ("db1", "db2", "db3"):
        lines.append(f"  {name}: {len(dbs[name])} rows x {dbs[name].shape[1] - 6} inputs")
    lines.append(pk.groupby("maneuver")[OUTPUT].agg(["count", "mean", "max"]).round(3).to_string())
    known = pk[pk.condition.isin(PAPER_TABLE1)].set_index("condition")
    if len(known):
        lines.append("\npaper conditions (peak PVV, g):")
        lines.append(f"  {'condition':16s} {'paper':>6s} {'here':>6s}  {'MLF':>5s}  counter")
        for cid, ref in PAPER_TABLE1.items():
            if cid in known.index:
                r = known.loc[cid]
                lines.append(f"  {cid:16s} {ref:6.2f} {r[OUTPUT]:6.3f}  {r.mlf:5.2f}  {r.counter}")
    return "\n".join(lines)


def campaign_plots(campaign, cfg, out: Path, paper: bool = False):
    """PVV vs airspeed and the pull-up / autorotation time histories; with `paper`, the
    paper's Figs 1-9 one file each and their numbers beside the paper's.

    Returns:
        (figure paths, [(caption, path)] of Figs 1-9, comparison rows or None).
    """
    from . import plots
    from .analysis.databases import peak_table
    from .paper.comparison import paper_figures

    peaks, windows = peak_table(campaign, cfg.analysis)
    paths = [plots.save(plots.pvv_vs_airspeed(peaks), out / "pvv_vs_airspeed.png")]
    conds = campaign.conditions()
    if "11022" in conds:
        fig = plots.time_histories(campaign, windows, conds["11022"], [
            ("a_z, g", ["az_g"]), ("pitch rate, deg/s", ["pitch_rate_dps"]),
            ("sticks, %", ["collective_pct", "lateral_pct", "longitudinal_pct"]), ("PVV, g", ["pvv"])],
            "Pull-up, counter 11022 (paper Figs 1-4)")
        paths.append(plots.save(fig, out / "pullup_11022.png"))
    if "AR60" in conds:
        fig = plots.time_histories(campaign, windows, conds["AR60"], [
            ("a_z, g", ["az_g"]), ("shaft power, hp", ["shaft_power_hp"]), ("collective, %", ["collective_pct"]),
            ("PVV, g", ["pvv"])], "Autorotation AR60, counters 11539 + 11540 (paper Figs 5-9)")
        paths.append(plots.save(fig, out / "autorotation_AR60.png"))
    figs, rows = paper_figures(campaign, windows, peaks, out) if paper else ([], None)
    for p in paths + [f for _, f in figs]:
        print(f"figure: {p}")
    return paths, figs, rows


def prepare_sweep(config, out=None):
    """Load an experiment config (a path, or an `ExperimentConfig`), start JAX on every core
    with the compilation cache, build the databases and run (or resume) its sweep.

    Returns:
        (config, databases, sweep results, sweep folder).
    """
    from .config import load_config

    cfg = absolute_paths(load_config(config) if isinstance(config, (str, Path)) else config)
    use_cpu_cores(cfg.sweep.cpu_devices)  # before anything imports JAX
    use_deterministic_gpu()
    from tqdm.auto import tqdm

    from .analysis.databases import build_databases
    from .nets.sweep import run_sweep

    enable_compilation_cache()
    out = Path(out) if out else Path(cfg.out_dir) / cfg.name / "sweep"
    campaign, _ = resolve_campaign(cfg)
    dbs = build_databases(campaign, cfg.analysis)
    res = run_sweep(cfg, dbs, out, progress=lambda **kw: tqdm(desc="nets", unit="net", disable=not sys.stderr.isatty(),
                                                              **kw))
    return cfg, dbs, res, out


def run_main_job(cfg, source: str | Path = "") -> Path:
    """The main job of an experiment config, end to end: the campaign, its databases and the
    paper's Figs 1-9, then (as `cfg.run` asks) the sweep of nets beside the paper's Figs 10-12
    and Table 1, the quasi-static replay of the pull-up (Figs 13-14), the studies the paper
    left open and discovery on a hidden-effect scenario. Progress is printed stage by stage.

    Args:
        cfg: `ExperimentConfig`; results go to `cfg.out_dir / cfg.name`.
        source: the config's file, named in the networks' section of the report.

    Returns:
        The report's path (`report.md`, or `report.html` with `cfg.run.html`).
    """
    cfg = absolute_paths(cfg)
    if cfg.run.networks and cfg.run.replay:
        cfg.check_replay()
    cfg.check_scenario()  # read now: a mistake there is said before hours of work, not after
    if cfg.run.networks:
        use_cpu_cores(cfg.sweep.cpu_devices)  # before anything imports JAX (else a no-op)
    use_deterministic_gpu()
    import pandas as pd

    from ._strict import to_dict
    from .analysis.databases import build_databases
    from .io import claim_folder, write_table
    from .paper.comparison import database_checks

    out = Path(cfg.out_dir) / cfg.name
    t0 = time.perf_counter()
    replay = cfg.run.networks and cfg.run.replay
    studies = replay and cfg.run.studies
    stages = [name for name, on in (("campaign", True), ("databases", True), ("figures", True),
                                    ("networks", cfg.run.networks), ("replay", replay), ("studies", studies),
                                    ("discovery", cfg.run.discovery_scenario), ("dynamic", cfg.run.dynamic),
                                    ("axes", cfg.run.axes)) if on]

    def step(name, text):
        check_interrupt()  # between stages: a Ctrl-C lost inside one stops the job here
        print(f"[{stages.index(name) + 1}/{len(stages)}] {text}")

    step("campaign", f"campaign ({'embedded synthetic' if not cfg.campaign.path else cfg.campaign.path})")
    campaign, campaign_dir = resolve_campaign(cfg)
    claim_folder(out, to_dict(cfg), campaign.fingerprint, kind="run")
    step("databases", "harmonic analysis, peak PVV, databases 1-3")
    dbs = build_databases(campaign, cfg.analysis)
    write_databases(dbs, out / "databases", cfg)
    summary = database_summary(dbs)
    print(summary)
    step("figures", "figures (paper Figs 1-9)")
    figures, paper_figs, fig_rows = campaign_plots(campaign, cfg, out / "figures", paper=True)
    checks = [database_checks(dbs["peaks"]), fig_rows]
    nets = reps = disc = None
    sections = []
    if cfg.run.networks:
        step("networks", f"networks: {', '.join(cfg.sweep.databases)} x {len(cfg.sweep.hidden)} architecture(s) x "
                         f"{cfg.sweep.seeds} seeds x {cfg.sweep.folds} folds (Figs 10-12, Table 1)")
        nets = _run_networks(cfg, dbs, out, source)
        checks.append(nets[2])
    if replay:
        step("replay", "quasi-static replay: offset fitted on all maneuvers, pull-up 11022 (Figs 13-14)")
        reps = _run_replay(cfg, campaign, out)
        checks.append(reps[2])
    if studies:
        step("studies", "studies: one offset per maneuver kind, window length, stick lag")
        sections = _run_studies(cfg, reps[3], out)
    if cfg.run.discovery_scenario:
        step("discovery", f"discovery on the hidden-effect scenario {cfg.run.discovery_scenario}")
        disc = _run_discovery(cfg, out / "discovery")
    dyn, axes = _through_time_and_axes(cfg, campaign, campaign_dir, out, step)
    checks = pd.concat([c for c in checks if c is not None and len(c)], ignore_index=True)
    write_table(checks, out / "paper_comparison", cfg)
    report = _write_report(cfg, out, summary, figures, paper_figs, checks, nets, reps, sections, disc,
                           time.perf_counter() - t0, dyn, axes)
    print(f"done in {time.perf_counter() - t0:.1f} s; results in {out}")
    print(f"report: {report}")
    return report


def _through_time_and_axes(cfg, campaign, campaign_dir, out: Path, step) -> tuple:
    """The stages `[run] dynamic` (`pvvjax dynamic` into `out/dynamic`: its comparison table)
    and `[run] axes` (`pvvjax axes` into `out/axes`: its report section); None where off."""
    dyn = axes = None
    if cfg.run.dynamic or cfg.run.axes:
        enable_compilation_cache()
    if cfg.run.dynamic:
        from .dynamics.study import run_dynamic

        step("dynamic", f"PVV through time: {', '.join(cfg.dynamic.models)} on {', '.join(cfg.dynamic.databases)}, "
                        f"{cfg.dynamic.seeds} seeds x {cfg.dynamic.folds} folds")
        dyn = run_dynamic(cfg, campaign, campaign_dir, out / "dynamic")[1]
    if cfg.run.axes:
        from .seat import report_section, run_study

        step("axes", f"three axes: {', '.join(cfg.axes.databases)} per pilot-floor axis, {cfg.axes.seeds} seeds x "
                     f"{cfg.axes.folds} folds" + ("; discovery on the axes none serves" if cfg.axes.discovery else ""))
        axes = report_section(*run_study(cfg, campaign, campaign_dir, out / "axes")[1:], cfg)
    return dyn, axes


def _run_networks(cfg, dbs, out: Path, source) -> tuple:
    """Train (or resume) the config's sweep; Figs 10-12 and Table 1 beside the paper.

    Returns:
        (Markdown, figure paths, comparison rows).
    """
    from tqdm.auto import tqdm

    from .nets.sweep import run_sweep
    from .paper.comparison import network_checks, networks_results

    enable_compilation_cache()
    res = run_sweep(cfg, dbs, out / "sweep",
                    progress=lambda **kw: tqdm(desc="nets", unit="net", disable=not sys.stderr.isatty(), **kw))
    md, figs, pred = networks_results(res, dbs, out / "figures", str(source))
    print(md.split("\n\nPoints outside")[0])
    return md, figs, network_checks(pred)


def _run_replay(cfg, campaign, out: Path) -> tuple:
    """The offset fitted on every transient maneuver (8-rev windows), and the pull-up 11022
    replayed at zero, half-segment and fitted offsets beside the paper (Figs 13-14).

    Returns:
        (Markdown, figure paths, comparison rows, (replay set, common offset) for the studies).
    """
    from .io import markdown_table, write_table
    from .paper.comparison import PAPER_REPLAY, PULLUP, pullup_replays, replay_checks
    from .replay.studies import one_offset
    from .replay.tables import load_replay_set, select_counters

    counters = select_counters(campaign, cfg.replay)
    if PULLUP not in counters:
        counters.append(PULLUP)
    rset = load_replay_set(campaign, counters, out / "sweep", cfg.sweep.databases, analysis=cfg.analysis)
    info = rset[0]
    common = one_offset(*rset, cfg.calibration)
    tau = common.offset_s.to_dict()
    tab, figs = pullup_replays(campaign, *rset, tau, out / "figures")
    write_table(tab, out / "replay" / "figs13_14", cfg)
    cols = ["offset", "database", "offset_s", "measured_peak_g", "predicted_peak_g", "peak_error_g",
            "phase_error_s"]
    lines = [f"Offset fitted by gradient on {len(info)} transient-maneuver counters (8-rev windows): "
             + ", ".join(f"{db} {t:.2f} s" for db, t in tau.items()) + ".", "",
             "The paper: " + "; ".join(f"{db}: {v}" for db, v in PAPER_REPLAY.items() if db in rset[3]) + ".", "",
             markdown_table(tab[cols])]
    md = "\n".join(lines)
    print(md)
    return md, figs, replay_checks(tab), (rset, common)


def _run_studies(cfg, replay_set, out: Path) -> list:
    """The studies the paper left open, on the replay set of the replay stage."""
    from .io import write_table
    from .paper.comparison import PULLUP
    from .replay import studies

    rset, common = replay_set
    figures, cc = out / "figures", cfg.calibration
    sections = [studies.offset_per_kind(*rset, cc, common, figures),
                studies.window_length(*rset, cc, figures),
                studies.stick_lag(*rset, cc, common, PULLUP, figures)]
    sections = [s for s in sections if s is not None]
    for s in sections:
        for name, tab in s.tables.items():
            write_table(tab, out / "studies" / name, cfg)
        print(s.markdown.split("\n")[0] + f": {len(s.figures)} figure(s), tables in {out / 'studies'}")
    return sections


def _run_discovery(cfg, out: Path):
    """Generate (or reuse) the scenario's campaign and run discovery on it; its ground
    truth is read only afterwards, to print what was hidden beside what was named."""
    import json as _json

    from .data.campaign import load_campaign
    from .discovery import discover
    from .discovery.report import write_discovery
    from .synth import cached_campaign, load_synth_config

    scfg = load_synth_config(cfg.run.discovery_scenario)
    folder = cached_campaign(scfg)
    enable_compilation_cache()
    res = discover(load_campaign(folder, cfg.campaign.columns, cfg.analysis.window_revs,
                                harmonic=cfg.analysis.harmonic), cfg, name=str(folder))
    write_discovery(res, out, cfg)
    truth_file = folder.parent / f"{folder.name}.truth.json"
    hidden = []
    if truth_file.exists():
        for e in _json.loads(truth_file.read_text())["effects"]:
            if e["changed"]:
                hidden.append(f"{e['name']} ({'on' if e['enabled'] else 'off'}"
                              + (f", scale {e['scale']:g}" if e["enabled"] and e["scale"] != 1 else "") + ")")
    print(f"generator settings that differ from the default physics: {', '.join(hidden) or 'none'}; named: "
          f"{', '.join(e.name for e in res.effects) or 'nothing'}")
    return res, hidden


def _write_report(cfg, out: Path, summary: str, figures, paper_figs, checks, nets, reps, sections, disc,
                  seconds: float, dyn=None, axes=None) -> Path:
    """report.md (and report.html) of the main job: every number beside the paper's, the
    paper's figures and tables reproduced, the studies and the discovery scenario."""
    from .paper.comparison import comparison_markdown

    link = lambda p, alt=None: f"![{alt or p.stem}](figures/{p.name})"  # noqa: E731
    lines = [f"# pvvjax main job: {cfg.name}", "",
             f"Campaign: {cfg.campaign.path or 'the embedded synthetic UH-60A campaign'}; "
             f"{cfg.analysis.window_revs:g}-revolution windows; {seconds:.0f} s.", "",
             "Contents: [paper comparison](#every-number-beside-the-papers) · [databases](#databases-1-3) · "
             "[Figs 1-9](#paper-figs-1-9-the-pull-up-and-the-autorotation)"
             + (" · [networks](#networks-paper-figs-10-12-table-1)" if nets else "")
             + (" · [replay](#quasi-static-replay-of-the-pull-up-11022-paper-figs-13-14)" if reps else "")
             + (" · [studies](#studies-the-paper-left-open)" if sections else "")
             + (" · [discovery](#discovery-on-a-hidden-effect-scenario)" if disc else "")
             + (" · [PVV through time](#pvv-through-time-dynamic-models-against-the-quasi-static-map)"
                if dyn is not None else "")
             + (" · [three axes](#the-pilots-seat-in-three-axes-which-inputs-each-axis-needs)" if axes else ""), "",
             "## Every number beside the paper's", "", comparison_markdown(checks),
             "The same rows: `paper_comparison.csv`.", "",
             "## Databases 1-3", "", "```", summary, "```", "",
             "## Paper Figs 1-9: the pull-up and the autorotation", ""]
    for caption, p in paper_figs:
        lines += [f"**{caption}**", "", link(p, caption), ""]
    lines += ["Overview figures:", ""] + [link(p) for p in figures] + [""]
    if nets is not None:
        md, figs, _ = nets
        lines += ["## Networks (paper Figs 10-12, Table 1)", "", md.replace("# Networks", "### Networks", 1), ""]
        lines += [link(p) for p in figs] + [""]
    if reps is not None:
        md, figs, *_ = reps
        lines += ["## Quasi-static replay of the pull-up 11022 (paper Figs 13-14)", "", md, ""]
        lines += [link(p) for p in figs] + [""]
    if sections:
        lines += ["## Studies the paper left open", ""]
    for s in sections:
        lines += ["#" + s.markdown, ""]  # one level down
    if disc is not None:
        from .discovery.report import report_section

        lines += report_section(disc[0], cfg.run.discovery_scenario, disc[1])
    if dyn is not None:
        from .dynamics.reporting import report_section

        lines += report_section(dyn, "dynamic/")
    lines += axes or []
    path = out / "report.md"
    path.write_text("\n".join(lines))
    if cfg.run.html:
        import markdown

        body = markdown.markdown(path.read_text(), extensions=["tables", "fenced_code", "toc"])
        (out / "report.html").write_text(
            "<!doctype html><html><head><meta charset='utf-8'><title>pvvjax report</title><style>"
            "body{font-family:sans-serif;max-width:60em;margin:2em auto}img{max-width:100%}"
            "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 6px}</style></head><body>"
            + body + "</body></html>")
        return out / "report.html"
    return path
