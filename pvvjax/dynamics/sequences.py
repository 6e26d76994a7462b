"""Sequences to learn vibration through time from: for every record, the N/rev amplitude
window by window along it (a hop of at most one revolution, from the harmonic analysis),
the flight state averaged over the same windows and, where a model takes them, its rates.
About a hundred windows a record, where the paper's databases keep one peak per condition."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..analysis.databases import STATE_CHANNELS
from ..analysis.harmonics import analyze
from ..data.batch import to_batch
from ..data.campaign import Campaign
from ..data.features import derive_features

__all__ = ["Sequences", "window_sequences"]


@dataclass(frozen=True)
class Sequences:
    """Window sequences of a campaign's records, padded to W windows (host arrays).

    Past a record's last window, times repeat its last time (a step of 0 s, which holds a
    dynamic model's state) and inputs repeat its last values; `mask` marks the real windows.

    Attributes:
        counters, conditions, maneuvers: (R,) per record.
        names: (C,) input names: the requested inputs, then `d_<name>_dt` rates if asked.
        time: (R, W) window-centre times, s. t_start, t_end: (R, W) window edges, s.
        amplitude: (R, W) the N/rev amplitude (PVV), g.
        inputs: (R, W, C) flight state averaged over each window (rates per second).
        mask: (R, W) True for the real windows.
        window_revs, hop_revs: the windows' length and spacing, revolutions.
    """

    counters: tuple[str, ...]
    conditions: tuple[str, ...]
    maneuvers: tuple[str, ...]
    names: tuple[str, ...]
    time: np.ndarray
    t_start: np.ndarray
    t_end: np.ndarray
    amplitude: np.ndarray
    inputs: np.ndarray
    mask: np.ndarray
    window_revs: float
    hop_revs: float


def window_sequences(campaign: Campaign, inputs: Sequence[str], *, window_revs: float = 2.0, hop_revs: float = 1.0,
                     rates: bool = False, harmonic: int | None = None, counters: Sequence[str] | None = None
                     ) -> Sequences:
    """The window sequences of a campaign's records.

    Args:
        campaign: a loaded campaign.
        inputs: state channels or derived features (`data.derive_features`) averaged over
            each window, e.g. a database's inputs (`analysis.DB_INPUTS["db1"]`).
        window_revs: window length, revolutions: short windows resolve the time history.
        hop_revs: window spacing, revolutions, above 0 and at most 1.
        rates: also each input's rate of change per second (central differences over the
            window times; one-sided at a record's ends).
        harmonic: the harmonic analysed (default: the aircraft's blade count, N/rev).
        counters: which records (default: every one, condition by condition).

    Returns:
        `Sequences`.
    """
    if not 0 < hop_revs <= 1:
        raise ValueError(f"hop_revs {hop_revs:g}: must lie in (0, 1] revolution (a sequence needs the windows of "
                         "every revolution)")
    counters = list(counters) if counters is not None else [c for cs in campaign.conditions().values() for c in cs]
    batch = to_batch(campaign, STATE_CHANNELS, counters)
    win = analyze(batch, window_revs, hop_revs, harmonic=harmonic or campaign.aircraft.blades)
    mask = np.asarray(win.valid)
    if not mask.any(axis=1).all():
        short = [c for c, ok in zip(counters, mask.any(axis=1)) if not ok]
        raise ValueError(f"records shorter than one {window_revs:g}-revolution window: {short}")
    means = np.asarray(win.means, np.float64)
    ch = {name: means[..., i] for i, name in enumerate(STATE_CHANNELS)}
    features = {**ch, **{k: np.asarray(v, np.float64) for k, v in derive_features(ch, campaign.aircraft).items()}}
    unknown = [n for n in inputs if n not in features]
    if unknown:
        raise ValueError(f"inputs {unknown}: neither state channels nor derived features ({sorted(features)})")
    x = np.stack([features[n] for n in inputs], axis=-1)
    time = np.asarray(win.time, np.float64)
    last = mask.shape[1] - 1 - np.argmax(mask[:, ::-1], axis=1)  # each record's last real window
    hold = np.minimum(np.arange(mask.shape[1])[None, :], last[:, None])  # past it: the last window again
    take = lambda a: np.take_along_axis(a, hold.reshape(hold.shape + (1,) * (a.ndim - 2)), axis=1)  # noqa: E731
    time, x, amp = take(time), take(x), take(np.asarray(win.amplitude, np.float64))
    names = tuple(inputs)
    if rates:
        x = np.concatenate([x, _rates(x, time, mask)], axis=-1)
        names += tuple(f"d_{n}_dt" for n in inputs)
    t_start, t_end = _edges(batch, time.shape[1], window_revs, hop_revs)
    info = campaign.counters.loc[counters]
    return Sequences(tuple(counters), tuple(info.condition), tuple(info.maneuver), names, time, take(t_start),
                     take(t_end), amp, x, mask, float(window_revs), float(hop_revs))


def _rates(x: np.ndarray, time: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """d x / d t per record over its real windows (np.gradient: central inside, one-sided at
    the ends); 0 past the last window."""
    out = np.zeros_like(x)
    for r in range(x.shape[0]):
        n = int(mask[r].sum())
        if n > 1:
            out[r, :n] = np.gradient(x[r, :n], time[r, :n], axis=0)
    return out


def _edges(batch, n_windows: int, window_revs: float, hop_revs: float) -> tuple[np.ndarray, np.ndarray]:
    """Start and end times of each window: its revolutions mapped to time along the record."""
    rev, t, m = np.asarray(batch.rev, np.float64), np.asarray(batch.time, np.float64), np.asarray(batch.mask)
    starts = hop_revs * np.arange(n_windows)
    t0, t1 = np.empty((len(rev), n_windows)), np.empty((len(rev), n_windows))
    for r in range(len(rev)):
        rv, tv = rev[r, m[r]], t[r, m[r]]
        t0[r] = np.interp(rv[0] + starts, rv, tv)
        t1[r] = np.interp(rv[0] + starts + window_revs, rv, tv)
    return t0, t1
