"""The paper's architecture search as a sweep plus a selection rule, with its plot.

    python experiments/architecture_search.py experiments/configs/architecture-search.toml [--docs]
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from pvvjax import plots
from pvvjax.experiment import prepare_sweep
from pvvjax.nets.evaluation import search_architecture


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("config")
    ap.add_argument("--docs", action="store_true")
    args = ap.parse_args()
    cfg, dbs, res, sweep_dir = prepare_sweep(args.config)
    out = sweep_dir.parent
    res["width"] = [int(h.split("-")[0]) for h in res.hidden]
    for db, g in res.groupby("database"):
        val = g.groupby("width").val_rms_g.agg(median="median", q25=lambda v: v.quantile(0.25),
                                                q75=lambda v: v.quantile(0.75), count="size")
        chosen = search_architecture(val["median"])
        test = g[g.width == chosen["width"]].test_rms_g.median()
        title = f"Architecture search, {db} (n-W-5-1, median of {int(val['count'].max())} nets)"
        fig = plots.size_search(val, chosen, title)
        path = plots.save(fig, out / f"architecture_search_{db}.png")
        print(val[["median", "q25", "q75"]].round(4).to_string())
        print(f"{db}: search path {chosen['path']} -> {chosen['width']} PEs in the first layer "
              f"(validation RMS {chosen['val_rms']:.4f} g, held-out test RMS {test:.4f} g); figure {path}")
        if args.docs:
            shutil.copy(path, Path("docs/figures") / path.name)
            print(f"copied to docs/figures/{path.name}")
    print(f"sweep results: {sweep_dir / 'results.parquet'}")


if __name__ == "__main__":
    main()
