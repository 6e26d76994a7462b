"""Held-out PVV through time judged as a flight simulator is qualified: FAA 14 CFR Part 60,
Appendix C, table C2A, test 3.f.1 (vibrations, 1/rev and N/rev), beside the time-history
and peak errors a researcher reads.

Per condition the test passes when the simulated amplitude lies within +3 dB / −6 dB of the
measured one (a ratio of 0.501 to 1.413), or within 10 % of the nominal vibration level in
cruise; "correct trend" is rank agreement over conditions (Kendall's τ)."""

from __future__ import annotations

import numpy as np
from scipy.stats import kendalltau

__all__ = ["FAA_RATIO", "faa_pass", "nominal_cruise", "heldout_scores", "rms_by_kind", "row_peaks"]

FAA_RATIO = (10 ** (-6 / 20), 10 ** (3 / 20))  # −6 dB, +3 dB: 0.501, 1.413


def faa_pass(pred, measured, nominal_g: float) -> np.ndarray:
    """Test 3.f.1 per condition: 0.501 <= pred/measured <= 1.413, or |pred − measured| <=
    0.1 × the nominal cruise level, g."""
    pred, measured = np.asarray(pred, float), np.asarray(measured, float)
    ratio = pred / np.where(measured > 0, measured, np.nan)
    return ((ratio >= FAA_RATIO[0]) & (ratio <= FAA_RATIO[1])) | (np.abs(pred - measured) <= 0.1 * nominal_g)


def nominal_cruise(peaks, maneuvers, advance_ratio, band, key: str = "dynamic.cruise_advance_ratio") -> float:
    """The nominal vibration level in cruise, g: the median measured peak of the level
    flights whose advance ratio lies in `band` ([lo, hi]; `key`: the setting it came from,
    for the error)."""
    peaks, mu = np.asarray(peaks, float), np.asarray(advance_ratio, float)
    pick = (np.asarray(maneuvers) == "level") & (mu >= band[0]) & (mu <= band[1])
    if not pick.any():
        raise ValueError(f"no level flight with an advance ratio in {list(band)}: the nominal cruise level of the FAA "
                         f"tolerance is taken from them (set {key})")
    return float(np.median(peaks[pick]))


def row_peaks(values, mask, time) -> tuple[np.ndarray, np.ndarray]:
    """Each row's largest value over its real windows and the time of that window, s."""
    v = np.where(mask, values, -np.inf)
    k = np.argmax(v, axis=1)
    rows = np.arange(len(v))
    return v[rows, k], np.asarray(time)[rows, k]


def heldout_scores(pred, measured, mask, time, maneuvers, transients, nominal_g: float) -> dict:
    """A model's held-out metrics over rows (conditions).

    Args:
        pred, measured: (R, W) predicted and measured PVV, g (rows of NaN prediction are
            left out). mask: (R, W) real windows. time: (R, W) window times, s.
        maneuvers: (R,) kinds. transients: the kinds whose time of peak is scored.
        nominal_g: the nominal cruise level (`nominal_cruise`).

    Returns:
        rms_g and rms_transient_g (per-window time-history RMS), peak_err_rms_g,
        peak_err_median_pct, within_10pct_share (peaks), time_of_peak_err_median_s
        (transients), faa_pass_share and faa_pass_share_transient (per condition),
        kendall_tau (peaks over conditions), n_conditions, and notes: why a score is NaN
        (a score over no window or no condition is NaN, never 0).
    """
    pred, measured, mask = np.asarray(pred, float), np.asarray(measured, float), np.asarray(mask, bool)
    keep = ~np.isnan(pred).any(axis=1)
    pred, measured, mask, time = pred[keep], measured[keep], mask[keep], np.asarray(time)[keep]
    trans = np.isin(np.asarray(maneuvers)[keep], list(transients))
    err2 = np.where(mask, (pred - measured) ** 2, 0.0)

    def rms(rows):  # over the rows' real windows; NaN over none
        return float(np.sqrt(err2[rows].sum() / mask[rows].sum())) if mask[rows].any() else float("nan")

    nan_if_empty = lambda a, f: float(f(a)) if len(a) else float("nan")  # noqa: E731
    notes = []
    if not len(pred):
        notes.append("no held-out prediction: every score is NaN")
    elif not trans.any():
        notes.append(f"no condition of the transient kinds ({', '.join(transients) or 'none named'}): "
                     "rms_transient_g, time_of_peak_err_median_s and faa_pass_share_transient are NaN")
    pp, tp = row_peaks(pred, mask, time)
    pm, tm = row_peaks(measured, mask, time)
    rel = np.abs(pp - pm) / pm
    ok = faa_pass(pp, pm, nominal_g)
    tau = float(kendalltau(pp, pm).statistic) if len(pp) > 1 else float("nan")
    return dict(rms_g=rms(np.ones(len(pred), bool)), rms_transient_g=rms(trans),
                peak_err_rms_g=nan_if_empty((pp - pm) ** 2, lambda a: np.sqrt(np.mean(a))),
                peak_err_median_pct=nan_if_empty(100 * rel, np.median),
                within_10pct_share=nan_if_empty(rel <= 0.1, np.mean),
                time_of_peak_err_median_s=nan_if_empty(np.abs(tp - tm)[trans], np.median),
                faa_pass_share=nan_if_empty(ok, np.mean), faa_pass_share_transient=nan_if_empty(ok[trans], np.mean),
                kendall_tau=tau, n_conditions=int(len(pred)), notes="; ".join(notes))


def rms_by_kind(pred, measured, mask, maneuvers) -> dict[str, float]:
    """The per-window RMS error of each maneuver kind's rows, g (rows of NaN prediction left
    out; a kind with no real window left is NaN): where a model wins or loses, e.g. level
    flight, most of a campaign's windows, against the transients.

    Args:
        pred, measured: (R, W) predicted and measured PVV, g. mask: (R, W) real windows.
        maneuvers: (R,) each row's kind.

    Returns:
        {kind: RMS, g} in the order the kinds first appear.
    """
    pred, measured, mask = np.asarray(pred, float), np.asarray(measured, float), np.asarray(mask, bool)
    mask = mask & ~np.isnan(pred).any(axis=1)[:, None]
    kinds = np.asarray(maneuvers)
    out = {}
    for k in dict.fromkeys(kinds.tolist()):
        m = mask & (kinds == k)[:, None]
        out[k] = float(np.sqrt(np.mean((pred[m] - measured[m]) ** 2))) if m.any() else float("nan")
    return out
