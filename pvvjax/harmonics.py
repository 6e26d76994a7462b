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

from .batch import RecordBatch

__all__ = ["Windows", "WindowPlan", "analyze", "harmonic_windows", "plan_windows"]

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
    """

    n_windows: int
    block: int
    edge_blocks: int
    interior_blocks: int


def _edge(u, smooth: bool):
    """Window edge rising from 0 at u = -1/2 to 1 at u = +1/2 (u in edge widths)."""
    s = jnp.clip(u + 0.5, 0.0, 1.0)
    return 0.5 - 0.5 * jnp.cos(jnp.pi * s) if smooth else s


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


@partial(jax.jit, static_argnames=("harmonic", "taper_revs", "plan"))
def harmonic_windows(az, cos_psi, sin_psi, rev, width, time, x, mask, window_revs, hop_revs, start_revs=0.0, *,
                     harmonic: int = 4, taper_revs: float = 0.0, plan: WindowPlan) -> Windows:
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
        taper_revs: raised-cosine edge width, revolutions (static; 0: rectangular).
        plan: static sizes (`plan_windows`).

    Returns:
        `Windows` with shapes (W,) and (W, C).
    """
    W, B, nE, nI = plan
    dt = az.dtype
    T = az.shape[0]
    if T % B:
        raise ValueError(f"record length {T} is not a multiple of the block size {B} (pad with `to_batch`)")
    nb = T // B
    last = jnp.maximum(jnp.sum(mask) - 1, 0)
    rec_start = rev[0] - 0.5 * width[0]
    rec_end = rev[last] + 0.5 * width[last]
    smooth = taper_revs > 0
    a = rec_start + 0.5 * taper_revs + start_revs + hop_revs * jnp.arange(W, dtype=dt)
    b = a + window_revs
    h_max = jnp.maximum(taper_revs, jnp.max(width))

    ck, sk = _phasor_power(cos_psi, sin_psi, harmonic)
    # Channels are averaged as deviations from the record's first sample (added back after):
    # exact for constants, and no float32 loss on large values such as gross weight.
    x_ref = x[0]
    # Columns summed under the window weights: az·cos, az·sin, cos, sin, az, time, channels, 1.
    # Each is reduced on its own: stacking full-length columns costs more than the analysis.
    cols = [az * ck, az * sk, ck, sk, az, time] + [x[:, c] - x_ref[c] for c in range(x.shape[1])]
    dw = width  # 0 in padding: the weight of a sample in full
    blocks = jnp.stack(_sums([(dw * v).reshape(nb, B) for v in cols] + [dw.reshape(nb, B)], axis=1), axis=-1)

    # Block of the last sample wholly before each edge ramp.
    m_a = jnp.clip((jnp.searchsorted(rev, a - 0.5 * h_max) - 1) // B, 0, nb - 1)
    m_b = jnp.clip((jnp.searchsorted(rev, b - 0.5 * h_max) - 1) // B, 0, nb - 1)
    right = jnp.maximum(m_b, m_a + nE)
    # Interior blocks [m_a + nE, right): every sample there has its full weight.
    ib = m_a[:, None] + nE + jnp.arange(nI)
    use = (ib < right[:, None]) & (ib < nb)
    interior = jnp.einsum("wk,wkv->wv", use.astype(dt), blocks[jnp.clip(ib, 0, nb - 1)])
    # Edge samples: blocks [m_a, m_a + nE) and [right, right + nE), with exact weights.
    span = jnp.arange(nE * B)
    idx = jnp.concatenate([m_a[:, None] * B + span, right[:, None] * B + span], axis=1)  # (W, 2 nE B)
    inside = idx < nb * B
    idx = jnp.clip(idx, 0, nb * B - 1)
    r, wd = rev[idx], width[idx]
    h = jnp.maximum(taper_revs, wd) if smooth else jnp.where(wd > 0, wd, 1.0)
    w = dw[idx] * inside * _edge((r - a[:, None]) / h, smooth) * _edge((b[:, None] - r) / h, smooth)
    edges = jnp.stack(_sums([w * v[idx] for v in cols] + [w], axis=1), axis=-1)
    sums = interior + edges
    wsum = sums[:, -1]
    mean = sums / jnp.where(wsum > 0, wsum, 1.0)[:, None]

    az_bar = mean[:, 4]
    re = mean[:, 0] - az_bar * mean[:, 2]
    im = -(mean[:, 1] - az_bar * mean[:, 3])
    amplitude = 2.0 * jnp.sqrt(re**2 + im**2 + jnp.finfo(dt).tiny)
    phase = jnp.arctan2(im, re)
    t_mid = mean[:, 5]
    center = jax.vmap(lambda col: jnp.interp(t_mid, time[:T], col), in_axes=1, out_axes=1)(x[:T])
    inside_record = (a - 0.5 * taper_revs >= rec_start - _EPS_REVS) & (b + 0.5 * taper_revs <= rec_end + _EPS_REVS)
    valid = inside_record & (wsum > 0)
    return Windows(amplitude, phase, t_mid, mean[:, 6:-1] + x_ref, center, valid)


def plan_windows(batch: RecordBatch, max_window_revs: float, min_hop_revs: float, taper_revs: float = 0.0,
                 start_revs: float = 0.0, block: int = 16) -> WindowPlan:
    """Static sizes that cover every window of every record for window lengths up to
    `max_window_revs` and hops down to `min_hop_revs` (needs a concrete batch)."""
    rev = np.asarray(batch.rev, np.float64)
    mask = np.asarray(batch.mask)
    d = np.diff(rev, axis=-1)
    dmask = mask[:, 1:] & mask[:, :-1]
    dmin, dmax = float(d[dmask].min()), float(d[dmask].max())
    span = float(max((rev[i, mask[i]][-1] - rev[i, 0]) for i in range(len(rev)))) + dmax
    n_windows = max(1, int(math.floor((span - start_revs - taper_revs - min(max_window_revs, span)) / min_hop_revs
                                      + _EPS_REVS)) + 1)
    h_max = max(taper_revs, dmax)
    edge = int(math.ceil((h_max + 3.0 * dmax) / (block * dmin))) + 1
    interior = int(math.ceil((max_window_revs + h_max) / (block * dmin))) + 2
    return WindowPlan(n_windows, block, edge, interior)


def analyze(batch: RecordBatch, window_revs: float = 8.0, hop_revs: float | None = None, *, harmonic: int = 4,
            taper_revs: float = 0.0, start_revs: float = 0.0, plan: WindowPlan | None = None) -> Windows:
    """Harmonic analysis of every record of a batch (vmapped over counters).

    Args:
        batch: the padded records.
        window_revs: window length L, revolutions (paper: 8).
        hop_revs: window spacing (default L: consecutive windows, as in the paper).
        harmonic: k (4 for the UH-60A's 4/rev).
        taper_revs: raised-cosine edge width (0: rectangular window).
        start_revs: shift of the first window from each record's start.
        plan: static sizes; computed from the batch when omitted.

    Returns:
        `Windows` with shapes (B, W) and (B, W, C).
    """
    hop = window_revs if hop_revs is None else hop_revs
    if plan is None:
        plan = plan_windows(batch, float(window_revs), float(hop), float(taper_revs), float(start_revs))
    fn = jax.vmap(
        partial(harmonic_windows, harmonic=harmonic, taper_revs=float(taper_revs), plan=plan),
        in_axes=(0, 0, 0, 0, 0, 0, 0, 0, None, None, None),
    )
    return fn(batch.az, batch.cos_psi, batch.sin_psi, batch.rev, batch.width, batch.time, batch.x, batch.mask,
              window_revs, hop, start_revs)
