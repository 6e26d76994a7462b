"""Does the vibration lag the flight state? Asked of nets trained *through* the lag.

Discovery's lag candidate (`discovery`) lags the prediction of nets trained without a lag;
the nets have already absorbed the lag (the offset moves, the peaks they learn are lowered),
so a lag only adds smoothing. Here the nets are trained on the replay windows with the lag
undone in their targets (`delag`: the static vibration a first-order lag τ turns into the
measured one), their lagged replay is compared with nets trained without a lag, and both
get the same freedom of offset: a fair test of a lag against a pure delay.

The study (`lag_study`) is a measurement, not yet a step of `discover`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .campaign import Campaign
from .config import ExperimentConfig
from .databases import DB_INPUTS
from .discovery import Model, _context, _fit_offset, _inputs, _replay, _train_model, fit_ensemble, metrics, predictions

__all__ = ["delag", "lag_study"]


def delag(y, time_s, counter, tau_s: float, span: int = 4) -> np.ndarray:
    """The input of a first-order lag whose output is `y`: u = y + τ·dy/dt per counter.

    dy/dt is a central difference over ±`span` windows (one-sided at a counter's ends): an
    8-revolution window series is smooth over that span, and a shorter difference would
    amplify the harmonic analysis' noise by τ/Δt.

    Args:
        y, time_s, counter: (n,) window values, their times, s, and the counter of each
            (windows of one counter in any order). tau_s: time constant, s (0: `y` itself).
        span: half-width of the difference, windows.

    Returns:
        (n,) the de-lagged series.
    """
    y, t = np.asarray(y, float), np.asarray(time_s, float)
    if tau_s <= 0:
        return y.copy()
    out = np.empty_like(y)
    for idx in pd.Series(np.arange(len(y))).groupby(np.asarray(counter)).indices.values():
        idx = idx[np.argsort(t[idx], kind="stable")]
        n = np.arange(len(idx))
        lo, hi = idx[np.maximum(n - span, 0)], idx[np.minimum(n + span, len(idx) - 1)]
        dt = t[hi] - t[lo]
        out[idx] = y[idx] + tau_s * np.divide(y[hi] - y[lo], dt, out=np.zeros(len(idx)), where=dt > 0)
    return out


def lag_study(campaign: Campaign, cfg: ExperimentConfig, taus=(1.0, 2.0, 3.0), reference_offsets=(0.0, 0.5),
              log=print) -> pd.DataFrame:
    """Nets trained on the windows through a lag of each τ, against nets trained without one.

    The peak nets of `discover` calibrate the offset δ. The reference (τ = 0) is trained at δ
    and at each of `reference_offsets`; each τ at max(0, δ − τ) (a lag delays by about τ).
    Every ensemble is trained like `train_rows = "windows"` (every `train_stride`-th full
    window, k-fold by condition × seeds), on the de-lagged windows (`delag`), and replayed
    with its lag; then its offset is refitted on the held-out windows (the `offset_bounds`
    grid), so that a lag is not credited with a better delay.

    Args:
        campaign: any campaign. cfg: its `discovery` and `train` sections are used.
        taus: lag time constants tried, s (> 0). reference_offsets: training offsets of the
            reference nets besides δ, s (inside `discovery.offset_bounds`).
        log: progress messages.

    Returns:
        One row per trained ensemble: tau_s, train_offset_s, offset_s (refitted),
        ensemble_rms_g (held-out RMS of the median over seeds, on the full windows), rms_g
        and peak_error_g (`discovery.metrics`), and drop (1 − its ensemble RMS / the best
        reference's).
    """
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
    runs = [(0.0, float(o)) for o in sorted({*map(float, reference_offsets), delta})]
    runs += [(float(t), max(lo, round(delta - t, 6))) for t in taus]
    rows = []
    for tau, off in runs:
        win = _replay(ctx, off)
        t = win.table
        sel = (t.weight.to_numpy() >= 0.999) & (t.k.to_numpy() % d.train_stride == 0)
        target = delag(t.measured_g.to_numpy(), t.time_s.to_numpy(), t.i.to_numpy(), tau)
        params = fit_ensemble(_inputs(Model({}, inputs), win)[sel], target[sel],
                              ctx.counter_fold[t.i.to_numpy()[sel]], k=d.folds, seeds=d.seeds, hidden=d.hidden,
                              train_cfg=cfg.train, seed=cfg.seed)
        model = _fit_offset(ctx, Model(params, inputs, lag_tau_s=tau), with_lag=False)
        win = _replay(ctx, model.offset_s)
        full = win.table.weight.to_numpy() >= 0.999
        pred = predictions(ctx, model, win)
        ens = np.median(pred, axis=0)[full] - win.table.measured_g.to_numpy()[full]
        m = metrics(pred, win)
        rows.append(dict(tau_s=tau, train_offset_s=off, offset_s=model.offset_s,
                         ensemble_rms_g=float(np.sqrt(np.mean(ens**2))), rms_g=m["rms_g"],
                         peak_error_g=m["peak_error_g"]))
        log(f"  τ {tau:.2f} s trained at {off:.2f} s, refitted offset {model.offset_s:.2f} s: "
            f"ensemble RMS {rows[-1]['ensemble_rms_g']:.4f} g")
    out = pd.DataFrame(rows)
    ref = out.ensemble_rms_g[out.tau_s == 0].min()
    return out.assign(drop=1.0 - out.ensemble_rms_g / ref)
