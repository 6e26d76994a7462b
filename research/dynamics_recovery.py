"""Probe: does the physics-shaped dynamic model identify the generator's response? The
window-level db1 map and the response behind it (`pvvjax.dynamics.fit_response`), every fold
by condition × `--seeds`,, on windows of `--window` revs at a 1-rev hop; prints the identified
response per net and its median.

    python research/dynamics_recovery.py mode   # second_order on (0.5 Hz, ζ 0.4), dynamic_lag off
    python research/dynamics_recovery.py lag    # the default effects (first-order lag τ = 0.6 s)
    python research/dynamics_recovery.py lag --full   # on the embedded campaign, not the small one

Results and what they leave open: notes/dynamics-studies.md.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pvvjax.analysis import DB_INPUTS
from pvvjax.config import DynamicConfig, TrainConfig, from_dict
from pvvjax.data import load_campaign
from pvvjax.dynamics import (
    compare,
    condition_split,
    dynamic_apply,
    fit_sequence_model,
    window_sequences,
)
from pvvjax.synth import SynthConfig, cached_campaign

COUNTS = dict(level=10, climb=3, descent=3, turn=3, roll=3, pushover=2, pullup=3, autorotation=1, flare=2)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("world", choices=["mode", "lag"])
    ap.add_argument("--window", type=float, default=2.0, help="window length, revolutions")
    ap.add_argument("--folds", type=int, default=4)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--full", action="store_true", help="the embedded campaign's conditions (default: a small one)")
    ap.add_argument("--lr", type=float, default=3e-3, help="joint training's step size")
    ap.add_argument("--rates", action="store_true", help="the map takes the inputs' rates too")
    ap.add_argument("--clean", action="store_true", help="the rate-driven effects off (pitch and roll rate, pitch "
                                                         "acceleration, sideslip): the map's inputs explain the rest")
    args = ap.parse_args(argv)
    effects = {"second_order": {"enabled": True}, "dynamic_lag": {"enabled": False}} if args.world == "mode" else {}
    if args.clean:
        effects = {**effects, **{k: {"enabled": False} for k in ("pitch_rate", "roll_rate", "pitch_acceleration",
                                                                   "sideslip")}}
    scfg = {"name": f"probe-{args.world}", "effects": effects, **({} if args.full else {"counts": COUNTS})}
    camp = load_campaign(cached_campaign(from_dict(SynthConfig, scfg)))
    seq = window_sequences(camp, DB_INPUTS["db1"], window_revs=args.window, hop_revs=1.0, chain=True,
                           rates=args.rates)
    split = condition_split(seq.conditions, args.folds, 0)
    t0 = time.perf_counter()
    x = compare.model_inputs(seq, "window_static_rates" if args.rates else "window_static")
    init = compare.dynamic_model_init(x.shape[-1], (10, 5), DynamicConfig())
    xt = np.concatenate([x, seq.time[..., None]], axis=-1)
    dyn = fit_sequence_model(init, dynamic_apply, xt, seq.amplitude, seq.mask, split, args.seeds,
                             TrainConfig(learning_rate=args.lr))
    ident = compare.identified_table(dyn.params)
    for k, v in ident.items():
        print(f"{k:18s} median {np.median(v):.3f}  per net {np.round(np.ravel(v), 3).tolist()}")
    print(f"best steps {np.ravel(dyn.best_step).tolist()}; {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
