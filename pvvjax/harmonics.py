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

Each window gathers a fixed-size support of samples around itself, so the cost is that of
the windows, not windows × record, and the function jits and vmaps with static shapes.
"""

from __future__ import annotations

import math
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .batch import RecordBatch

__all__ = ["Windows", "WindowPlan", "analyze", "harmonic_windows", "plan_windows", "sample_widths"]

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
    """Static sizes for a batch: how many windows, and the samples gathered per window."""

    n_windows: int
    support: int


def sample_widths(rev):
    """Revolutions each sample stands for: half-way to each neighbour. (T,) -> (T,)."""
    d = jnp.diff(rev)
    return 0.5 * (jnp.concatenate([d[:1], d]) + jnp.concatenate([d, d[-1:]]))


def _edge(u, smooth):
    """Window edge rising from 0 at u = -1/2 to 1 at u = +1/2 (u in edge widths)."""
    s = jnp.clip(u + 0.5, 0.0, 1.0)
    return jnp.where(smooth, 0.5 - 0.5 * jnp.cos(jnp.pi * s), s)


@partial(jax.jit, static_argnames=("harmonic", "n_windows", "support"))
def harmonic_windows(az, psi, rev, time, x, mask, window_revs, hop_revs, taper_revs=0.0, start_revs=0.0, *,
                     harmonic: int = 4, n_windows: int, support: int) -> Windows:
    """Harmonic analysis and window averages of one record.

    Args:
        az: (T,) acceleration, g. psi: (T,) blade azimuth, rad. rev: (T,) unwrapped
            azimuth, revolutions, increasing (padding continues it). time: (T,) s.
        x: (T, C) channels to average. mask: (T,) True on real samples.
        window_revs: window length L, revolutions (differentiable).
        hop_revs: spacing of window starts, revolutions (L for consecutive windows).
        taper_revs: raised-cosine edge width, revolutions (0: rectangular).
        start_revs: shift of the first window from the record start, revolutions.
        harmonic: harmonic order k (static).
        n_windows, support: static sizes (see `plan_windows`).

    Returns:
        `Windows` with shapes (W,) and (W, C).
    """
    T = az.shape[0]
    S = min(support, T)
    dt = az.dtype
    m = mask.astype(dt)
    width = sample_widths(rev)
    last = jnp.maximum(jnp.sum(mask) - 1, 0)
    rec_start = rev[0] - 0.5 * width[0]
    rec_end = rev[last] + 0.5 * width[last]
    taper = jnp.asarray(taper_revs, dt)
    smooth = taper > 0
    a = rec_start + 0.5 * taper + start_revs + hop_revs * jnp.arange(n_windows, dtype=dt)
    b = a + window_revs
    h_max = jnp.maximum(taper, jnp.max(jnp.where(mask, width, 0.0)))

    kpsi = harmonic * psi
    c, s = jnp.cos(kpsi), jnp.sin(kpsi)
    # Channels are averaged as deviations from the record's first sample (added back after):
    # exact for constants, and no float32 loss on large values such as gross weight.
    x_ref = x[0]
    # Columns summed under the window weights: az·cos, az·sin, cos, sin, az, time, channels.
    vals = jnp.concatenate([jnp.stack([az * c, az * s, c, s, az, time], axis=-1), x - x_ref], axis=-1)
    cols = jnp.concatenate([vals, jnp.stack([rev, width, m], axis=-1)], axis=-1)

    start = jnp.searchsorted(rev, a - 0.5 * h_max) - 2
    start = jnp.clip(start, 0, T - S)
    block = jax.vmap(lambda i: jax.lax.dynamic_slice_in_dim(cols, i, S, axis=0))(start)  # (W, S, V+3)
    v, r, wd, mk = block[..., :-3], block[..., -3], block[..., -2], block[..., -1]
    h = jnp.where(smooth, jnp.maximum(taper, wd), wd)
    w = wd * mk * _edge((r - a[:, None]) / h, smooth) * _edge((b[:, None] - r) / h, smooth)
    sums = jnp.einsum("ws,wsv->wv", w, v)
    wsum = jnp.sum(w, axis=-1)
    safe = jnp.where(wsum > 0, wsum, 1.0)
    mean = sums / safe[:, None]

    az_bar = mean[:, 4]
    re = mean[:, 0] - az_bar * mean[:, 2]
    im = -(mean[:, 1] - az_bar * mean[:, 3])
    amplitude = 2.0 * jnp.sqrt(re**2 + im**2 + jnp.finfo(dt).tiny)
    phase = jnp.arctan2(im, re)
    t_mid = mean[:, 5]
    center = jax.vmap(lambda col: jnp.interp(t_mid, time, col), in_axes=1, out_axes=1)(x)

    covered = (block[:, 0, -3] - 0.5 * block[:, 0, -2] <= a - 0.5 * h_max + _EPS_REVS) | (start == 0)
    covered &= (block[:, -1, -3] + 0.5 * block[:, -1, -2] >= b + 0.5 * h_max - _EPS_REVS) | (start + S > last)
    inside = (a - 0.5 * taper >= rec_start - _EPS_REVS) & (b + 0.5 * taper <= rec_end + _EPS_REVS)
    valid = inside & covered & (wsum > 0)
    return Windows(amplitude, phase, t_mid, mean[:, 6:] + x_ref, center, valid)


def plan_windows(batch: RecordBatch, max_window_revs: float, min_hop_revs: float, taper_revs: float = 0.0,
                 start_revs: float = 0.0) -> WindowPlan:
    """Static sizes that cover every window of every record for window lengths up to
    `max_window_revs` and hops down to `min_hop_revs` (concrete batch needed)."""
    rev = np.asarray(batch.rev, np.float64)
    mask = np.asarray(batch.mask)
    d = np.diff(rev, axis=-1)
    dmask = mask[:, 1:] & mask[:, :-1]
    dmin, dmax = float(d[dmask].min()), float(d[dmask].max())
    span = float(max((rev[i, mask[i]][-1] - rev[i, 0]) for i in range(len(rev)))) + dmax
    n_windows = max(1, int(math.floor((span - start_revs - taper_revs - min(max_window_revs, span)) / min_hop_revs + _EPS_REVS)) + 1)
    extent = max_window_revs + 2.0 * max(taper_revs, dmax) + 4.0 * dmax
    support = int(math.ceil(extent / dmin)) + 4
    return WindowPlan(n_windows, support)


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
        partial(harmonic_windows, harmonic=harmonic, n_windows=plan.n_windows, support=plan.support),
        in_axes=(0, 0, 0, 0, 0, 0, None, None, None, None),
    )
    return fn(batch.az, batch.psi, batch.rev, batch.time, batch.x, batch.mask,
              window_revs, hop, taper_revs, start_revs)
