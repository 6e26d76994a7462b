"""Which of two tied candidates encompasses the other, on one benchmark world.

A round's retrainings can tie two candidates on different channels that carry the same
kinematics (the coordinated turn's |ṙ| is the roll rate weighted by sec²φ / V), and the
workflow then names the one the selection credits with more gain (`discovery._confirm._choose`).
An encompassing test asks instead what each adds on top of the other: both are added as
additive terms to the workflow's baseline, alone and each on top of the other, and the
ensemble's held-out RMS and each term's coefficient are compared. A term fitted on top of
the other keeps the share of its coefficient that the other does not explain: the candidate
that keeps more of its own explains more of the other's gain than the other of its. The
`RESULT` line of each training draw (`--draws`; tab-separated): the draw, each alone, each on
top of the other (shrinks of the ensemble's RMS), then the coefficient kept by b on top of a
and by a on top of b.
Measured on every cross-channel tie of the benchmark's table and of seeds + 15 in
docs/discovery-studies.md ("An encompassing test between tied channels"); the rule built on it
is `[discovery] encompassing` (`discovery._round._kept_on_top`, the same measure):

    python experiments/encompassing_probe.py 15:roll-rate \
        input:roll_rate_dps:offset_s=0.5,transform=abs abs_rate:yaw_rate_dps:offset_s=0.5 --draws 4
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from term_backfit_probe import baseline, world  # noqa: E402

from pvvjax.discovery._confirm import _augment  # noqa: E402
from pvvjax.discovery._model import metrics, predictions  # noqa: E402
from pvvjax.discovery.candidates import from_key  # noqa: E402


def on_top(before: float, after: float) -> float:
    """The share of `before`'s ensemble RMS that a term added on top of it removes."""
    return (before - after) / before


def compare(campaign, cfg, a, b, t0: float) -> tuple:
    """Both terms alone and each on top of the other, on the workflow's baseline of `cfg`.
    Returns (a alone, b alone, b on a, a on b) as shrinks of the ensemble's RMS, then the
    coefficient b keeps on top of a and a on top of b (shares of each one's own alone)."""
    ctx, base, win = baseline(campaign, cfg)

    def rms(label, m) -> tuple[float, float]:
        """The ensemble's held-out RMS of `m`, and its last term's coefficient (median over folds)."""
        got = metrics(predictions(ctx, m, win), win)
        coefs = ", ".join(f"{c.name} {np.median(t[:, 1]):.5f}" for c, t in m.terms)
        print(f"  {label}: ensemble RMS {got['ensemble_rms_g']:.4f} g, RMS {got['rms_g']:.4f} g"
              + (f"; coefficients (median over folds) {coefs}" if coefs else "")
              + f" ({time.perf_counter() - t0:.0f} s)", flush=True)
        return got["ensemble_rms_g"], float(np.median(m.terms[-1][1][:, 1])) if m.terms else np.nan

    r0, _ = rms(f"baseline (offset {base.offset_s:.2f} s)", base)
    ma, mb = _augment(ctx, base, a, "additive"), _augment(ctx, base, b, "additive")
    (ra, ka), (rb, kb) = rms(f"+ {a.name}", ma), rms(f"+ {b.name}", mb)
    rab, kab = rms(f"+ {a.name} + {b.name}", _augment(ctx, ma, b, "additive"))
    rba, kba = rms(f"+ {b.name} + {a.name}", _augment(ctx, mb, a, "additive"))
    # A term fitted on top of the other keeps the share of its own coefficient that the
    # other does not explain: ~0 where the other encompasses it.
    return on_top(r0, ra), on_top(r0, rb), on_top(ra, rab), on_top(rb, rba), kab / kb, kba / ka


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("world", help="SEED_OFFSET:SCENARIO of the benchmark config")
    ap.add_argument("a", help="a candidate key (its proposal, without a fitted coefficient)")
    ap.add_argument("b", help="the other candidate key")
    ap.add_argument("--draws", type=int, default=1,
                    help="training draws (the config's seed + 1000 × draw; draw 0 is the discovery's own)")
    args = ap.parse_args()
    (campaign, cfg), t0 = world(args.world), time.perf_counter()
    a, b = from_key(args.a), from_key(args.b)
    for draw in range(args.draws):
        print(f"draw {draw}:", flush=True)
        got = compare(campaign, dataclasses.replace(cfg, seed=cfg.seed + 1000 * draw), a, b, t0)
        print(f"  alone: {a.name} {got[0]:+.1%}, {b.name} {got[1]:+.1%}; on top of the other: {b.name} on "
              f"{a.name} {got[2]:+.1%}, {a.name} on {b.name} {got[3]:+.1%}; coefficient kept on top of the "
              f"other: {b.name} {got[4]:.2f}, {a.name} {got[5]:.2f}")
        print("RESULT\t" + "\t".join(f"{v:.4f}" for v in (draw, *got)), flush=True)


if __name__ == "__main__":
    main()
