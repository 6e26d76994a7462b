"""The paper's quasi-static replay (Figs 13-14) and the studies it left open: the offset fitted
by gradient (one for all maneuvers vs one per maneuver kind), the window length, and a
separate lag for the stick inputs.

    python experiments/replay_study.py experiments/configs/replay.toml [--docs]

Needs the paper networks (python experiments/paper_networks.py experiments/configs/paper-networks.toml).
Writes runs/<name>/study/ (figures, tables, results.md); with --docs also docs/figures/ and
docs/replay-results.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import shutil
import time
from pathlib import Path

import numpy as np
import pandas as pd

from pvvjax import plots
from pvvjax.cli import enable_compilation_cache, resolve_campaign
from pvvjax.config import load_config
from pvvjax.io import markdown_table as md_table
from pvvjax.io import write_table
from pvvjax.paper import PAPER_REPLAY as PAPER
from pvvjax.paper import PULLUP, pullup_replays
from pvvjax.replay_tables import (
    calibration_settings,
    calibration_table,
    cost_weights,
    counter_cost_table,
    grid_table,
    load_replay_set,
    peak_summary,
    replay_windows,
    select_counters,
    settings_at,
)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("config")
    ap.add_argument("--docs", action="store_true", help="also copy figures and results into docs/")
    args = ap.parse_args()
    t_start = time.perf_counter()
    enable_compilation_cache()
    cfg = load_config(args.config)
    out = Path(cfg.out_dir) / cfg.name / "study"
    campaign, _ = resolve_campaign(cfg)
    counters = select_counters(campaign, cfg.replay)
    info, batch, recs, models = load_replay_set(campaign, counters, cfg.replay.sweep, cfg.replay.databases)
    cc = cfg.calibration
    figs, md = [], [f"# Quasi-static replay and calibration: results\n\nConfig `{args.config}`; "
                    f"{len(info)} maneuver counters ({', '.join(sorted(set(info.maneuver)))}); each replayed by "
                    "the held-out nets (median of 4 seeds) of the paper networks.\n"]

    # ---------------------------------------------------------------- 1. offset, one for all maneuvers (L = 8)
    off_cfg = dataclasses.replace(cc, free=("offset_s",), groups="all")
    fixed8 = calibration_table(info, batch, recs, models, off_cfg, (0.0, 8.0, 0.0))
    per_kind = calibration_table(info, batch, recs, models, off_cfg, (0.0, 8.0, 0.0), groups="maneuver")
    own = calibration_table(info.loc[[PULLUP]], batch, _take(recs, [counters.index(PULLUP)]),
                            {db: _take(m, [counters.index(PULLUP)]) for db, m in models.items()}, off_cfg,
                            (0.0, 8.0, 0.0))
    tau_all = fixed8.set_index("database").offset_s

    # ---------------------------------------------------------------- 2. Figs 13-14 for the pull-up
    fig1314, figs = pullup_replays(campaign, info, batch, recs, models, tau_all.to_dict(), out,
                                   {"optimized, 11022 alone": own.set_index("database").offset_s.to_dict()})
    i = counters.index(PULLUP)
    one, rec1, models1 = info.loc[[PULLUP]], _take(recs, [i]), {db: _take(m, [i]) for db, m in models.items()}
    windows = {}
    write_table(fig1314, out / "figs13_14", cfg)
    md += ["## Paper Figs 13-14: pull-up 11022, consecutive 8-rev windows\n",
           "The paper: " + "; ".join(f"{db}: {v}" for db, v in PAPER.items()) + ".\n",
           md_table(fig1314[["offset", "database", "offset_s", "measured_peak_g", "predicted_peak_g", "peak_error_g",
                             "phase_error_s", "rms_g"]]), "",
           *[f"![{f.stem}](figures/{f.name})" for f in figs], ""]

    # ---------------------------------------------------------------- 3. one offset for all vs one per kind
    weights = cost_weights(cc)
    settings = calibration_settings(batch, off_cfg, False)
    gid_tau = {db: np.array([per_kind[(per_kind.database == db) & (per_kind.group == k)].offset_s.iloc[0]
                             for k in info.maneuver]) for db in models}
    th_all = {db: np.stack([np.full(len(info), tau_all[db]), np.full(len(info), 8.0), np.zeros(len(info))], 1)
              for db in models}
    th_kind = {db: np.stack([gid_tau[db], np.full(len(info), 8.0), np.zeros(len(info))], 1) for db in models}
    th_zero = {db: np.stack([np.zeros(len(info)), np.full(len(info), 8.0), np.zeros(len(info))], 1) for db in models}
    per_counter = []
    for name, th in (("zero", th_zero), ("one for all", th_all), ("one per kind", th_kind)):
        c = counter_cost_table(info, recs, models, th, settings, weights)
        c["offsets"] = name
        per_counter.append(c)
    per_counter = pd.concat(per_counter, ignore_index=True)
    kind_tab = (per_counter.assign(abs_peak=per_counter.peak_error_g.abs(), abs_phase=per_counter.phase_error_s.abs())
                .groupby(["database", "maneuver", "offsets"])
                .agg(cost=("cost", "mean"), median_abs_peak_error_g=("abs_peak", "median"),
                     median_abs_phase_error_s=("abs_phase", "median"), rms_g=("rms_g", "median")).reset_index())
    kind_tab = kind_tab.merge(per_kind[["database", "group", "offset_s"]].rename(columns={"group": "maneuver",
                                                                                        "offset_s": "kind_offset_s"}),
                              on=["database", "maneuver"])
    write_table(kind_tab, out / "offset_per_kind", cfg)
    totals = per_counter.groupby(["database", "offsets"]).cost.mean().unstack().reset_index()
    fig = _offset_bars(per_kind, tau_all)
    figs.append(plots.save(fig, out / "offset_per_kind.png"))
    md += ["## One offset for all maneuvers vs one per maneuver kind (8-rev windows, hop 1 rev)\n",
           "Offsets fitted by gradient (Levenberg-Marquardt from the best point of a 0.25 s grid):\n",
           md_table(per_kind[["database", "group", "n_counters", "offset_s", "cost", "steps"]]), "",
           "One offset for all maneuvers: " + ", ".join(f"{db} {t:.2f} s" for db, t in tau_all.items()) + ".\n",
           "Mean cost over all maneuver counters:\n", md_table(totals), "",
           "Per kind (median absolute errors; cost is the mean):\n",
           md_table(kind_tab), "", f"![offset per kind](figures/{figs[-1].name})", ""]

    # ---------------------------------------------------------------- 4. window length
    # (a) inputs and vibration share the window (the paper's set-up); (b) the measured PVV
    # keeps the paper's 8-rev windows and only the input averaging length varies.
    flat, profiles, t_grid = [], {}, 0.0
    for label, ref in (("shared windows", 0.0), ("8-rev reference, input window varies", 8.0)):
        wl_cfg = dataclasses.replace(cc, free=("offset_s", "window_revs"), window_bounds=(2.0, 24.0),
                                     grid_window_step_revs=1.0, coarse_window_step_revs=2.0, reference_revs=ref)
        cal_wl = calibration_table(info, batch, recs, models, wl_cfg, (0.0, 8.0, 0.0))
        t0 = time.perf_counter()
        grid = grid_table(info, recs, models, wl_cfg, batch)
        t_grid += time.perf_counter() - t0
        write_table(grid, out / f"window_grid_ref{ref:g}", cfg)
        prof = grid.groupby(["database", "window_revs"]).cost.min().reset_index()
        profiles[label] = (prof, cal_wl)
        for db, g in prof.groupby("database"):
            best = g.loc[g.cost.idxmin()]
            near = g[g.cost <= best.cost * 1.05].window_revs
            r = cal_wl[cal_wl.database == db].iloc[0]
            gd = grid[grid.database == db]
            gb = gd.loc[gd.cost.idxmin()]
            flat.append(dict(windows=label, database=db, gradient_window_revs=r.window_revs,
                             gradient_offset_s=r.offset_s, gradient_cost=r.cost, grid_window_revs=gb.window_revs,
                             grid_offset_s=gb.offset_s, grid_cost=gb.cost,
                             cost_at_8_revs=float(g[g.window_revs == 8.0].cost.iloc[0]),
                             within_5pct_of_min=f"{near.min():g}-{near.max():g} revs"))
            if ref:
                f = plots.cost_map(gd, (r.offset_s, r.window_revs), f"{db}: cost, 8-rev reference windows")
                figs.append(plots.save(f, out / f"cost_map_{db}.png"))
    flat = pd.DataFrame(flat)
    write_table(flat, out / "window_length", cfg)
    fig = _window_profile(profiles)
    figs.append(plots.save(fig, out / "window_length.png"))
    md += ["## Window length\n",
           "Offset and window length fitted together by gradient, and a brute-force grid "
           f"(0.1 s × 1 rev, {t_grid:.0f} s in all) for reference; the profile is the cost minimised over the "
           "offset at each length. With shared windows both sides smooth together as L grows; with an 8-rev "
           "reference the measured PVV stays fixed and L is the input averaging alone.\n", md_table(flat), "",
           "![window length](figures/window_length.png)", "",
           *[f"![cost map {db}](figures/cost_map_{db}.png)" for db in models], ""]

    # ---------------------------------------------------------------- 5. stick lag (db2, db3)
    stick_dbs = {db: models[db] for db in ("db2", "db3") if db in models}
    if stick_dbs:
        st_cfg = dataclasses.replace(cc, free=("offset_s", "stick_offset_s"), groups="all")
        cal_st = calibration_table(info, batch, recs, stick_dbs, st_cfg, (0.0, 8.0, 0.0))
        base = fixed8[fixed8.database.isin(stick_dbs)]
        rows = []
        for db in stick_dbs:
            b, s = base[base.database == db].iloc[0], cal_st[cal_st.database == db].iloc[0]
            rows.append(dict(database=db, offset_only_s=b.offset_s, cost_offset_only=b.cost, offset_s=s.offset_s,
                             stick_offset_s=s.stick_offset_s, cost_with_stick_lag=s.cost))
        st_tab = pd.DataFrame(rows)
        # The pull-up again, consecutive 8-rev windows: does the stick lag close the overshoot and phase error?
        pu = []
        for db in stick_dbs:
            b, s = base[base.database == db].iloc[0], cal_st[cal_st.database == db].iloc[0]
            for name, th in (("offset only", (b.offset_s, 8.0, 0.0)),
                             ("offset + stick lag", (s.offset_s, 8.0, s.stick_offset_s))):
                w = replay_windows(one, rec1, {db: models1[db]}, th, settings_at(batch, th))
                sm = peak_summary(w)
                sm.insert(0, "model", name)
                pu.append(sm)
                windows[(db, name)] = w
        pu = pd.concat(pu, ignore_index=True)
        write_table(st_tab, out / "stick_lag", cfg)
        write_table(pu, out / "stick_lag_pullup", cfg)
        fig = plots.replay({f"{db}, {name}": windows[(db, name)] for db in stick_dbs
                            for name in ("offset only", "offset + stick lag")},
                           f"pull-up {PULLUP}: sticks with their own lag (db2/db3)")
        figs.append(plots.save(fig, out / "stick_lag_11022.png"))
        md += ["## A separate lag for the stick inputs (db2, db3)\n",
               "Offset and stick lag fitted together over all maneuvers (the sticks see the state "
               "offset plus their own):\n", md_table(st_tab), "",
               "Pull-up 11022 at those values (consecutive 8-rev windows):\n",
               md_table(pu[["model", "database", "offset_s", "stick_offset_s", "predicted_peak_g", "peak_error_g",
                            "phase_error_s", "rms_g"]]), "", "![stick lag](figures/stick_lag_11022.png)", ""]

    md.append(f"Regenerate: `python experiments/replay_study.py {args.config} --docs` "
              f"({time.perf_counter() - t_start:.0f} s on the machine of docs/benchmarks.md).\n")
    text = "\n".join(md)
    (out / "results.md").write_text(text)
    print(text)
    print(f"wrote {out / 'results.md'} and {len(figs)} figures in {out}")
    if args.docs:
        for f in figs:
            shutil.copy(f, Path("docs/figures") / f.name)
        Path("docs/replay-results.md").write_text(text)
        print("copied to docs/figures and docs/replay-results.md")


def _take(tree, idx):
    import jax

    return jax.tree.map(lambda a: a[np.asarray(idx)], tree)


def _offset_bars(per_kind: pd.DataFrame, tau_all: pd.Series):
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.0, 3.6))
    kinds = list(dict.fromkeys(per_kind.group))
    dbs = list(dict.fromkeys(per_kind.database))
    x = np.arange(len(kinds))
    for k, db in enumerate(dbs):
        v = per_kind[per_kind.database == db].set_index("group").loc[kinds, "offset_s"]
        ax.bar(x + (k - 1) * 0.27, v, 0.27, color=f"C{k}", label=f"{db} per kind")
        ax.axhline(tau_all[db], color=f"C{k}", ls="--", lw=1, label=f"{db} one for all ({tau_all[db]:.2f} s)")
    ax.set_xticks(x, kinds)
    ax.set_ylabel("fitted offset, s")
    ax.set_title("Input-to-vibration offset: one per maneuver kind vs one for all", fontsize=9)
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=6, ncol=2)
    return fig


def _window_profile(profiles: dict):
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(profiles), figsize=(11.0, 3.8), sharey=False)
    for ax, (label, (prof, cal)) in zip(np.atleast_1d(axes), profiles.items()):
        for k, (db, g) in enumerate(prof.groupby("database")):
            ax.plot(g.window_revs, g.cost, "o-", ms=3, color=f"C{k}", label=f"{db}: min over offset (grid)")
            r = cal[cal.database == db].iloc[0]
            ax.plot(r.window_revs, r.cost, "x", color=f"C{k}", ms=10, mew=2, label=f"{db}: gradient optimum")
        ax.axvline(8.0, color="k", ls=":", lw=1, label="the paper's 8 revs")
        ax.set_xlabel("window length, revolutions")
        ax.set_ylabel("mean replay cost")
        ax.set_title(f"Window length, {label}", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6)
    return fig


if __name__ == "__main__":
    main()
