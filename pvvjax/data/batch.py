"""Campaign records as one padded batch of arrays (the boundary into the jitted core).

Records of different lengths are padded to a common length with a mask, so that one
compiled function serves the whole campaign and vmaps over counters. Padding continues
time and rotor azimuth linearly (so searches stay monotonic) and holds channel values
(so interpolation near the end never sees a jump); padded samples carry zero weight.

Compiled programs are keyed on shapes, so sizes that follow the data (samples per record,
records, windows, conditions) are rounded up to a few buckets (`bucket_size`: steps of
about 1.25×, at most 25 % padding): campaigns of similar size then share every compiled
analysis, replay and calibration program instead of compiling their own.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from typing import Sequence

import jax
import numpy as np

from .._arguments import instance, names, number, refuse
from .campaign import Campaign, CampaignWarning

__all__ = ["BLOCK", "MEMORY_SHARE", "RecordBatch", "batch_rows", "bucket_size", "by_group", "in_batch_order",
           "machine_memory", "pad_rows", "sample_widths", "take_rows", "to_batch", "unpad_rows"]

BLOCK = 64  # batches are padded to a multiple of this many samples


def bucket_size(n: int) -> int:
    """The smallest bucket >= n: 1, 2, 4, 8, then m·2^k with m in {4, 5, 6, 7} (10, 12,
    14, 16, 20, 24, ...), so that sizes come in few values and, above 8, padding adds at
    most 25 %."""
    n = max(int(n), 1)
    if n <= 8:
        return 1 << (n - 1).bit_length()
    k = (n - 1).bit_length() - 3  # 2^(k+2) < n <= 2^(k+3)
    return -(-n // (1 << k)) << k


def pad_rows(tree, n: int):
    """Every leaf of a PyTree padded along its leading axis to `n` rows with copies of its
    first row (real data, so the padded rows compute finite results; slice them off).
    Padded on the host, so that no small program is compiled per size; a JAX array comes
    back as one."""
    def pad(a):
        extra = n - np.shape(a)[0]
        if extra <= 0:
            return a
        h = np.asarray(a)
        out = np.concatenate([h, np.repeat(h[:1], extra, axis=0)])
        return jax.device_put(out) if isinstance(a, jax.Array) else out

    return jax.tree.map(pad, tree)


@jax.jit
def take_rows(tree, idx):
    """The rows `idx` (an integer array) of every leaf of a PyTree, along its leading axis:
    one program per tree layout and count of rows (eagerly, every leaf would compile its own)."""
    return jax.tree.map(lambda a: a[idx], tree)


def unpad_rows(tree, n: int):
    """The first `n` rows of every leaf of a PyTree (what `pad_rows` added, removed), sliced
    on the host so that no program is compiled per `n`; JAX arrays on the default device."""
    return jax.tree.map(lambda a: jax.device_put(np.asarray(a)[:n]), tree)


@dataclasses.dataclass(frozen=True)
class RecordBatch:
    """A padded batch of counters; a PyTree whose leaves are the arrays.

    Attributes:
        time: (B, T) time from record start, s.
        rev: (B, T) unwrapped rotor azimuth in revolutions.
        cos_psi, sin_psi: (B, T) reference-blade azimuth ψ as a unit phasor (computed in
            float64 from the wrapped azimuth, so it carries no wrap or rounding artefact).
        width: (B, T) revolutions each sample stands for (half-way to each neighbour); 0 in
            padding, so it is also the sample's weight in a harmonic analysis.
        accel: (B, T) the analysed pilot-floor acceleration (the `axis` channel of
            `to_batch`: `az_g` vertical unless asked otherwise), g (0 in padding).
        x: (B, T, C) flight-state channels named by `channels`, canonical units.
        mask: (B, T) True on real samples.
        counters: (static) the counter of each batch row.
        channels: (static) the channel of each slice of `x`.
        axis: (static) the acceleration channel `accel` holds (a tuple: its last axis).
    """

    time: jax.Array
    rev: jax.Array
    cos_psi: jax.Array
    sin_psi: jax.Array
    width: jax.Array
    accel: jax.Array
    x: jax.Array
    mask: jax.Array
    counters: tuple[str, ...] = ()
    channels: tuple[str, ...] = ()
    axis: str | tuple[str, ...] = "az_g"

    def channel(self, name: str):
        """The (B, T) array of one channel."""
        return self.x[..., self.channels.index(name)]

    @property
    def lengths(self) -> np.ndarray:
        return np.asarray(self.mask).sum(axis=-1)


jax.tree_util.register_dataclass(
    RecordBatch,
    data_fields=["time", "rev", "cos_psi", "sin_psi", "width", "accel", "x", "mask"],
    meta_fields=["counters", "channels", "axis"],
)


def sample_widths(rev: np.ndarray) -> np.ndarray:
    """Revolutions each sample stands for: half-way to each neighbour (ends: one step)."""
    d = np.diff(rev)
    return 0.5 * (np.r_[d[:1], d] + np.r_[d, d[-1:]])


def _pad_linear(v: np.ndarray, n: int) -> np.ndarray:
    step = v[-1] - v[-2]
    return np.concatenate([v, v[-1] + step * np.arange(1, n + 1)])


def to_batch(campaign: Campaign, channels: Sequence[str], counters: Sequence[str] | None = None,
             min_length: int = 0, dtype=np.float32, axis: str | tuple[str, ...] = "az_g") -> RecordBatch:
    """Stack a campaign's records into a padded `RecordBatch`.

    Args:
        campaign: a loaded campaign.
        channels: channel names for `x`, in order (must exist in every record).
        counters: which counters, in which order (default: condition then segment order).
        min_length: pad to at least this many samples.
        dtype: floating dtype of the arrays.
        axis: the pilot-floor acceleration analysed (`az_g`, `ax_g` or `ay_g`, data
            contract): what `accel` holds; a tuple of them makes `accel` (B, T, A).

    The length is padded to whole `BLOCK`s, in `bucket_size` steps of blocks.

    Raises:
        ArgumentError: an argument it cannot use, by name.
        MemoryError: a batch larger than `MEMORY_SHARE` of the machine's memory, with the
            estimate, before any of it is allocated.

    Returns:
        The batch (NumPy arrays; JAX converts them on first use).
    """
    instance("to_batch", "campaign", campaign, Campaign, "a Campaign (load_campaign or campaign_from_frames)")
    channels = names("to_batch", "channels", channels)
    number("to_batch", "min_length", min_length, at_least=0, whole=True)
    if counters is None:
        counters = [c for cs in campaign.conditions().values() for c in cs]
    counters = names("to_batch", "counters", counters)
    unknown = [c for c in counters if c not in campaign.records]
    if unknown:
        raise refuse("to_batch", "counters", unknown, f"counters of campaign {campaign.source or '<memory>'}")
    axes = (axis,) if isinstance(axis, str) else tuple(names("to_batch", "axis", axis))
    recs = [campaign.records[c] for c in counters]
    for c, r in zip(counters, recs):
        missing = [ch for ch in (*channels, *axes) if ch not in r.columns]
        if missing:
            raise refuse("to_batch", "channels" if set(missing) & set(channels) else "axis", missing,
                         f"channels of every record: counter {c!r} has none of them")
    T = max(max(len(r) for r in recs), min_length)
    T = bucket_size(-(-T // BLOCK)) * BLOCK  # whole blocks for the harmonic analysis, few distinct lengths
    B, C = len(recs), len(channels)
    _check_memory(campaign, B, T, C + len(axes), np.dtype(dtype).itemsize, counters, [len(r) for r in recs])
    out = {k: np.zeros((B, T), dtype) for k in ("time", "rev", "cos_psi", "sin_psi", "width")}
    out["accel"] = np.zeros((B, T, len(axes)), dtype)
    x = np.zeros((B, T, C), dtype)
    mask = np.zeros((B, T), bool)
    for i, r in enumerate(recs):
        n, pad = len(r), T - len(r)
        t = r["time_s"].to_numpy(np.float64)
        az_deg = r["azimuth_deg"].to_numpy(np.float64)
        rev = np.unwrap(az_deg, period=360.0) / 360.0
        out["time"][i] = _pad_linear(t, pad)
        rev = _pad_linear(rev, pad)  # float64 until stored: psi keeps full precision
        out["rev"][i] = rev
        psi = 2.0 * np.pi * np.mod(rev, 1.0)
        out["cos_psi"][i], out["sin_psi"][i] = np.cos(psi), np.sin(psi)
        out["width"][i, :n] = sample_widths(rev[:n])
        out["accel"][i, :n] = r[list(axes)].to_numpy(np.float64)
        vals = r[list(channels)].to_numpy(np.float64)
        x[i, :n] = vals
        x[i, n:] = vals[-1]
        mask[i, :n] = True
    accel = np.ascontiguousarray(out["accel"][..., 0]) if isinstance(axis, str) else out["accel"]
    return RecordBatch(out["time"], out["rev"], out["cos_psi"], out["sin_psi"], out["width"], accel, x, mask,
                       tuple(counters), tuple(channels), axis)


# A batch may take at most this share of the machine's memory: the analysis and the replay
# hold several arrays of its size while they run.
MEMORY_SHARE = 0.25


def machine_memory() -> int | None:
    """The machine's physical memory, bytes (None where the system does not say)."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


# Padding every record to the longest is warned about where it multiplies the batch's memory
# by more than this and the batch passes `_PADDING_WARN_BYTES`.
_PADDING_WARN_FACTOR = 4.0
_PADDING_WARN_BYTES = 2**30


def _check_memory(campaign, B: int, T: int, columns: int, itemsize: int, counters, lengths) -> None:
    """Refuse, with the estimate, a batch larger than `MEMORY_SHARE` of the machine's memory,
    before any of it is allocated; warn, naming the longest record, where padding to it
    multiplies the memory of the rest."""
    need, have = B * T * (5 + columns) * itemsize + B * T, machine_memory()
    source = campaign.source or "<memory>"
    if have and need > MEMORY_SHARE * have:
        raise MemoryError(f"campaign {source}: {B} record(s) padded to {T} samples need "
                          f"{need / 2**30:.3g} GiB as one batch, more than {MEMORY_SHARE:.0%} of this machine's "
                          f"{have / 2**30:.3g} GiB; analyse fewer or shorter records at once (a long record cut "
                          "into counters), or use a machine with more memory")
    factor = B * T / max(sum(lengths), 1)
    if factor > _PADDING_WARN_FACTOR and need > _PADDING_WARN_BYTES:
        longest = counters[int(np.argmax(lengths))]
        warnings.warn(f"campaign {source}: counter {longest!r} ({max(lengths)} samples) pads the {B - 1} other "
                      f"record(s) to its length: {need / 2**30:.3g} GiB, {factor:.3g}x what their samples need; "
                      "cut the long record into counters of one condition's segments, or run it apart",
                      CampaignWarning, stacklevel=3)


def by_group(batch: RecordBatch, groups: dict, run):
    """`run(sub_batch, key)` on the records of each group (key -> row indices, e.g. the
    window plans of `analysis.plan_groups`), the results (PyTrees with records along the
    leading axis) put back in the batch's order, on the host (no program per group size)."""
    return in_batch_order([run(batch_rows(batch, rows), key) for key, rows in groups.items()], groups)


def in_batch_order(parts: list, groups: dict):
    """Results of each group (PyTrees with the group's records along the leading axis, in the
    order of `groups`: key -> row indices) as one PyTree in the batch's order, on the host."""
    back = np.argsort(np.concatenate([np.asarray(rows) for rows in groups.values()]))
    return jax.tree.map(lambda *a: jax.device_put(np.concatenate([np.asarray(x) for x in a])[back]), *parts)


def batch_rows(batch: RecordBatch, rows) -> RecordBatch:
    """The records `rows` of a batch, as a batch (their counters with them)."""
    rows = np.asarray(rows)
    sub = take_rows(batch, rows)
    return dataclasses.replace(sub, counters=tuple(batch.counters[i] for i in rows) if batch.counters else ())
