"""The real-time vibration element as a pure JAX step: (state, frame) -> (state, outputs).

The same element as the NumPy one (`pvvjax.realtime.element`, the one to embed in a simulator
host), written as a pure function so that it jits, runs a whole record in one
`lax.scan` (`stream`), and vmaps over records or models. Frames are kept in a ring buffer of
fixed capacity; a window is computed (by `lax.while_loop`, so a long frame gap catches up)
when the first frame past its end arrives. A rejected frame (non-finite value or time not
advancing) leaves the state unchanged, which also makes padding a record with NaN frames
harmless.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..analysis.harmonics import edge_weight
from ..data.constants import UH60A
from ..data.features import advance_ratio, maneuver_load_factor
from ..nets.networks import apply_for
from .element import CHANNELS, FEATURES

__all__ = ["ElementSpec", "ElementState", "StepOutput", "capacity_for", "init", "make_spec", "step", "stream"]

_STICK_IDX = np.array([CHANNELS.index(s) for s in ("collective_pct", "lateral_pct", "longitudinal_pct")], np.int32)


class ElementSpec(NamedTuple):
    """The element's parameters (a PyTree: arrays and floats).

    Attributes:
        params: nets stacked on a leading axis (their median is the prediction).
        idx: (d,) indices of the nets' inputs into `FEATURES` order (see `make_spec`).
        window_revs, hop_revs, offset_s, stick_offset_s, phase_rad: as `rtelement.VibrationElement`.
        lo, hi: (d,) input envelope (±inf: none). clip: 1.0 to clip to it, 0.0 to only flag.
        rotor_radius_ft, g_ft_s2: rotor constants of the features.
        harm_k, harm_ratio, harm_phase: extra seat-shake harmonics (order, ratio to the
            4/rev amplitude, phase), as `rtelement.VibrationElement(harmonics=...)`.
    """

    params: dict
    idx: jax.Array
    window_revs: float
    hop_revs: float
    offset_s: float
    stick_offset_s: float
    phase_rad: float
    lo: jax.Array
    hi: jax.Array
    clip: float
    rotor_radius_ft: float
    g_ft_s2: float
    harm_k: jax.Array
    harm_ratio: jax.Array
    harm_phase: jax.Array




def make_spec(params, inputs, *, window_revs=8.0, hop_revs=1.0, offset_s=0.0, stick_offset_s=0.0, phase_rad=0.0,
              envelope=None, clip=True, rotor_radius_ft=26.83, g_ft_s2=32.174, harmonics=None) -> ElementSpec:
    """An `ElementSpec` from stacked net parameters (MLP or RBF) and the database's input
    names (features: the rates and the GRU of `pvvjax dynamic` run in the NumPy, C and FMU
    elements)."""
    rates = [k for k in inputs if k not in FEATURES]
    if rates or "rnn" in params:
        raise ValueError(f"the JAX element takes {', '.join(FEATURES)} into MLP or RBF nets; "
                         f"{'inputs ' + str(rates) if rates else 'a GRU'} run in the NumPy, C or FMU element")
    # Nets from a sweep take every database padded to the same inputs (masked): pad to match.
    n_in = int(np.shape(params["x_shift"])[-1])
    d = len(inputs)
    idx = jnp.asarray([FEATURES.index(k) for k in inputs] + [0] * (n_in - d))
    lo, hi = (np.full(d, -np.inf), np.full(d, np.inf)) if envelope is None else envelope
    lo = np.concatenate([np.asarray(lo, float), np.full(n_in - d, -np.inf)])
    hi = np.concatenate([np.asarray(hi, float), np.full(n_in - d, np.inf)])
    f = lambda v: jnp.asarray(v, jnp.result_type(float))  # noqa: E731
    harm = {int(k): v for k, v in dict(harmonics or {}).items()}
    return ElementSpec(params, idx, f(window_revs), f(hop_revs), f(offset_s), f(stick_offset_s), f(phase_rad),
                       f(lo), f(hi), f(1.0 if clip else 0.0), f(rotor_radius_ft), f(g_ft_s2),
                       f(list(harm)), f([v[0] for v in harm.values()]), f([v[1] for v in harm.values()]))


class ElementState(NamedTuple):
    """Ring buffer of recent frames and the element's running values (all arrays)."""

    t: jax.Array  # (M,) frame times, s
    r: jax.Array  # (M,) unwrapped azimuth, revolutions
    x: jax.Array  # (M, C) channels
    n: jax.Array  # frames stored since reset (int)
    az: jax.Array  # last azimuth, deg
    j: jax.Array  # next window (int)
    start: jax.Array  # revolution where window 0 starts
    pvv: jax.Array
    prev: jax.Array
    ramp_rev: jax.Array
    wtime: jax.Array
    flag: jax.Array
    ready: jax.Array


class StepOutput(NamedTuple):
    """As `rtelement.ElementOutput`."""

    pvv_g: jax.Array
    shake_g: jax.Array
    amplitude_g: jax.Array
    ready: jax.Array
    window_time_s: jax.Array
    out_of_envelope: jax.Array
    rejected: jax.Array


def capacity_for(window_revs, hop_revs, offsets_s, frame_rate_hz, min_rpm=200.0) -> int:
    """Ring-buffer frames that cover a window, a hop and the offsets at the given frame
    rate down to `min_rpm` (a power of two)."""
    per_rev = frame_rate_hz * 60.0 / min_rpm
    need = (window_revs + 2.0 * hop_revs + 4.0) * per_rev + max(abs(o) for o in offsets_s) * frame_rate_hz + 16
    return 1 << math.ceil(math.log2(need))


def init(capacity: int, dtype=None) -> ElementState:
    """A reset element with a ring of `capacity` frames. For one call per frame, jit `step`
    with `donate_argnums=1`: the ring is then updated in place instead of copied."""
    dt = dtype or jnp.result_type(float)
    z = lambda: jnp.zeros((), dt)  # noqa: E731  (distinct buffers: the state may be donated)
    return ElementState(jnp.zeros(capacity, dt), jnp.zeros(capacity, dt), jnp.zeros((capacity, len(CHANNELS)), dt),
                        jnp.zeros((), jnp.int32), z(), jnp.zeros((), jnp.int32), z(), z(), z(), z(),
                        jnp.full((), jnp.nan, dt), jnp.zeros((), bool), jnp.zeros((), bool))


def _ordered(s: ElementState):
    """The ring in time order; slots never filled get times and revolutions far below the
    first frame (so the arrays stay increasing), and `first` is the oldest real slot."""
    M = s.t.shape[0]
    k = jnp.arange(M)
    pos = (s.n - M + k) % M
    real = (s.n - M + k) >= 0
    t, r, x = s.t[pos], s.r[pos], s.x[pos]
    first = jnp.maximum(M - s.n, 0)
    t = jnp.where(real, t, -1e12 + k)
    r = jnp.where(real, r, -1e12 + k)
    return t, r, x, first, real


def _interp(x, xp, fp, first):
    """`replay._interp` on the real part of the ordered ring (extrapolating from its ends)."""
    i = jnp.clip(jnp.searchsorted(xp, x, method="compare_all"), first + 1, xp.shape[0] - 1)
    x0, x1, f0, f1 = xp[i - 1], xp[i], fp[i - 1], fp[i]
    return f0 + (x - x0) * ((f1 - f0) / (x1 - x0))


def _window_edges(spec, s, t, r, first):
    a = s.start + spec.hop_revs * s.j
    b = a + spec.window_revs
    t_a, t_b = _interp(a, r, t, first), _interp(b, r, t, first)
    taus = jnp.stack([spec.offset_s, spec.offset_s + spec.stick_offset_s])
    ends = _interp(jnp.concatenate([t_a - taus, t_b - taus]), t, r, first)
    return b, t_a, t_b, ends[:2], ends[2:]


def _is_ready(spec, s):
    t, r, x, first, real = _ordered(s)
    b, _, _, _, b_in = _window_edges(spec, s, t, r, first)
    dr = jnp.where(real[1:] & real[:-1], jnp.diff(r), 0.0)
    need = jnp.max(b_in) + 2.0 * jnp.max(dr)  # every hat touching the input windows is complete
    return (s.n >= 3) & (r[-1] > b) & (r[-1] > need)


def _features(spec, x):
    ch = dict(zip(CHANNELS, x))
    ac = UH60A._replace(rotor_radius_ft=spec.rotor_radius_ft, g_ft_s2=spec.g_ft_s2)
    mu = advance_ratio(ch["airspeed_kt"], ch["rotor_rpm"], ac)
    mlf = maneuver_load_factor(ch["roll_angle_deg"], ch["pitch_rate_dps"], ch["airspeed_kt"], ac)
    return jnp.concatenate([x, jnp.stack([mu, mlf])])


def _amplitude(s: ElementState, spec):
    frac = jnp.clip((s.r[(s.n - 1) % s.r.shape[0]] - s.ramp_rev) / spec.hop_revs, 0.0, 1.0)
    return s.prev + (s.pvv - s.prev) * frac


def _window(spec, s: ElementState) -> ElementState:
    """Predict window s.j (assumed ready) and advance to the next."""
    t, r, x, first, real = _ordered(s)
    _, t_a, t_b, a_in, b_in = _window_edges(spec, s, t, r, first)
    M = t.shape[0]
    dr = jnp.diff(r)
    width = 0.5 * (jnp.concatenate([dr[:1], dr]) + jnp.concatenate([dr, dr[-1:]]))
    is_first = jnp.arange(M) == first
    width = jnp.where(is_first & (s.n <= M), dr[jnp.minimum(first, M - 2)], width)  # the record's first frame
    ok = real & ~(is_first & (s.n > M))  # the oldest slot of a wrapped ring lost its left neighbour
    h = jnp.where(ok, width, 1.0)

    def mean(lo, hi):
        w = jnp.where(ok, h * edge_weight((r - lo) / h, "linear") * edge_weight((hi - r) / h, "linear"), 0.0)
        return w @ x / jnp.sum(w)

    m_state, m_stick = mean(a_in[0], b_in[0]), mean(a_in[1], b_in[1])
    xm = m_state.at[_STICK_IDX].set(m_stick[_STICK_IDX])
    z = _features(spec, xm)[spec.idx]
    tol = 1e-9 * (1.0 + jnp.maximum(jnp.abs(spec.lo), jnp.abs(spec.hi)))  # as the NumPy element
    flag = jnp.any((z < spec.lo - tol) | (z > spec.hi + tol))
    z = jnp.where(spec.clip > 0, jnp.clip(z, spec.lo, spec.hi), z)
    preds = jnp.sort(jax.vmap(apply_for(spec.params), in_axes=(0, None))(spec.params, z))
    k = preds.shape[0]
    pred = 0.5 * (preds[(k - 1) // 2] + preds[k // 2])
    prev = jnp.where(s.ready, _amplitude(s, spec), pred)
    return s._replace(j=s.j + 1, pvv=pred, prev=prev, ramp_rev=r[-1], wtime=0.5 * (t_a + t_b), flag=flag,
                      ready=jnp.ones((), bool))


def step(spec: ElementSpec, s: ElementState, time_s, azimuth_deg, channels) -> tuple[ElementState, StepOutput]:
    """One frame: store it, predict every window that became ready, and output.

    Args:
        spec: `make_spec`. s: the state (`init`).
        time_s: frame time, s. azimuth_deg: reference-blade azimuth, deg.
        channels: (C,) `rtelement.CHANNELS`, canonical units.

    Returns:
        (new state, `StepOutput`).
    """
    dt = s.t.dtype
    time_s, azimuth_deg = jnp.asarray(time_s, dt), jnp.asarray(azimuth_deg, dt)
    channels = jnp.asarray(channels, dt)
    M = s.t.shape[0]
    last = (s.n - 1) % M
    bad = (~jnp.all(jnp.isfinite(channels)) | ~jnp.isfinite(time_s) | ~jnp.isfinite(azimuth_deg)
           | ((s.n > 0) & (time_s <= s.t[last])))
    d = azimuth_deg - s.az
    r = jnp.where(s.n == 0, azimuth_deg / 360.0, s.r[last] + (d - 360.0 * jnp.round(d / 360.0)) / 360.0)
    pos = s.n % M
    # A rejected frame writes the slot's old value back and does not advance: O(1), and the
    # ring is updated in place (a select over the whole state would copy it every frame).
    keep = lambda old, v: jnp.where(bad, old, v)  # noqa: E731
    s = s._replace(t=s.t.at[pos].set(keep(s.t[pos], time_s)), r=s.r.at[pos].set(keep(s.r[pos], r)),
                   x=s.x.at[pos].set(keep(s.x[pos], channels)), n=s.n + jnp.where(bad, 0, 1),
                   az=keep(s.az, azimuth_deg))
    s = s._replace(start=jnp.where((s.n == 2) & ~bad, s.r[0] - 0.5 * (s.r[1] - s.r[0]), s.start))

    # The windows that became ready. The loop carries only the small values (the ring is
    # read-only there): carrying the ring through XLA's loop and branches copies it.
    ring = s
    small_fields = ("j", "pvv", "prev", "ramp_rev", "wtime", "flag", "ready")
    r_last = s.r[(s.n - 1) % M]

    def full(q):
        return ring._replace(**dict(zip(small_fields, q)))

    def more(q):  # the cheap test first: has the rotor passed the window's end at all?
        b = s.start + spec.hop_revs * q[0] + spec.window_revs
        passed = (s.n >= 3) & (r_last > b)
        return jax.lax.cond(passed, lambda: _is_ready(spec, full(q)), lambda: jnp.zeros((), bool))

    def advance(q):
        new = _window(spec, full(q))
        return tuple(getattr(new, f) for f in small_fields)

    small = tuple(getattr(s, f) for f in small_fields)
    # Enter the loop only when the cheap test passes: a loop that closes over the ring costs
    # a copy of it per frame on CPU, once per window is nothing.
    b0 = s.start + spec.hop_revs * s.j + spec.window_revs
    small = jax.lax.cond((s.n >= 3) & (r_last > b0), lambda q: jax.lax.while_loop(more, advance, q), lambda q: q,
                         small)
    s = full(small)
    amp = jnp.where(s.n > 0, _amplitude(s, spec), 0.0)
    psi = 2.0 * jnp.pi * s.r[(s.n - 1) % M]
    shake = amp * (jnp.cos(4.0 * psi + spec.phase_rad)
                   + jnp.sum(spec.harm_ratio * jnp.cos(spec.harm_k * psi + spec.harm_phase)))
    out = StepOutput(s.pvv, shake, amp, s.ready, s.wtime, s.flag, bad)
    return s, out


@jax.jit
def stream(spec: ElementSpec, s: ElementState, time_s, azimuth_deg, channels) -> tuple[ElementState, StepOutput]:
    """A whole record in one `lax.scan` of `step` (frames (F,), (F,), (F, C)); outputs (F,)."""
    def body(state, frame):
        return step(spec, state, *frame)

    return jax.lax.scan(body, s, (time_s, azimuth_deg, channels))
