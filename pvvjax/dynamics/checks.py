"""Results checked like inputs: a model of PVV through time is degenerate when its held-out
prediction is missing or constant through a record whose measured vibration varies, when a
parameter is not finite, or when its identified response leaves the range the campaign can
show (a delay longer than the records, a mode faster than the windows resolve or slower
than a record lasts). A degenerate model is flagged in the comparison and is never `best`.

The same range is the one `[dynamic]`'s starting response is checked against before any
work (`check_dynamic`), so a setting that can only train a degenerate model is refused by
its key."""

from __future__ import annotations

from typing import NamedTuple

import jax
import numpy as np

from ..config import ZETA_RANGE
from ..io import listed

__all__ = ["ResponseLimits", "check_dynamic", "constant_rows", "parameter_problems", "prediction_problems",
           "response_limits"]

# A record varies when its measured window amplitudes spread by more than this share of their
# mean; a prediction is constant on it when its spread is below this share of the measured one.
VARIES_SHARE = 0.05
CONSTANT_SHARE = 1e-3


class ResponseLimits(NamedTuple):
    """The range a response identified on a campaign can be trusted in ([lo, hi] each).

    Attributes:
        f_n_hz: natural frequency, Hz: a period no longer than 2π × the median record (one
            radian per record at least) and no faster than the windows' Nyquist rate.
        zeta: damping ratio (`config.ZETA_RANGE`).
        delay_s: delay, s: at most half the median record (a longer delay holds a record's
            first value through most of it).
        record_s: the median record's duration, s. window_rate_hz: windows per second.
    """

    f_n_hz: tuple[float, float]
    zeta: tuple[float, float]
    delay_s: tuple[float, float]
    record_s: float
    window_rate_hz: float


def response_limits(record_s: float, window_spacing_s: float) -> ResponseLimits:
    """`ResponseLimits` of records of median duration `record_s` (s) analysed every
    `window_spacing_s` (s)."""
    rate = 1.0 / window_spacing_s
    return ResponseLimits((1.0 / (2 * np.pi * record_s), 0.5 * rate), ZETA_RANGE, (0.0, 0.5 * record_s),
                          float(record_s), float(rate))


def _campaign_limits(campaign, hop_revs: float) -> tuple[ResponseLimits, float, float]:
    """(the response's limits, the shortest condition's duration, s, a revolution, s) of a
    campaign whose conditions' records are joined in time, windows `hop_revs` apart."""
    dur = {c: float(r.time_s.iloc[-1] - r.time_s.iloc[0]) for c, r in campaign.records.items()}
    per_condition = [sum(dur[c] for c in cs) for cs in campaign.conditions().values()]
    rpm = float(np.median([np.median(r.rotor_rpm) for r in campaign.records.values()]))
    rev_s = 60.0 / rpm
    return response_limits(float(np.median(per_condition)), hop_revs * rev_s), float(min(per_condition)), rev_s


def check_dynamic(cfg, campaign) -> None:
    """Refuse, by dotted key and before any work, the `[dynamic]` settings (and `[analysis]
    axis`) that this campaign cannot support: an axis it does not carry, a starting response
    outside `ResponseLimits`, windows or an offset grid longer than its shortest condition,
    more folds than conditions, transient kinds it does not fly (a warning: their scores
    are NaN with the reason), or no level flight in the cruise band."""
    import warnings

    from ..analysis import require_axis

    dc = cfg.dynamic
    require_axis(campaign, cfg.analysis.axis)
    lim, shortest, rev_s = _campaign_limits(campaign, dc.hop_revs)
    checks = [("f_n_hz", dc.f_n_hz, lim.f_n_hz, "Hz", "a period within 2π x the median record "
               f"({lim.record_s:.3g} s) and at most half the window rate ({lim.window_rate_hz:.3g} windows/s: "
               "dynamic.hop_revs)"),
              ("delay_s", dc.delay_s, lim.delay_s, "s", f"at most half the median record ({lim.record_s:.3g} s)")]
    for key, value, (lo, hi), unit, why in checks:
        if not lo <= value <= hi:
            raise ValueError(f"dynamic.{key} = {value:g} {unit}: outside {lo:.3g} to {hi:.3g} {unit} on campaign "
                             f"{campaign.source} ({why})")
    if dc.window_revs * rev_s > shortest:
        raise ValueError(f"dynamic.window_revs = {dc.window_revs:g}: {dc.window_revs * rev_s:.3g} s, longer than the "
                         f"shortest condition of campaign {campaign.source} ({shortest:.3g} s)")
    lo, hi = dc.offset_bounds
    if max(abs(lo), abs(hi)) > shortest:
        raise ValueError(f"dynamic.offset_bounds = {[lo, hi]}: an offset beyond the shortest condition of campaign "
                         f"{campaign.source} ({shortest:.3g} s) moves every window out of it")
    n_cond = len(campaign.conditions())
    if dc.folds > n_cond:
        raise ValueError(f"dynamic.folds = {dc.folds}: campaign {campaign.source} has {n_cond} condition(s); a k-fold "
                         "split by condition needs at least k")
    flown = set(campaign.counters.maneuver)
    absent = [k for k in dc.transients if k not in flown]
    if absent:
        warnings.warn(f"dynamic.transients: campaign {campaign.source} flies no {', '.join(absent)}; "
                      + ("their time of peak is not scored" if len(absent) < len(dc.transients) else
                         "no transient is scored (rms_transient_g and the time of peak are NaN, with the reason)"),
                      stacklevel=2)


def constant_rows(pred, measured, mask) -> np.ndarray:
    """(R,) bool: the rows whose measured amplitude varies (spread above `VARIES_SHARE` of
    its mean) while the prediction does not (spread below `CONSTANT_SHARE` of the measured)."""
    pred, measured, mask = np.asarray(pred, float), np.asarray(measured, float), np.asarray(mask, bool)
    n = mask.sum(axis=1)
    ok = (n >= 3) & np.isfinite(np.where(mask, pred, 0.0)).all(axis=1)

    def spread(v):
        m = np.where(mask, v, 0.0).sum(axis=1) / np.maximum(n, 1)
        return np.sqrt((np.where(mask, v - m[:, None], 0.0) ** 2).sum(axis=1) / np.maximum(n, 1)), m

    s_meas, m_meas = spread(measured)
    s_pred, _ = spread(np.where(np.isfinite(pred), pred, 0.0))
    varies = ok & (s_meas > VARIES_SHARE * np.abs(m_meas))
    return varies & (s_pred <= CONSTANT_SHARE * s_meas)


def prediction_problems(pred, measured, mask, conditions) -> list[str]:
    """Why a held-out prediction (R, W) cannot be trusted: rows with no prediction, and rows
    that vary while the prediction is constant (`constant_rows`), naming them."""
    pred, mask = np.asarray(pred, float), np.asarray(mask, bool)
    out = []
    missing = [c for c, p, m in zip(conditions, pred, mask) if m.any() and not np.isfinite(p[m]).all()]
    if missing:
        out.append(f"no finite prediction on {len(missing)} of {len(conditions)} conditions "
                   f"({listed(missing)})")
    flat = [c for c, bad in zip(conditions, constant_rows(pred, measured, mask)) if bad]
    if flat:
        out.append(f"a constant prediction through {len(flat)} condition(s) whose vibration varies "
                   f"({listed(flat)})")
    return out


def parameter_problems(params, limits: ResponseLimits | None = None) -> list[str]:
    """Why a model's nets (params stacked over folds and seeds) cannot be trusted: a
    non-finite parameter, or (`limits` given, a dynamic model) an identified response whose
    median over the nets lies outside `limits`, naming the parameter."""
    from .models import identified

    leaves = jax.tree.leaves(params)
    bad = [np.asarray(a) for a in leaves if not np.isfinite(np.asarray(a, float)).all()]
    out = [f"non-finite parameters in {len(bad)} of {len(leaves)} arrays"] if bad else []
    if limits is not None and "response" in params:
        ident = identified(params)
        for key, (lo, hi) in (("f_n_hz", limits.f_n_hz), ("zeta", limits.zeta), ("delay_s", limits.delay_s)):
            v = float(np.median(ident[key]))
            if not (np.isfinite(v) and lo <= v <= hi):
                out.append(f"identified {key} {v:.4g} outside its range {lo:.3g} to {hi:.3g}")
    return out


