"""The paper's quasi-static replay (Figs 13-14) and the studies it left open: the offset fitted
by gradient (one for all maneuvers vs one per maneuver kind), the window length, and a
separate lag for the stick inputs (`pvvjax.replay.studies`).

    python experiments/replay_study.py experiments/configs/replay.toml [--docs]

Needs the paper networks (python experiments/paper_networks.py experiments/configs/paper-networks.toml).
Writes runs/<name>/study/ (results.md, its tables, figures/); with --docs also docs/figures/ and
docs/replay-results.md.
"""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

from pvvjax.config import load_config
from pvvjax.experiment import enable_compilation_cache, resolve_campaign
from pvvjax.io import markdown_table, write_table
from pvvjax.paper.comparison import PAPER_REPLAY, PULLUP, pullup_replays
from pvvjax.replay.quasistatic import studies
from pvvjax.replay.tables import load_replay_set, select_counters, take_counters


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
    info, batch, recs, models = load_replay_set(campaign, counters, cfg.replay.sweep, cfg.replay.databases,
                                                analysis=cfg.analysis)
    cc = cfg.calibration
    fig_dir = out / "figures"
    md = [f"# Quasi-static replay and calibration: results\n\nConfig `{args.config}`; "
          f"{len(info)} maneuver counters ({', '.join(sorted(set(info.maneuver)))}); each replayed by "
          "the held-out nets (median of 4 seeds) of the paper networks.\n"]

    common = studies.one_offset(info, batch, recs, models, cc)
    i = counters.index(PULLUP)
    own = studies.one_offset(info.loc[[PULLUP]], batch, *take_counters((recs, models), [i]), cc)
    fig1314, figs = pullup_replays(campaign, info, batch, recs, models, common.offset_s.to_dict(), fig_dir,
                                   {"optimized, 11022 alone": own.offset_s.to_dict()})
    write_table(fig1314, out / "figs13_14", cfg)
    md += ["## Paper Figs 13-14: pull-up 11022, consecutive 8-rev windows\n",
           "The paper: " + "; ".join(f"{db}: {v}" for db, v in PAPER_REPLAY.items()) + ".\n",
           markdown_table(fig1314[["offset", "database", "offset_s", "measured_peak_g", "predicted_peak_g",
                                   "peak_error_g", "phase_error_s", "rms_g"]]), "",
           *[f"![{f.stem}](figures/{f.name})" for f in figs], ""]

    sections = [studies.offset_per_kind(info, batch, recs, models, cc, common, fig_dir),
                studies.window_length(info, batch, recs, models, cc, fig_dir),
                studies.stick_lag(info, batch, recs, models, cc, common, PULLUP, fig_dir)]
    for s in filter(None, sections):
        md.append(s.markdown)
        figs += list(s.figures)
        for name, tab in s.tables.items():
            write_table(tab, out / name, cfg)

    md.append(f"Regenerate: `python experiments/replay_study.py {args.config} --docs` "
              f"({time.perf_counter() - t_start:.0f} s on the machine of docs/benchmarks.md).\n")
    text = "\n".join(md)
    (out / "results.md").write_text(text)
    print(text)
    print(f"wrote {out / 'results.md'}, its tables and {len(figs)} figures in {out}")
    if args.docs:
        for f in figs:
            shutil.copy(f, Path("docs/figures") / f.name)
        Path("docs/replay-results.md").write_text(text)
        print(f"copied {len(figs)} figures to docs/figures and the results to docs/replay-results.md")


if __name__ == "__main__":
    main()
