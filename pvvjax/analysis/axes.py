"""Harmonics of several pilot-floor axes in one windowed pass.

A seat shaker or motion base is driven in three axes, and a simulator must reproduce the
1/rev of rotor track and balance beside the blade-passage N/rev (FAA Part 60 App. C,
3.f.1). `axis_windows` weighs every window once and sums, in that one pass, the products of
every axis with every harmonic's phasor: for A axes and H harmonics, the window sums of

    time, a_1..a_A, (cos kψ, sin kψ) per harmonic, a·(cos kψ, sin kψ) per axis and harmonic,

and then each (axis, harmonic) is computed exactly as `harmonic_windows` computes its one:
c = mean(a e^{-ikψ}) − mean(a)·mean(e^{-ikψ}), amplitude 2|c|, phase arg c. The channel
means of the flight state ride in the same pass, so a peak table per axis and harmonic
needs no second analysis.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..data.batch import RecordBatch, bucket_size, by_group, pad_rows, unpad_rows
from .harmonics import (
    WindowPlan,
    Windows,
    _edge_kind,
    _phasor_power,
    make_columns,
    means_from_sums,
    plan_groups,
    record_plans,
    window_bounds,
    window_sums,
)

__all__ = ["AXES", "AxisWindows", "analyze_axes", "axis_windows", "resolved_harmonics"]

# The pilot-floor acceleration channels of the data contract: vertical, longitudinal, lateral.
AXES = ("az_g", "ax_g", "ay_g")


class AxisWindows(NamedTuple):
    """Per-window harmonics of several axes (leading batch axes, then as below).

    Attributes:
        amplitude: (..., A, H, W) amplitude of harmonic h of axis a, g.
        phase: (..., A, H, W) its phase relative to the blade azimuth, rad.
        time: (..., W) weighted window-centre time, s.
        means: (..., W, C) window-averaged channels.
        center: (..., W, C) channels at the window-centre time.
        valid: (..., W) True where the window lies wholly inside the record.
    """

    amplitude: jax.Array
    phase: jax.Array
    time: jax.Array
    means: jax.Array
    center: jax.Array
    valid: jax.Array

    def select(self, axis: int, harmonic: int) -> Windows:
        """The `Windows` of one axis index and harmonic index (what `analyze` gives for it)."""
        return Windows(self.amplitude[..., axis, harmonic, :], self.phase[..., axis, harmonic, :], self.time,
                       self.means, self.center, self.valid)


@partial(jax.jit, static_argnames=("harmonics", "taper_revs", "plan", "edge"))
def axis_windows(accel, cos_psi, sin_psi, rev, width, time, x, mask, window_revs, hop_revs, start_revs=0.0, *,
                 harmonics: tuple[int, ...], taper_revs: float = 0.0, plan: WindowPlan,
                 edge: str = "cell") -> AxisWindows:
    """Harmonics `harmonics` of every axis of one record, in one windowed pass.

    Args:
        accel: (T, A) pilot-floor accelerations, g (0 in padding).
        cos_psi, sin_psi, rev, width, time, x, mask, window_revs, hop_revs, start_revs,
            taper_revs, plan, edge: as in `harmonic_windows`.
        harmonics: the harmonic orders k (static), e.g. (1, N, 2N).

    Returns:
        `AxisWindows` with shapes (A, H, W), (W,) and (W, C).
    """
    kind = _edge_kind(edge, taper_revs)
    T, n_axes = accel.shape
    H = len(harmonics)
    phasors = [p for k in harmonics for p in _phasor_power(cos_psi, sin_psi, k)]  # cos k1ψ, sin k1ψ, cos k2ψ, ...
    axes = [accel[:, i] for i in range(n_axes)]
    x_ref = x[0]
    cols = (time, *axes, *phasors, *(a * p for a in axes for p in phasors),
            *(x[:, c] - x_ref[c] for c in range(x.shape[1])))
    columns = make_columns(cols, rev, width, x_ref, block=plan.block)
    a, b, inside = window_bounds(rev, width, mask, window_revs, hop_revs, start_revs, taper_revs, plan.n_windows)
    mean, wsum = means_from_sums(window_sums(columns, a, b, kind=kind, taper_revs=taper_revs, plan=plan))
    t_mid = mean[:, 0]
    bar = mean[:, 1:1 + n_axes]  # (W, A)
    ph = mean[:, 1 + n_axes:1 + n_axes + 2 * H].reshape(-1, 1, H, 2)  # (W, 1, H, cos/sin)
    n_prod = 2 * H * n_axes
    prod = mean[:, 1 + n_axes + 2 * H:1 + n_axes + 2 * H + n_prod].reshape(-1, n_axes, H, 2)
    re = prod[..., 0] - bar[..., None] * ph[..., 0]
    im = -(prod[..., 1] - bar[..., None] * ph[..., 1])
    amplitude = 2.0 * jnp.sqrt(re**2 + im**2 + jnp.finfo(mean.dtype).tiny)
    center = jax.vmap(lambda col: jnp.interp(t_mid, time[:T], col), in_axes=1, out_axes=1)(x[:T])
    means = mean[:, 1 + n_axes + 2 * H + n_prod:] + x_ref
    return AxisWindows(jnp.moveaxis(amplitude, 0, -1), jnp.moveaxis(jnp.arctan2(im, re), 0, -1), t_mid, means,
                       center, inside & (wsum > 0))


def resolved_harmonics(batch: RecordBatch, harmonics, window_revs: float) -> tuple[int, ...]:
    """The harmonics a campaign's windows resolve: every record's typical sampling gives more
    than 2k samples per revolution (below, harmonic k aliases onto a lower one), and the
    window spans at least one revolution (shorter, neighbouring harmonics do not separate).

    A record's sampling is its median azimuth step, so that one glitched sample (an azimuth
    that stands still or jumps) does not drop a harmonic from every record's tables; the
    sparsest record decides.

    Args:
        batch: the campaign's records (`to_batch`).
        harmonics: candidate orders k (per rev).
        window_revs: the analysis window (revolutions).

    Returns:
        the resolved orders of `harmonics`, in their order.
    """
    rev, mask = np.asarray(batch.rev, np.float64), np.asarray(batch.mask)
    both = mask[:, 1:] & mask[:, :-1]
    steps = [np.median(d[m]) for d, m in zip(np.diff(rev, axis=-1), both) if m.any()]
    per_rev = 1.0 / float(max(steps))  # exactly 2k is not resolved: a margin above the rounding of `rev`
    return tuple(k for k in harmonics if per_rev > 2 * k * (1.0 + 1e-4) and window_revs >= 1.0)


def analyze_axes(batch: RecordBatch, harmonics, window_revs: float = 8.0, hop_revs: float | None = None, *,
                 taper_revs: float = 0.0, start_revs: float = 0.0, plan: WindowPlan | None = None,
                 edge: str = "cell") -> AxisWindows:
    """`axis_windows` of every record of a batch whose `accel` holds several axes
    (`to_batch(..., axis=AXES)`: (B, T, A)), vmapped over counters; arguments as `analyze`.

    Returns:
        `AxisWindows` with shapes (B, A, H, W), (B, W) and (B, W, C).
    """
    if np.ndim(batch.accel) != 3:
        raise ValueError("analyze_axes needs a batch of several axes: to_batch(..., axis=(...))")
    hop = window_revs if hop_revs is None else hop_revs
    if plan is None:  # each record's sizes from its own samples (see `analyze`)
        groups = plan_groups(record_plans(batch, float(window_revs), float(hop), float(taper_revs),
                                          float(start_revs), edge=edge))
        if len(groups) > 1:
            return by_group(batch, groups, lambda b, p: analyze_axes(b, harmonics, window_revs, hop_revs,
                                                                    taper_revs=taper_revs, start_revs=start_revs,
                                                                    plan=p, edge=edge))
        plan = next(iter(groups))
    fn = jax.vmap(partial(axis_windows, harmonics=tuple(int(k) for k in harmonics), taper_revs=float(taper_revs),
                          plan=plan, edge=edge), in_axes=(0, 0, 0, 0, 0, 0, 0, 0, None, None, None))
    arrays = (batch.accel, batch.cos_psi, batch.sin_psi, batch.rev, batch.width, batch.time, batch.x, batch.mask)
    n = arrays[0].shape[0]
    return unpad_rows(fn(*pad_rows(arrays, bucket_size(n)), window_revs, hop, start_revs), n)
