"""Windowed harmonic analysis of the pilot-floor acceleration (4/rev PVV).

A window is an interval of rotor revolutions [a, a + L). Sample n stands for the interval
of revolutions half-way to its neighbours (width Δ_n), and its weight is the part of that
interval inside the window: the window length L is therefore continuous, and the analysis
is differentiable in L (and in the window start), with exact fractional-sample edges. With
`taper_revs > 0` the edges become raised-cosine ramps of that width, centred on a and a+L,
which keeps the effective length L and makes d/dL smooth. With integer L, no taper and
uniform azimuth sampling, a window is exactly the rectangular-window DFT of its samples.

Harmonic k of window j, referenced to the blade azimuth ψ (so that the signal is
≈ A·cos(kψ + φ)):

    c_j = Σ w_n (a_n - ā_j) e^{-ikψ_n} / Σ w_n,   A_j = 2|c_j|,   φ_j = arg c_j,

where ā_j is the window's weighted mean acceleration: removing it stops the ~1 g steady
load factor from leaking into harmonic k when L is not a whole number of revolutions.

The azimuth enters as the phasor (cos ψ, sin ψ), so e^{-ikψ} costs a few multiplications.
Width-weighted products are summed in blocks of samples; a window adds its interior blocks
and weighs only the samples near its edges: about one pass over the samples, with static
shapes, so the function jits and vmaps over counters.
"""

from __future__ import annotations

import math
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._arguments import check_arguments
from .._lookup import Lookup, make_lookup, search
from ..data.batch import RecordBatch, bucket_size, by_group, pad_rows, unpad_rows

__all__ = [
    "Columns",
    "EDGES",
    "WindowPlan",
    "Windows",
    "analyze",
    "edge_weight",
    "harmonic_from_means",
    "harmonic_windows",
    "make_columns",
    "means_from_sums",
    "plan_groups",
    "plan_windows",
    "record_bounds",
    "record_columns",
    "record_plans",
    "stack_columns",
    "window_bounds",
    "window_sums",
    "with_prefix",
]

_EPS_REVS = 1e-4  # float tolerance on window bounds, revolutions


class Windows(NamedTuple):
    """Per-window results (leading batch axes, then W windows).

    Attributes:
        amplitude: harmonic amplitude (PVV for k = 4), g.
        phase: harmonic phase relative to blade azimuth, rad.
        time: weighted window-centre time, s.
        means: (..., W, C) window-averaged channels.
        center: (..., W, C) channels at the window-centre time.
        valid: True where the window lies wholly inside the record.
    """

    amplitude: jax.Array
    phase: jax.Array
    time: jax.Array
    means: jax.Array
    center: jax.Array
    valid: jax.Array


class WindowPlan(NamedTuple):
    """Static sizes for a batch (see `plan_windows`).

    Attributes:
        n_windows: windows per record.
        block: samples per block of the first-stage reduction.
        edge_blocks: blocks around each window edge whose samples get exact edge weights.
        interior_blocks: most blocks strictly inside one window.
        edge_samples: samples that can lie in one edge ramp (the prefix-sum path).
    """

    n_windows: int
    block: int
    edge_blocks: int
    interior_blocks: int
    edge_samples: int = 4


EDGES = ("cell", "linear")


def edge_weight(u, kind: str):
    """Fraction of a sample's weight inside a window edge, rising from 0 to 1 as the sample
    moves inwards; u is the sample's distance inside the edge in ramp widths h.

    "cell": the part of the sample's cell (width h) inside: linear over |u| < 1/2; exact
    rectangular windows, but d/d(edge) jumps where an edge crosses a cell boundary.
    "linear": the part of the sample's hat function (half-width h) inside, i.e. the window
    integrates the linear interpolant of the samples: a quadratic ramp over |u| < 1 whose
    derivative is continuous, so gradients in the edge positions (window length, time
    offset) have no jumps, at whole-sample positions included.
    "taper": raised cosine over |u| < 1/2 (h is the taper width).
    """
    if kind == "linear":
        v = jnp.clip(u, -1.0, 1.0)
        return jnp.where(v < 0, 0.5 * (1.0 + v) ** 2, 1.0 - 0.5 * (1.0 - v) ** 2)
    s = jnp.clip(u + 0.5, 0.0, 1.0)
    return 0.5 - 0.5 * jnp.cos(jnp.pi * s) if kind == "taper" else s


def _edge_kind(edge: str, taper_revs: float) -> str:
    if edge not in EDGES:
        raise ValueError(f"edge must be one of {EDGES}, got {edge!r}")
    return "taper" if taper_revs > 0 else edge


def _reach(kind: str) -> float:
    """Half-extent of an edge ramp in ramp widths."""
    return 1.0 if kind == "linear" else 0.5


def _sums(arrays, axis: int):
    """Sums of several same-shape arrays along `axis` in one pass (a variadic reduce: XLA
    then reads the shared inputs once instead of once per sum)."""
    zeros = tuple(jnp.zeros((), a.dtype) for a in arrays)
    return jax.lax.reduce(tuple(arrays), zeros, lambda xs, ys: tuple(p + q for p, q in zip(xs, ys)), (axis,))


def _phasor_power(c, s, k: int):
    """(cos kψ, sin kψ) from (cos ψ, sin ψ) by repeated complex multiplication (no
    transcendental functions in the hot loop)."""
    rc, rs = jnp.ones_like(c), jnp.zeros_like(s)
    bc, bs = c, s
    while k:
        if k & 1:
            rc, rs = rc * bc - rs * bs, rc * bs + rs * bc
        k >>= 1
        if k:
            bc, bs = bc * bc - bs * bs, 2.0 * bc * bs
    return rc, rs


class Columns(NamedTuple):
    """What windows of one record are computed from (`record_columns`); independent of the
    window positions, so it is computed once per record and reused for any windows.

    Attributes:
        cols: columns summed under window weights: az·cos kψ, az·sin kψ, cos kψ, sin kψ,
            az, time, then each channel minus its first value; a tuple of (T,) arrays, or
            one (T, n) array (`stack_columns`: faster for many window sums of one record).
        blocks: (T / block, len(cols) + 1) width-weighted block sums of cols and of 1.
        x_ref: (C,) first value of each channel (added back to window means).
        rev, width: (T,) as in `harmonic_windows`; width_max: the largest width.
        prefix: optional (hi, lo) float32 pair of (T / block + 1, len(cols) + 1) prefix sums
            of `blocks`, accurate to float64 (`with_prefix`): window sums then take two rows
            instead of every interior block.
        lookup: optional O(1) search table of rev (`with_prefix` adds it).
    """

    cols: tuple | jax.Array
    blocks: jax.Array
    x_ref: jax.Array
    rev: jax.Array
    width: jax.Array
    width_max: jax.Array
    prefix: tuple | None = None
    lookup: Lookup | None = None


N_HARMONIC_COLS = 6  # az·cos, az·sin, cos, sin, az, time


def record_columns(az, cos_psi, sin_psi, rev, width, time, x, *, harmonic: int, block: int) -> Columns:
    """Columns and block sums of one record (see `Columns`); T must be a multiple of `block`."""
    T = az.shape[0]
    if T % block:
        raise ValueError(f"record length {T} is not a multiple of the block size {block} (pad with `to_batch`)")
    ck, sk = _phasor_power(cos_psi, sin_psi, harmonic)
    # Channels are averaged as deviations from the record's first sample (added back after):
    # exact for constants, and no float32 loss on large values such as gross weight.
    x_ref = x[0]
    cols = (az * ck, az * sk, ck, sk, az, time) + tuple(x[:, c] - x_ref[c] for c in range(x.shape[1]))
    return make_columns(cols, rev, width, x_ref, block=block)


def make_columns(cols: tuple, rev, width, x_ref, *, block: int) -> Columns:
    """`Columns` of any tuple of (T,) columns: their width-weighted block sums, beside the
    record's revolutions and widths (`record_columns` for one harmonic of one axis)."""
    T = rev.shape[0]
    nb = T // block
    # Each column is reduced on its own: stacking full-length columns costs more than the analysis.
    blocks = jnp.stack(_sums([(width * v).reshape(nb, block) for v in cols] + [width.reshape(nb, block)], axis=1),
                       axis=-1)
    return Columns(cols, blocks, x_ref, rev, width, jnp.max(width))


def stack_columns(c: Columns) -> Columns:
    """The same columns as one (T, n) array: costs one pass, then every window sum
    gathers its edge samples in one operation instead of one per column."""
    return c._replace(cols=jnp.stack(c.cols, axis=1)) if isinstance(c.cols, tuple) else c


def with_prefix(c: Columns) -> Columns:
    """`c` with float64-accurate prefix sums of its width-weighted columns (per sample, split
    into a float32 pair) and a search table of its revolutions: a window sum then takes two
    prefix rows and weighs the few samples of its edge ramps, whatever the window length
    (NumPy: run once per record, outside jit; leading batch axes allowed)."""
    c = stack_columns(c)
    cols = np.asarray(c.cols)
    w = np.asarray(c.width)
    *lead, T, n = cols.shape
    cols, w = cols.reshape(-1, T, n), w.reshape(-1, T)
    dt = np.asarray(c.blocks).dtype
    hi = np.empty((cols.shape[0], T + 1, n + 1), dt)
    lo = np.empty_like(hi)
    # One record at a time in a reused float64 buffer: it stays in cache, and a campaign's
    # worth of float64 copies (hundreds of MB) would make this 10x slower.
    p = np.empty((T + 1, n + 1), np.float64)
    p[0] = 0.0
    for r in range(cols.shape[0]):
        np.multiply(cols[r], w[r][:, None], out=p[1:, :n], dtype=np.float64)
        p[1:, n] = w[r]
        np.cumsum(p[1:], axis=0, out=p[1:])
        hi[r] = p
        lo[r] = p - hi[r]
    hi, lo = hi.reshape(*lead, T + 1, n + 1), lo.reshape(*lead, T + 1, n + 1)
    # device_put, not jnp.asarray: the latter compiles a small copy program per shape.
    return c._replace(prefix=(jax.device_put(hi), jax.device_put(lo)),
                      lookup=jax.tree.map(jax.device_put, make_lookup(c.rev)))


def _prefix_window_sums(c: Columns, a, b, reach, kind, taper_revs, plan, select, every, keep):
    """`window_sums` through per-sample prefix sums: interior by two prefix rows, edge-ramp
    samples (at most `plan.edge_samples` per edge) weighed exactly."""
    rev, width = c.rev, c.width
    T, W, K = rev.shape[0], a.shape[0], plan.edge_samples
    i = search(c.lookup, rev, jnp.concatenate([a, b]) - reach)  # first sample of each ramp
    i_a = i[:W]
    i_b = jnp.maximum(i[W:], i_a + K)
    lo_i, hi_i = jnp.minimum(i_a + K, T), jnp.minimum(i_b, T)
    interior = (c.prefix[0][hi_i] - c.prefix[0][lo_i]) + (c.prefix[1][hi_i] - c.prefix[1][lo_i])
    interior = interior if every else interior[:, keep]
    idx = jnp.concatenate([i_a[:, None] + jnp.arange(K), i_b[:, None] + jnp.arange(K)], axis=1)  # (W, 2K)
    inside = idx < T
    idx = jnp.minimum(idx, T - 1)
    r, wd = rev[idx], width[idx]
    h = jnp.maximum(taper_revs, wd) if kind == "taper" else jnp.where(wd > 0, wd, 1.0)
    w = wd * inside * edge_weight((r - a[:, None]) / h, kind) * edge_weight((b[:, None] - r) / h, kind)
    rows = c.cols[idx]
    edges = jnp.einsum("wn,wnv->wv", w, rows if every else rows[..., list(select)])
    return interior + jnp.concatenate([edges, jnp.sum(w, axis=1, keepdims=True)], axis=1)


def window_sums(c: Columns, a, b, *, kind: str, taper_revs: float, plan: WindowPlan, select=None):
    """Weighted sums of columns over windows [a, b) (revolutions), with exact edge weights.

    Each window adds its interior blocks and weighs only the samples of the blocks around
    its two edges; gradients in `a` and `b` flow through the edge weights.

    Args:
        c: `record_columns` of the record.
        a, b: (W,) window starts and ends, revolutions (any positions, b - a ≤ the plan's
            longest window).
        kind: edge kind ("cell", "linear" or "taper", see `edge_weight`).
        taper_revs: ramp width for "taper".
        plan: static sizes (`plan_windows`).
        select: indices of the columns wanted (default all).

    Returns:
        (W, n + 1): sums of the selected columns, then the sum of the weights.
    """
    B, nE, nI = plan.block, plan.edge_blocks, plan.interior_blocks
    dt = c.blocks.dtype
    rev, width = c.rev, c.width
    T = rev.shape[0]
    nb = T // B
    stacked = not isinstance(c.cols, tuple)
    n_cols = c.cols.shape[1] if stacked else len(c.cols)
    select = tuple(range(n_cols)) if select is None else tuple(select)
    keep = list(select) + [n_cols]
    every = select == tuple(range(n_cols))
    h_max = jnp.maximum(taper_revs, c.width_max)
    reach = _reach(kind) * h_max
    if c.prefix is not None:
        return _prefix_window_sums(c, a, b, reach, kind, taper_revs, plan, select, every, keep)
    # Block of the last sample wholly before each edge ramp.
    W = a.shape[0]
    m = jnp.clip((jnp.searchsorted(rev, jnp.concatenate([a, b]) - reach) - 1) // B, 0, nb - 1)
    m_a, m_b = m[:W], m[W:]
    right = jnp.maximum(m_b, m_a + nE)
    # Interior blocks [m_a + nE, right): every sample there has its full weight.
    ib = m_a[:, None] + nE + jnp.arange(nI)
    use = (ib < right[:, None]) & (ib < nb)
    inner = c.blocks[jnp.clip(ib, 0, nb - 1)]  # gather rows first, then columns: no full-length copies
    interior = jnp.einsum("wk,wkv->wv", use.astype(dt), inner if every else inner[..., keep])
    # Edge samples: blocks [m_a, m_a + nE) and [right, right + nE), with exact weights. Whole
    # blocks are gathered (XLA gathers contiguous slices much faster than single samples).
    eb = jnp.concatenate([m_a[:, None] + jnp.arange(nE), right[:, None] + jnp.arange(nE)], axis=1)  # (W, 2 nE)
    inside = jnp.repeat(eb < nb, B, axis=1)
    eb = jnp.clip(eb, 0, nb - 1)
    r, wd = rev.reshape(nb, B)[eb].reshape(W, -1), width.reshape(nb, B)[eb].reshape(W, -1)
    h = jnp.maximum(taper_revs, wd) if kind == "taper" else jnp.where(wd > 0, wd, 1.0)
    w = wd * inside * edge_weight((r - a[:, None]) / h, kind) * edge_weight((b[:, None] - r) / h, kind)
    if stacked:  # one gather of all columns (cheap when the record was stacked once, `stack_columns`)
        rows = c.cols.reshape(nb, B, n_cols)[eb].reshape(W, 2 * nE * B, n_cols)
        edges = jnp.einsum("wn,wnv->wv", w, rows if every else rows[..., list(select)])
        edges = jnp.concatenate([edges, jnp.sum(w, axis=1, keepdims=True)], axis=1)
    else:
        edges = jnp.stack(_sums([w * c.cols[i].reshape(nb, B)[eb].reshape(W, -1) for i in select] + [w], axis=1),
                          axis=-1)
    return interior + edges


def means_from_sums(sums):
    wsum = sums[..., -1]
    return sums[..., :-1] / jnp.where(wsum > 0, wsum, 1.0)[..., None], wsum


def harmonic_from_means(mean):
    """(amplitude, phase, time) of windows from the means of the harmonic columns (W, ≥6)."""
    az_bar = mean[:, 4]
    re = mean[:, 0] - az_bar * mean[:, 2]
    im = -(mean[:, 1] - az_bar * mean[:, 3])
    amplitude = 2.0 * jnp.sqrt(re**2 + im**2 + jnp.finfo(mean.dtype).tiny)
    return amplitude, jnp.arctan2(im, re), mean[:, 5]


def record_bounds(rev, width, mask):
    """First and last revolution covered by a record's samples."""
    last = jnp.maximum(jnp.sum(mask) - 1, 0)
    return rev[0] - 0.5 * width[0], rev[last] + 0.5 * width[last]


@partial(jax.jit, static_argnames=("harmonic", "taper_revs", "plan", "edge"))
def harmonic_windows(az, cos_psi, sin_psi, rev, width, time, x, mask, window_revs, hop_revs, start_revs=0.0, *,
                     harmonic: int = 4, taper_revs: float = 0.0, plan: WindowPlan, edge: str = "cell") -> Windows:
    """Harmonic analysis and window averages of one record.

    Two stages keep the cost near one pass over the samples: width-weighted products are
    summed into blocks of `plan.block` samples; each window then adds its interior blocks
    and computes exact (fractional or tapered) weights only for the samples of the blocks
    around its two edges. Gradients in the window length and start flow through the edges.

    Args:
        az: (T,) acceleration, g. cos_psi, sin_psi: (T,) blade-azimuth phasor.
        rev: (T,) unwrapped azimuth, revolutions, increasing (padding continues it).
        width: (T,) revolutions each sample stands for (`batch.sample_widths`), 0 in padding.
        time: (T,) s. x: (T, C) channels to average. mask: (T,) True on real samples.
        window_revs: window length L, revolutions (differentiable).
        hop_revs: spacing of window starts, revolutions (L for consecutive windows).
        start_revs: shift of the first window from the record start, revolutions.
        harmonic: harmonic order k (static).
        taper_revs: raised-cosine edge width, revolutions (static; 0: rectangular window).
        plan: static sizes (`plan_windows`).
        edge: rectangular edge kind, "cell" (exact DFT for whole windows) or "linear"
            (integral of the linear interpolant: gradients continuous in L and start).

    Returns:
        `Windows` with shapes (W,) and (W, C).
    """
    kind = _edge_kind(edge, taper_revs)
    W = plan.n_windows
    T = az.shape[0]
    cols = record_columns(az, cos_psi, sin_psi, rev, width, time, x, harmonic=harmonic, block=plan.block)
    a, b, inside_record = window_bounds(rev, width, mask, window_revs, hop_revs, start_revs, taper_revs, W)
    mean, wsum = means_from_sums(window_sums(cols, a, b, kind=kind, taper_revs=taper_revs, plan=plan))
    amplitude, phase, t_mid = harmonic_from_means(mean)
    center = jax.vmap(lambda col: jnp.interp(t_mid, time[:T], col), in_axes=1, out_axes=1)(x[:T])
    valid = inside_record & (wsum > 0)
    return Windows(amplitude, phase, t_mid, mean[:, N_HARMONIC_COLS:] + cols.x_ref, center, valid)


def window_bounds(rev, width, mask, window_revs, hop_revs, start_revs, taper_revs: float, n_windows: int):
    """Starts and ends (revolutions) of a record's `n_windows` windows, every `hop_revs`
    from `start_revs` past the record's start, and whether each lies wholly inside it."""
    rec_start, rec_end = record_bounds(rev, width, mask)
    a = rec_start + 0.5 * taper_revs + start_revs + hop_revs * jnp.arange(n_windows, dtype=rev.dtype)
    b = a + window_revs
    inside = (a - 0.5 * taper_revs >= rec_start - _EPS_REVS) & (b + 0.5 * taper_revs <= rec_end + _EPS_REVS)
    return a, b, inside


def plan_windows(batch: RecordBatch, max_window_revs: float, min_hop_revs: float, taper_revs: float = 0.0,
                 start_revs: float = 0.0, block: int = 16, edge: str = "cell") -> WindowPlan:
    """Static sizes that cover every window of every record for window lengths up to
    `max_window_revs` and hops down to `min_hop_revs` (needs a concrete batch). Each size
    is rounded up to a `bucket_size`, so that campaigns of similar records share programs
    (the extra windows lie past the record and are invalid). A hop below one sample is
    refused (`ValueError`): its windows would repeat samples without bound."""
    return _plan(np.asarray(batch.rev, np.float64), np.asarray(batch.mask), max_window_revs, min_hop_revs,
                 taper_revs, start_revs, block, edge)


def record_plans(batch: RecordBatch, max_window_revs: float, min_hop_revs: float, taper_revs: float = 0.0,
                 start_revs: float = 0.0, block: int = 16, edge: str = "cell") -> list[WindowPlan]:
    """`plan_windows` of each record of a batch alone: what its own sampling needs, which no
    other record's samples can move."""
    rev, mask = np.asarray(batch.rev, np.float64), np.asarray(batch.mask)
    return [_plan(rev[i:i + 1], mask[i:i + 1], max_window_revs, min_hop_revs, taper_revs, start_revs, block, edge)
            for i in range(len(rev))]


def plan_groups(plans: list[WindowPlan]) -> dict[WindowPlan, np.ndarray]:
    """Records (their plans from `record_plans`) grouped by the sizes their windows need,
    each group's plan holding every record's windows (the most windows of any record):
    plan -> the records' row indices."""
    n_windows = max(p.n_windows for p in plans)
    groups: dict = {}
    for i, p in enumerate(plans):
        groups.setdefault(p._replace(n_windows=n_windows), []).append(i)
    return {p: np.asarray(rows) for p, rows in groups.items()}


def _plan(rev, mask, max_window_revs, min_hop_revs, taper_revs, start_revs, block, edge) -> WindowPlan:
    d = np.diff(rev, axis=-1)
    dmask = mask[:, 1:] & mask[:, :-1]
    dmin, dmax = float(d[dmask].min()), float(d[dmask].max())
    sample = float(np.median(d[dmask]))
    if not min_hop_revs >= sample:  # more windows than samples: each start repeated, memory without bound
        raise ValueError(f"a window hop of {min_hop_revs:g} revolutions is below one sample ({sample:.3g} revolutions "
                         "at this campaign's sampling); give a hop of at least that (analysis.hop_revs, "
                         "replay.hop_revs or calibration.hop_revs)")
    span = float(max((rev[i, mask[i]][-1] - rev[i, 0]) for i in range(len(rev)))) + dmax
    n_windows = max(1, int(math.floor((span - start_revs - taper_revs - min(max_window_revs, span)) / min_hop_revs
                                      + _EPS_REVS)) + 1)
    h_max = max(taper_revs, dmax)
    ramp = 2.0 * _reach(_edge_kind(edge, taper_revs)) * h_max
    n_edge = int(math.ceil((ramp + 3.0 * dmax) / (block * dmin))) + 1
    interior = int(math.ceil((max_window_revs + h_max) / (block * dmin))) + 2
    return WindowPlan(bucket_size(n_windows), block, bucket_size(n_edge), bucket_size(interior),
                      bucket_size(int(math.ceil(ramp / dmin)) + 2))


def analyze(batch: RecordBatch, window_revs: float = 8.0, hop_revs: float | None = None, *, harmonic: int = 4,
            taper_revs: float = 0.0, start_revs: float = 0.0, plan: WindowPlan | None = None,
            edge: str = "cell") -> Windows:
    """Harmonic analysis of every record of a batch (vmapped over counters).

    Args:
        batch: the padded records.
        window_revs: window length L, revolutions (paper: 8).
        hop_revs: window spacing (default L: consecutive windows, as in the paper).
        harmonic: k (4 for the UH-60A's 4/rev).
        taper_revs: raised-cosine edge width (0: rectangular window).
        start_revs: shift of the first window from each record's start.
        plan: static sizes; computed from the batch when omitted.
        edge: "cell" or "linear" (see `harmonic_windows`).

    Returns:
        `Windows` with shapes (B, W) and (B, W, C).

    The records are padded to a `bucket_size` count for the computation (and the results
    sliced back), so that batches of similar size share one compiled program.
    """
    hop = window_revs if hop_revs is None else hop_revs
    if not isinstance(batch.rev, jax.core.Tracer):
        check_arguments(window_revs, hop, harmonic, taper_revs, start_revs)
    if plan is None and not isinstance(batch.rev, jax.core.Tracer):
        # Each record's sizes from its own samples: records that need the same share one call,
        # and no record's sampling (or a defect in it) moves another record's numbers.
        groups = plan_groups(record_plans(batch, float(window_revs), float(hop), float(taper_revs),
                                          float(start_revs), edge=edge))
        if len(groups) > 1:
            return by_group(batch, groups, lambda b, p: analyze(b, window_revs, hop_revs, harmonic=harmonic,
                                                               taper_revs=taper_revs, start_revs=start_revs, plan=p,
                                                               edge=edge))
        plan = next(iter(groups))
    elif plan is None:
        plan = plan_windows(batch, float(window_revs), float(hop), float(taper_revs), float(start_revs), edge=edge)
    fn = jax.vmap(
        partial(harmonic_windows, harmonic=harmonic, taper_revs=float(taper_revs), plan=plan, edge=edge),
        in_axes=(0, 0, 0, 0, 0, 0, 0, 0, None, None, None),
    )
    arrays = (batch.accel, batch.cos_psi, batch.sin_psi, batch.rev, batch.width, batch.time, batch.x, batch.mask)
    n = arrays[0].shape[0]
    if isinstance(arrays[0], jax.core.Tracer):  # under a caller's jit or vmap: its shapes, as given
        return fn(*arrays, window_revs, hop, start_revs)
    return unpad_rows(fn(*pad_rows(arrays, bucket_size(n)), window_revs, hop, start_revs), n)
