"""The paper's networks on the embedded campaign: Figs 10-12 and Table 1, from held-out
(5-fold cross-validated) predictions.

    python experiments/paper_networks.py experiments/configs/paper-networks.toml [--docs]

Writes runs/<name>/ (sweep, figures, tables); with --docs also docs/figures/ and
docs/networks-results.md (the numbers quoted in docs/networks.md).
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from pvvjax import plots
from pvvjax.cli import PAPER_TABLE1, prepare_sweep
from pvvjax.evaluation import attach_measured, heldout_predictions, table1

PAPER_T1 = {  # Table 1 of the paper: test and db1/db2/db3 predictions, g
    "T1-level-135": (0.10, 0.09, 0.10, 0.11), "T1-descent-160": (0.25, 0.24, 0.25, 0.26),
    "T1-climb-62": (0.12, 0.12, 0.12, 0.12), "T1-turn45-145": (0.13, 0.13, 0.13, 0.14),
}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("config")
    ap.add_argument("--docs", action="store_true", help="also copy figures and tables into docs/")
    args = ap.parse_args()
    cfg, dbs, res, sweep_dir = prepare_sweep(args.config)
    out = sweep_dir.parent
    pred = attach_measured(heldout_predictions(res), dbs)
    figs = []
    for i, db in enumerate(("db1", "db2", "db3")):
        sel = pred[pred.database == db]
        if sel.empty:
            continue
        arch = sel.architecture.iloc[0]
        fig = plots.correlation(sel, f"Fig {10 + i}: {db}, {arch}, median of {sel.n_nets.max()} seeds")
        figs.append(plots.save(fig, out / f"fig{10 + i}_correlation_{db}.png"))
    t1 = table1(pred, {k: v for k, v in PAPER_TABLE1.items() if k in PAPER_T1})
    for db_i, db in enumerate(("db1", "db2", "db3"), start=1):
        t1[f"paper {db}"] = [PAPER_T1[c][db_i] for c in t1.condition]
    t1 = t1[["condition", "paper test", "test", "paper db1", "db1", "paper db2", "db2", "paper db3", "db3"]]
    summary = (pred.groupby("database")
               .apply(lambda g: {"held-out RMS (g)": (g.error**2).mean() ** 0.5, "max |error| (g)": g.error.abs().max(),
                                 "95th pct |error| (g)": g.error.abs().quantile(0.95),
                                 "within ±0.05 g": (~g.outside_band).mean(), "conditions": len(g)}, include_groups=False)
               .apply(lambda d: d).to_dict())
    lines = ["# Networks on the embedded campaign: held-out results", "",
             f"Config `{args.config}`; {len(res)} nets; predictions are the median over seeds of the net that held "
             "each condition out (5-fold cross-validation by condition).", "",
             "| database | architecture | held-out RMS (g) | max abs error (g) | 95th pct abs error (g) | within ±0.05 g |",
             "|---|---|---|---|---|---|"]
    for db, d in summary.items():
        arch = pred[pred.database == db].architecture.iloc[0]
        lines.append(f"| {db} | {arch} | {d['held-out RMS (g)']:.3f} | {d['max |error| (g)']:.3f} | "
                     f"{d['95th pct |error| (g)']:.3f} | {d['within ±0.05 g']:.0%} |")
    lines += ["", "Table 1 (g): the paper's values beside the synthetic campaign's, held-out predictions.", "",
              "| " + " | ".join(t1.columns) + " |", "|" + "---|" * len(t1.columns)]
    for r in t1.itertuples(index=False):
        lines.append("| " + " | ".join(f"{v:.3f}" if isinstance(v, float) else str(v) for v in r) + " |")
    flagged = pred[pred.outside_band].sort_values("error", key=abs, ascending=False)
    lines += ["", f"Points outside ±0.05 g (flagged as possible bad data, as the paper does): {len(flagged)}", "",
              "| database | condition | maneuver | measured | predicted |", "|---|---|---|---|---|"]
    for r in flagged.head(15).itertuples():
        lines.append(f"| {r.database} | {r.condition} | {r.maneuver} | {r.measured:.3f} | {r.predicted:.3f} |")
    md = "\n".join(lines) + "\n"
    (out / "results.md").write_text(md)
    pred.to_csv(out / "heldout_predictions.csv", index=False)
    print(md)
    print(f"wrote {out / 'results.md'}, {out / 'heldout_predictions.csv'} and figures:")
    for f in figs:
        print(f"  {f}")
    if args.docs:
        for f in figs:
            shutil.copy(f, Path("docs/figures") / f.name)
        Path("docs/networks-results.md").write_text(md.replace("](", "](figures/"))
        print("copied to docs/figures and docs/networks-results.md")


if __name__ == "__main__":
    main()
