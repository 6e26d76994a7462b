"""How much one world's attributable shrink moves with the nets' training seed alone.

For a hidden benchmark world and the null world of its seed, each run retrains everything
with another training seed (the config's `seed` + 1000 × run) and an ensemble of `--nets`
nets per fold: both baselines (offset calibrated, as the workflow's) and the hidden world's
model with one additive term of a fixed coefficient (no fit: the same effect every run), then
the attributable shrink (before − after) / (before − null's before). Measured on pitch
acceleration 31 in docs/discovery-studies.md ("How noisy is one world's attributable shrink"):

    python experiments/attributable_noise.py 0:pitch-acceleration 0:null-31 \\
        abs_rate:pitch_rate_dps:offset_s=0.5 0.0288 --runs 4 --nets 4

`--train KEY=VALUE ...` trains every net with other `[train]` settings (weight decay, patience,
the optimizer): whether a training regime lowers that noise ("How noisy ...", the regimes).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from discovery_benchmark import _settings  # noqa: E402
from term_backfit_probe import baseline, world  # noqa: E402

from pvvjax.discovery._confirm import _train_model  # noqa: E402
from pvvjax.discovery._model import metrics, predictions  # noqa: E402
from pvvjax.discovery.candidates import from_key  # noqa: E402


def ensemble_rms(campaign, cfg, term=None) -> tuple[float, float]:
    """The baseline's ensemble RMS, and the model's with `term` (candidate, coefficient) added."""
    ctx, base, win = baseline(campaign, cfg)
    before = metrics(predictions(ctx, base, win), win)["ensemble_rms_g"]
    if term is None:
        return before, np.nan
    c, b = term
    m = base._replace(terms=((c, np.tile([0.0, b], (cfg.discovery.folds, 1))),))
    m = m._replace(params=_train_model(ctx, m))  # the nets on the peaks minus the term
    return before, metrics(predictions(ctx, m, win), win)["ensemble_rms_g"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("hidden", help="SEED_OFFSET:SCENARIO, the hidden world")
    ap.add_argument("null", help="SEED_OFFSET:SCENARIO, the null world of the same seed")
    ap.add_argument("candidate", help="the term's candidate key, e.g. abs_rate:pitch_rate_dps:offset_s=0.5")
    ap.add_argument("coefficient", type=float, help="its fixed coefficient")
    ap.add_argument("--runs", type=int, default=4, help="training seeds")
    ap.add_argument("--nets", type=int, default=4, help="nets per fold (the config's `seeds`)")
    ap.add_argument("--train", nargs="+", action="extend", default=[], metavar="KEY=VALUE",
                    help="[train] settings over the config's (a TOML value; a bare word is a string), "
                         "e.g. --train weight_decay=0.01")
    args = ap.parse_args()
    train = _settings(args.train)
    (hc, hcfg), (nc, ncfg) = world(args.hidden, args.nets, train), world(args.null, args.nets, train)
    term = (from_key(args.candidate), args.coefficient)
    for r in range(args.runs):
        before, after = ensemble_rms(hc, dataclasses.replace(hcfg, seed=hcfg.seed + 1000 * r), term)
        null, _ = ensemble_rms(nc, dataclasses.replace(ncfg, seed=ncfg.seed + 1000 * r))
        print(f"nets {args.nets}, run {r}: before {before:.4f} g, after {after:.4f} g, null {null:.4f} g, "
              f"attributable {(before - after) / (before - null):.2f}", flush=True)


if __name__ == "__main__":
    main()
