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

from pvvjax.experiment import prepare_sweep
from pvvjax.paper.comparison import networks_results


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("config")
    ap.add_argument("--docs", action="store_true", help="also copy figures and tables into docs/")
    args = ap.parse_args()
    cfg, dbs, res, sweep_dir = prepare_sweep(args.config)
    out = sweep_dir.parent
    md, figs, pred = networks_results(res, dbs, out, args.config)
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
