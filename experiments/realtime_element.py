"""The real-time element on the pull-up 11022 and the autorotation AR60 (counter 11540):
streamed PVV and seat-shake signal against the flight test, and per-frame latency.

    python experiments/realtime_element.py [--docs]

Exports the db1 paper networks (experiments/paper_networks.py) as an element with the
offset fitted to 11022 (docs/replay-results.md), then plays each record at 1 kHz.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from pvvjax import plots
from pvvjax.analysis.harmonics import analyze
from pvvjax.data.batch import to_batch
from pvvjax.data.campaign import load_campaign
from pvvjax.synth import cached_campaign

OUT = Path("runs/realtime")
RECORDS = {"11022": "pull-up 11022", "11540": "autorotation AR60, segment 2 (11540)"}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--docs", action="store_true")
    args = ap.parse_args()
    run = lambda *a: subprocess.run([sys.executable, "-m", "pvvjax", *a], check=True)  # noqa: E731
    run("export", "runs/paper-networks/sweep", "--element", "--database", "db1", "--offset", "0.66",
        "--out", str(OUT / "element"))
    camp = load_campaign(cached_campaign())
    import matplotlib.pyplot as plt

    figs = []
    for counter, title in RECORDS.items():
        csv = OUT / f"stream_{counter}.csv"
        run("realtime", "--model", str(OUT / "element"), "--record", counter, "--rate", "1000", "--out", str(csv))
        s = pd.read_csv(csv)
        rec = camp.records[counter]
        w = analyze(to_batch(camp, [], [counter]), 8.0, 1.0)
        valid = np.asarray(w.valid[0])
        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
        ax1.plot(np.asarray(w.time[0])[valid], np.asarray(w.amplitude[0])[valid], "k-", lw=1.2,
                 label="flight test 4P PVV (8-rev windows every rev, at their centre)")
        ax1.plot(s.time_s, s.pvv_g, "C0-", lw=1, label="element PVV (at the frame it is ready)")
        ax1.set_ylabel("PVV, g")
        ax1.legend(fontsize=7)
        ax1.grid(alpha=0.3)
        spr = int(round(len(rec) / (np.ptp(np.unwrap(np.deg2rad(rec.azimuth_deg))) / (2 * np.pi))))
        vib = rec.az_g - rec.az_g.rolling(spr, center=True, min_periods=1).mean()  # minus the 1-rev mean
        ax2.plot(rec.time_s, vib, color="0.6", lw=0.3, label="flight test az minus its 1-rev moving mean")
        ax2.plot(s.time_s, s.shake_g, "C3-", lw=0.4, label="element seat shake (4P)")
        ax2.set_ylabel("acceleration, g")
        ax2.set_xlabel("time, s")
        ax2.legend(fontsize=7, loc="upper right")
        ax2.grid(alpha=0.3)
        fig.suptitle(f"Real-time element, {title}: db1 nets, offset 0.66 s, 1 kHz frames "
                     f"(median {s.latency_us.median():.1f} µs per frame)", fontsize=9)
        figs.append(plots.save(fig, OUT / f"realtime_{counter}.png"))
    print("figures:", *figs, sep="\n  ")
    if args.docs:
        for f in figs:
            shutil.copy(f, Path("docs/figures") / f.name)
        print("copied to docs/figures:", ", ".join(f.name for f in figs))


if __name__ == "__main__":
    main()
