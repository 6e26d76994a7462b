"""Sequences to learn vibration through time from: for every record, the N/rev amplitude
window by window along it (a hop of at most one revolution, from the harmonic analysis),
the flight state averaged over the same windows and, where a model takes them, its rates.
About a hundred windows a record, where the paper's databases keep one peak per condition."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..analysis.databases import STATE_CHANNELS, analyze_by_length
from ..data.batch import to_batch
from ..data.campaign import Campaign
from ..data.features import derive_features

__all__ = ["Sequences", "window_sequences"]


@dataclass(frozen=True)
class Sequences:
    """Window sequences of a campaign's records, padded to W windows (host arrays).

    A row is one record, or with `chain` one condition's records in segment order, joined
    into one flight (the later segment's clock continues from the earlier one's end, so that
    a dynamic model's state carries across the join). Past a row's last window, times repeat
    its last time (a step of 0 s, which holds a dynamic model's state) and inputs repeat its
    last values; `mask` marks the real windows.

    Attributes:
        counters: (R,) the row's record, or its records joined by "+".
        conditions, maneuvers: (R,) per row.
        names: (C,) input names: the requested inputs, then `d_<name>_dt` rates if asked.
        time: (R, W) window-centre times along the row, s. t_start, t_end: (R, W) window
            edges, s, on each window's own record's clock.
        record: (R, W) the record (counter) each window belongs to.
        amplitude: (R, W) the N/rev amplitude (PVV), g.
        inputs: (R, W, C) flight state averaged over each window (rates per second).
        mask: (R, W) True for the real windows.
        window_revs, hop_revs: the windows' length and spacing, revolutions.
    """

    counters: tuple[str, ...]
    record: np.ndarray
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
                     rates: bool = False, harmonic: int | None = None, counters: Sequence[str] | None = None,
                     chain: bool = False, axis: str = "az_g") -> Sequences:
    """The window sequences of a campaign's records.

    Args:
        campaign: a loaded campaign.
        inputs: state channels or derived features (`data.derive_features`) averaged over
            each window, e.g. a database's inputs (`analysis.DB_INPUTS["db1"]`).
        window_revs: window length, revolutions: short windows resolve the time history.
        hop_revs: window spacing, revolutions, above 0 and at most 1.
        rates: also each input's rate of change per second: the backward difference to the
            window before (causal, as a simulator can compute it; 0 at the first window).
        harmonic: the harmonic analysed (default: the aircraft's blade count, N/rev).
        counters: which records (default: every one, condition by condition).
        chain: join each condition's records (its segments, e.g. one autorotation recorded
            as two counters) into one row.
        axis: the pilot-floor acceleration analysed (`az_g`, `ax_g`, `ay_g`).

    Returns:
        `Sequences`.
    """
    if not 0 < hop_revs <= 1:
        raise ValueError(f"hop_revs {hop_revs:g}: must lie in (0, 1] revolution (a sequence needs the windows of "
                         "every revolution)")
    counters = list(counters) if counters is not None else [c for cs in campaign.conditions().values() for c in cs]
    # Batched by length: one long record among short ones costs its own memory, not theirs.
    win = analyze_by_length(campaign, counters, window_revs, hop_revs, harmonic=harmonic or campaign.aircraft.blades,
                            axis=axis)
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
    tracks = [_track(campaign, c, axis) for c in counters]
    t_start, t_end = _edges(tracks, time.shape[1], window_revs, hop_revs)
    info = campaign.counters.loc[counters]
    rows = _rows(counters, list(info.condition), chain)
    cols = [x, np.asarray(win.amplitude, np.float64), t_start, t_end]
    record = np.asarray(counters, dtype=object)[:, None].repeat(mask.shape[1], 1)
    time, x, amp, t_start, t_end, record, mask = _join(rows, time, tracks, mask, [*cols, record])
    names = tuple(inputs)
    if rates:
        x = np.concatenate([x, _rates(x, time, mask)], axis=-1)
        names += tuple(f"d_{n}_dt" for n in inputs)
    first = [r[0] for r in rows]
    return Sequences(tuple("+".join(counters[i] for i in r) for r in rows), record,
                     tuple(info.condition.iloc[first]), tuple(info.maneuver.iloc[first]), names, time, t_start,
                     t_end, amp, x, mask, float(window_revs), float(hop_revs))


def _rows(counters, conditions, chain: bool) -> list[list[int]]:
    """The records of each row: one each, or (chain) a condition's records in the order
    given (`Campaign.conditions` gives segment order)."""
    if not chain:
        return [[i] for i in range(len(counters))]
    groups: dict = {}
    for i, c in enumerate(conditions):
        groups.setdefault(c, []).append(i)
    return list(groups.values())


def _track(campaign: Campaign, counter: str, axis: str) -> tuple[np.ndarray, np.ndarray]:
    """(time s, revolutions) of a record's samples, as the analysis counts them."""
    b = to_batch(campaign, [], [counter], axis=axis)
    m = np.asarray(b.mask[0])
    return np.asarray(b.time[0], np.float64)[m], np.asarray(b.rev[0], np.float64)[m]


def _join(rows, time, tracks, mask, arrays):
    """Each row's real windows, its records' one after another (a later record's times
    shifted to start one sample step after the earlier's last sample, from `tracks`),
    padded to the longest row by repeating its last window."""
    n = mask.sum(axis=1)
    width = max(int(sum(n[i] for i in r)) for r in rows)
    out_t, out = np.empty((len(rows), width)), [np.empty((len(rows), width) + a.shape[2:], a.dtype) for a in arrays]
    out_m = np.zeros((len(rows), width), bool)
    for j, r in enumerate(rows):
        shift, parts_t, parts = 0.0, [], [[] for _ in arrays]
        for i in r:
            real = mask[i]
            parts_t.append(time[i, real] + shift)
            for p, a in zip(parts, arrays):
                p.append(a[i, real])
            tv = tracks[i][0]
            shift += tv[-1] + (tv[-1] - tv[-2] if len(tv) > 1 else 0.0)
        k = int(sum(len(p) for p in parts_t))
        hold = np.minimum(np.arange(width), k - 1)
        out_t[j] = np.concatenate(parts_t)[hold]
        for o, p in zip(out, parts):
            o[j] = np.concatenate(p)[hold]
        out_m[j, :k] = True
    return (out_t, *out, out_m)


def _rates(x: np.ndarray, time: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """d x / d t per row as the backward difference to the window before (causal); 0 at the
    first window and past the last."""
    dt = np.diff(time, axis=1)[..., None]
    d = np.where(dt > 0, np.diff(x, axis=1) / np.where(dt > 0, dt, 1.0), 0.0)
    out = np.concatenate([np.zeros_like(x[:, :1]), d], axis=1)
    return np.where(mask[..., None], out, 0.0)


def _edges(tracks, n_windows: int, window_revs: float, hop_revs: float) -> tuple[np.ndarray, np.ndarray]:
    """Start and end times of each window: its revolutions mapped to time along the record
    (`tracks`: each record's sample times and revolutions)."""
    starts = hop_revs * np.arange(n_windows)
    t0, t1 = np.empty((len(tracks), n_windows)), np.empty((len(tracks), n_windows))
    for r, (tv, rv) in enumerate(tracks):
        t0[r] = np.interp(rv[0] + starts, rv, tv)
        t1[r] = np.interp(rv[0] + starts + window_revs, rv, tv)
    return t0, t1
