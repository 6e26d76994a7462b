"""A rotor-speed band added to a benchmark world's baseline in each way discovery can add it:
a gain on the nets' output (learned in steps of 1 / `gain_unit`), an extra network input,
an additive term; the nets retrained each time, the held-out ensemble RMS before and after.

Each job is SEED_OFFSET:SCENARIO of the benchmark config. `--bands top` tries the band of
the grid at the top rotor speed (where the benchmark's mode acts), `all` every band of the
grid (on a null world: what a band could gain by chance). The numbers in docs/discovery-studies.md
("A band as a network input"):

    python experiments/resonance_modes_probe.py 11:rotor-resonance,14:rotor-resonance \\
        --modes gain1,gain10,input,additive
    python experiments/resonance_modes_probe.py 1:null-51 --modes input --bands all
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from term_backfit_probe import baseline, world  # noqa: E402

from pvvjax.candidates import library  # noqa: E402
from pvvjax.discovery._confirm import _augment  # noqa: E402
from pvvjax.discovery._model import metrics, predictions  # noqa: E402


def shrinks(job: str, modes, which: str = "top") -> tuple[float, list]:
    """The baseline's ensemble RMS and, per band and mode, 1 − after / before."""
    campaign, cfg = world(job)
    ctx, base, win = baseline(campaign, cfg)
    before = metrics(predictions(ctx, base, win), win)["ensemble_rms_g"]
    bands = [c for c in library(win.at(base.offset_s), model_inputs=base.inputs) if c.operator == "resonance"]
    if which == "top":
        bands = bands[-1:]
    out = []
    for band in bands:
        band = replace(band, parameters={**band.parameters, "offset_s": base.offset_s})
        for mode in modes:
            how, unit = ("gain", float(mode[4:] or 1)) if mode.startswith("gain") else (mode, None)
            c = band if unit is None else replace(band, parameters={**band.parameters, "gain_unit": unit})
            after = metrics(predictions(ctx, _augment(ctx, base, c, how), win), win)["ensemble_rms_g"]
            out.append((band.parameters["center"], mode, 1.0 - after / before))
    return before, out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("jobs", help="comma-separated SEED_OFFSET:SCENARIO")
    ap.add_argument("--modes", default="gain1,gain10,input", help="gainU (a gain in steps of 1/U), input, additive")
    ap.add_argument("--bands", choices=("top", "all"), default="top")
    args = ap.parse_args()
    for job in args.jobs.split(","):
        t0 = time.perf_counter()
        before, rows = shrinks(job, args.modes.split(","), args.bands)
        print(f"{job}: ensemble RMS {before:.4f} g; " + "; ".join(f"{c:.1f} {m} {s:+.1%}" for c, m, s in rows)
              + f" ({time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
