"""Backfitting an additive term with the nets on one benchmark world: the term's coefficient
and the held-out metrics after each refit.

The workflow adds a term in one pass (`discovery._confirm._augment`): fitted on the current
model's residual, the nets retrained on the peaks minus it, the term refitted once. Where the
nets had learned part of the effect through their own inputs, the first fit is short of it;
each further refit (retrain on the peaks minus the term, refit on the new nets' residual)
moves the coefficient towards the joint fit. Measured on pitch acceleration 31 in
docs/discovery-studies.md ("Backfitting a named term"):

    python experiments/term_backfit_probe.py 0:pitch-acceleration abs_rate:pitch_rate_dps:offset_s=0.5 --refits 4

`--window-refits N` refits the term N times on nets trained on every `train_stride`-th replay
window minus it (about 25 times the peaks: where the term's channel moves apart from the
model's inputs, the split between them has data), each time retraining the peak nets on the
peaks minus it: whether the peaks' few rows are what holds the coefficient short.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from discovery_benchmark import _campaign, find_scenario, scenario_config  # noqa: E402

from pvvjax._strict import ConfigError, from_dict, to_dict  # noqa: E402
from pvvjax.analysis.databases import DB_INPUTS  # noqa: E402
from pvvjax.config import TrainConfig  # noqa: E402
from pvvjax.discovery import Model  # noqa: E402
from pvvjax.discovery._confirm import _augment, _fit_term, _train_model  # noqa: E402
from pvvjax.discovery._fits import _fit_offset  # noqa: E402
from pvvjax.discovery._model import _replay, metrics, predictions  # noqa: E402
from pvvjax.discovery._workflow import _context  # noqa: E402
from pvvjax.discovery.candidates import from_key  # noqa: E402

CONFIG = Path(__file__).parent / "configs" / "discovery" / "benchmark.toml"


def world(job: str, nets: int | None = None, train: dict | None = None):
    """The campaign and config of SEED_OFFSET:SCENARIO of the benchmark config (with `nets`
    nets per fold: the discovery's `seeds`; `train`: [train] settings over the config's)."""
    sc, cfg = world_config(job, nets, train)
    return _campaign(sc["synth"]), cfg


def world_config(job: str, nets: int | None = None, train: dict | None = None):
    """`world`'s scenario and config, without generating the campaign."""
    offset, name = job.split(":")
    sc, overrides = find_scenario(CONFIG, int(offset), name)
    cfg = scenario_config(sc, overrides)
    if nets is not None:
        cfg = dataclasses.replace(cfg, discovery=dataclasses.replace(cfg.discovery, seeds=nets))
    if train:  # checked as a [train] table is: an unknown key or a wrong type is named
        try:
            train_cfg = from_dict(TrainConfig, {**to_dict(cfg.train), **train}, where="--train")
        except ConfigError as e:
            raise SystemExit(str(e)) from None
        cfg = dataclasses.replace(cfg, train=train_cfg)
    return sc, cfg


def baseline(campaign, cfg):
    """The workflow's baseline: peak nets that calibrate the replay, the offset fitted (and
    with `train_rows = "windows"` nets retrained on the windows there), and the held-out
    windows at it. Returns (context, model, windows)."""
    ctx = _context(campaign, cfg, lambda m: None)
    inputs = tuple(DB_INPUTS[cfg.discovery.database])
    ctx.replay_params = _train_model(ctx, Model({}, inputs), rows="peaks")
    base = _fit_offset(ctx, Model(ctx.replay_params, inputs), with_lag=False)
    if cfg.discovery.train_rows == "windows":
        base = base._replace(params=_train_model(ctx, base))
    return ctx, base, _replay(ctx, base.offset_s)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("world", help="SEED_OFFSET:SCENARIO of the benchmark config")
    ap.add_argument("candidate", help="the term's candidate key, e.g. abs_rate:pitch_rate_dps:offset_s=0.5")
    ap.add_argument("--refits", type=int, default=4, help="refits after the workflow's one pass")
    ap.add_argument("--window-refits", type=int, default=0,
                    help="refits of the term on nets trained on the windows minus it (peak nets retrained after each)")
    args = ap.parse_args()
    (campaign, cfg), c, t0 = world(args.world), from_key(args.candidate), time.perf_counter()
    ctx, base, win = baseline(campaign, cfg)

    def show(label, m):
        got = metrics(predictions(ctx, m, win), win)
        coef = f"coefficient {np.median(m.terms[-1][1][:, 1]):.5f} (median over folds); " if m.terms else ""
        print(f"{label}: {coef}ensemble RMS {got['ensemble_rms_g']:.4f} g, RMS {got['rms_g']:.4f} g, "
              f"peak error {got['peak_error_g']:.4f} g ({time.perf_counter() - t0:.0f} s)", flush=True)

    show(f"baseline (offset {base.offset_s:.2f} s)", base)
    m = _augment(ctx, base, c, "additive")
    show("the workflow's term", m)
    for k in range(args.refits):
        params = _train_model(ctx, m)  # the peaks minus the term as it stands
        term = _fit_term(ctx, base._replace(params=params), c, win)  # on the new nets' residual
        m = base._replace(params=params, terms=base.terms + ((c, term),))
        show(f"refit {k + 2}", m)
    m = base._replace(terms=base.terms + ((c, _fit_term(ctx, base, c, win)),))  # the workflow's first fit
    for k in range(args.window_refits):
        on_windows = _train_model(ctx, m, rows="windows")  # the windows minus the term as it stands
        m = base._replace(terms=base.terms + ((c, _fit_term(ctx, base._replace(params=on_windows), c, win)),))
        show(f"window refit {k + 1}", m._replace(params=_train_model(ctx, m)))  # peak nets, peaks minus it


if __name__ == "__main__":
    main()
