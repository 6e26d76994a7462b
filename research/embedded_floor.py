"""Discovery toward the floor on the embedded campaign (`make demo`'s): what its vibration
depends on that db1 lacks (`world_truth.discrepancies`, each sized by switching it off in the
generator), what `discover` names from the db1 map with its defaults, and how much of the
baseline's gap to the floor the model with those effects closes. The floor is the
generator's noise-free, scatter-free law scored as a model (`world_truth.floor_g`), set
against the held-out RMS before and after, as the drawn-world benchmark does.

    python research/embedded_floor.py [--out FILE.json]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from pathlib import Path

from pvvjax.data.campaign import load_campaign
from pvvjax.discovery import discover, summary
from pvvjax.synth import SynthConfig, cached_campaign, generate

ROOT = Path(__file__).resolve().parents[1]


def _world_truth():
    spec = importlib.util.spec_from_file_location("world_truth", ROOT / "research" / "world_truth.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["world_truth"] = mod
    spec.loader.exec_module(mod)
    return mod


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=None, help="also write the result as JSON here")
    args = ap.parse_args()
    wt = _world_truth()
    cfg = SynthConfig()
    _, records, _ = generate(cfg)
    truth = wt.discrepancies(cfg, records)
    print("what db1 lacks (size where it acts / floor):")
    for e in truth["entries"]:
        print(f"  {e['name']}: {e['kind']}, {e['against_noise']:.2f}")
    res = discover(load_campaign(cached_campaign(cfg)), log=print)
    js = summary(res)
    before, after, floor = res.before["rms_g"], res.after["rms_g"], truth["floor_g"]
    closed = (before - after) / (before - floor)
    out = dict(named=[dict(name=e["name"], kind=e["kind"], p=e["adjusted_p"]) for e in js["effects"]],
               before_g=before, after_g=after, floor_g=floor, gap_closed=closed, seconds=res.seconds,
               discrepancies=[dict(name=e["name"], kind=e["kind"], against_noise=e["against_noise"])
                              for e in truth["entries"]])
    print(f"held-out RMS {before:.4f} -> {after:.4f} g, floor {floor:.4f} g: {closed:.0%} of the gap closed")
    if args.out:
        Path(args.out).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
