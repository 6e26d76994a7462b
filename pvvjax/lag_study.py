"""Does the vibration lag the flight state? Asked of nets trained *through* the lag.

Discovery's lag candidate (`discovery`) lags the prediction of nets trained without a lag;
the nets have already absorbed the lag (the offset moves, the peaks they learn are lowered),
so a lag only adds smoothing. Here the nets are trained on the replay windows with the lag
undone in their targets (`discovery.delag`: the static vibration a first-order lag τ turns into the
measured one), their lagged replay is compared with nets trained without a lag, and both
get the same freedom of offset: a fair test of a lag against a pure delay.

With `[discovery] lag_test = true`, `discover` runs the same trainings as its first step
where a lag learned inside one training has confirmed a slow lag (`lag_slow_s`), to add it
(on every world with `lag_trials_always`); `lag_study` runs them on any world and reports
them all.
"""

from __future__ import annotations

import os

import pandas as pd

from .campaign import Campaign
from .config import DiscoveryConfig, ExperimentConfig
from .databases import DB_INPUTS
from .discovery import Model
from .discovery._confirm import _train_model
from .discovery._fits import _fit_offset
from .discovery._lag import _lag_trials
from .discovery._workflow import _context, _workflow_inputs

__all__ = ["lag_study"]


def lag_study(campaign: Campaign | str | os.PathLike, cfg: ExperimentConfig | DiscoveryConfig, taus=(1.0, 2.0, 3.0),
              reference_offsets=(0.0, 0.5), log=print) -> pd.DataFrame:
    """Nets trained on the windows through a lag of each τ, against nets trained without one.

    The peak nets of `discover` calibrate the offset δ. The reference (τ = 0) is trained at δ
    and at each of `reference_offsets`; each τ at max(0, δ − τ) (a lag delays by about τ).
    Every ensemble is trained like `train_rows = "windows"` (every `train_stride`-th full
    window, k-fold by condition × seeds), on the de-lagged windows (`discovery.delag`), and replayed
    with its lag; then its offset is refitted on the held-out windows (the `offset_bounds`
    grid), so that a lag is not credited with a better delay. The same trainings as the lag
    test of `discover` (`discovery.lag_test`), every row reported.

    Args:
        campaign: any campaign, or its folder. cfg: its `discovery` and `train` sections
            are used (or a bare `DiscoveryConfig`).
        taus: lag time constants tried, s (> 0). reference_offsets: training offsets of the
            reference nets besides δ, s (inside `discovery.offset_bounds`).
        log: progress messages.

    Returns:
        One row per trained ensemble: tau_s, train_offset_s, offset_s (refitted),
        ensemble_rms_g (held-out RMS of the median over seeds, on the full windows), rms_g
        and peak_error_g (`discovery.metrics`), and drop (1 − its ensemble RMS / the best
        reference's).
    """
    campaign, cfg, _ = _workflow_inputs("lag_study", campaign, cfg)
    d = cfg.discovery
    lo, hi = d.offset_bounds
    bad = [o for o in reference_offsets if not lo <= o <= hi]
    if bad or any(t <= 0 for t in taus):
        raise ValueError(f"lag_study: taus must be > 0 and reference_offsets inside discovery.offset_bounds "
                         f"{[lo, hi]}; got taus {list(taus)}, reference_offsets {list(reference_offsets)}")
    inputs = tuple(DB_INPUTS[d.database])
    ctx = _context(campaign, cfg, log)
    ctx.replay_params = _train_model(ctx, Model({}, inputs), rows="peaks")
    delta = _fit_offset(ctx, Model(ctx.replay_params, inputs), with_lag=False).offset_s
    log(f"lag study: peak nets' offset {delta:.2f} s")
    out = pd.DataFrame([dict(tau_s=t["tau_s"], train_offset_s=t["train_offset_s"], offset_s=t["model"].offset_s,
                             ensemble_rms_g=t["ensemble_rms_g"], rms_g=t["metrics"]["rms_g"],
                             peak_error_g=t["metrics"]["peak_error_g"])
                        for t in _lag_trials(ctx, delta, taus, reference_offsets, log)])
    ref = out.ensemble_rms_g[out.tau_s == 0].min()
    return out.assign(drop=1.0 - out.ensemble_rms_g / ref)
