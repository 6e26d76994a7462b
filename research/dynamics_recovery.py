"""Probe: does the physics-shaped dynamic model (pvvjax.dynamics) identify the generator's
response on a small campaign? One seed, four folds by condition, windows of `--window` revs
at a 1-rev hop, db1 inputs; prints each fold's identified response.

    python research/dynamics_recovery.py mode   # second_order on (0.5 Hz, ζ 0.4), dynamic_lag off
    python research/dynamics_recovery.py lag    # the default campaign's effects (lag τ = 0.6 s)

Results and what they leave open: notes/dynamics-studies.md.
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np

from pvvjax.analysis.databases import DB_INPUTS
from pvvjax.config import TrainConfig, from_dict
from pvvjax.data.campaign import load_campaign
from pvvjax.dynamics import dynamic_apply, dynamic_init, identified, window_sequences
from pvvjax.nets import train
from pvvjax.nets.networks import mlp_init, scaling
from pvvjax.synth import SynthConfig, cached_campaign

COUNTS = dict(level=10, climb=3, descent=3, turn=3, roll=3, pushover=2, pullup=3, autorotation=1, flare=2)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("world", choices=["mode", "lag"])
    ap.add_argument("--window", type=float, default=2.0, help="window length, revolutions")
    ap.add_argument("--folds", type=int, default=4)
    args = ap.parse_args(argv)
    effects = {"second_order": {"enabled": True}, "dynamic_lag": {"enabled": False}} if args.world == "mode" else {}
    camp = load_campaign(cached_campaign(from_dict(SynthConfig, {"name": f"probe-{args.world}", "counts": COUNTS,
                                                                 "effects": effects})))
    inputs = DB_INPUTS["db1"]
    seq = window_sequences(camp, inputs, window_revs=args.window, hop_revs=1.0)
    x = np.concatenate([seq.inputs, seq.time[..., None]], -1).astype(np.float32)
    y, m = seq.amplitude.astype(np.float32), seq.mask.astype(np.float32)
    conditions = sorted(set(seq.conditions))
    fold_of = {c: i % args.folds for i, c in enumerate(np.random.default_rng(0).permutation(conditions))}
    folds = np.array([fold_of[c] for c in seq.conditions])
    cfg = TrainConfig(max_steps=3000, learning_rate=3e-3, patience=20)
    fit = jax.jit(lambda p, d: train.fit(p, d, cfg, apply=dynamic_apply))
    t0 = time.perf_counter()
    for f in range(args.folds):
        tr, va = folds != f, folds == f
        sc = scaling(seq.inputs[tr][seq.mask[tr]], seq.amplitude[tr][seq.mask[tr]])
        p0 = dynamic_init(mlp_init(jax.random.key(f), len(inputs), (10, 5), scale=sc))
        res = fit(p0, train.Data(x[tr], y[tr], m[tr], x[va], y[va], m[va]))
        got = {k: round(float(v), 3) for k, v in identified(res.params).items()}
        print(f"fold {f}: {got}, held-out RMS {float(res.best_val_rms):.4f} g at step {int(res.best_step)}")
    print(f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
