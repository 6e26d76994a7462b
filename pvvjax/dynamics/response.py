"""The dynamic part of a vibration model, as pure JAX functions of window sequences: a
delay and a unit-gain second-order response, so that a static map followed by them equals
the map in trimmed flight and follows a maneuver with the lag, overshoot and ringing the
identified natural frequency and damping give.

Sequences run along the last axis, sampled at window times `t` (s) that need not be
uniform (the windows are a whole number of revolutions, and the rotor speed varies);
padding after a record's last window repeats its last time, a step of 0 s, which holds the
state."""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["delayed", "second_order"]


@jax.jit  # one program per shape, inside another program or not
def second_order(u: jax.Array, t: jax.Array, omega_n, zeta) -> jax.Array:
    """y'' + 2ζω_n y' + ω_n² y = ω_n² u, from rest at u's first value (y = u[0], y' = 0),
    integrated step by step by the trapezoidal rule (Tustin): exact steady gain 1, stable for
    every step, and differentiable in ω_n and ζ.

    Args:
        u: (..., T) input, g.
        t: (..., T) times, s, non-decreasing (a step of 0 holds the state).
        omega_n: natural frequency, rad/s (scalar or broadcasting against u[..., 0]).
        zeta: damping ratio (likewise).

    Returns:
        (..., T) response, g.
    """
    u = jnp.asarray(u)
    w2 = jnp.broadcast_to(jnp.asarray(omega_n, u.dtype) ** 2, u.shape[:-1])
    c = jnp.broadcast_to(2.0 * jnp.asarray(zeta, u.dtype) * jnp.asarray(omega_n, u.dtype), u.shape[:-1])
    a = 0.5 * jnp.moveaxis(jnp.diff(t, axis=-1), -1, 0)
    pairs = jnp.moveaxis(u[..., :-1] + u[..., 1:], -1, 0)

    def step(state, inp):
        y, v = state
        a, s = inp
        r0 = y + a * v
        r1 = v - a * w2 * y - a * c * v + a * w2 * s
        det = 1.0 + a * c + a * a * w2
        y, v = ((1.0 + a * c) * r0 + a * r1) / det, (-a * w2 * r0 + r1) / det
        return (y, v), y

    _, ys = jax.lax.scan(step, (u[..., 0], jnp.zeros_like(u[..., 0])), (a, pairs))
    return jnp.concatenate([u[..., :1], jnp.moveaxis(ys, 0, -1)], axis=-1)


@jax.jit  # one program per shape, inside another program or not
def delayed(u: jax.Array, t: jax.Array, delay_s) -> jax.Array:
    """u(t − delay) by linear interpolation along each sequence, its first value held before
    it starts: a fractional delay, differentiable in `delay_s`.

    Args:
        u: (..., T) sequence. t: (..., T) its times, s, non-decreasing.
        delay_s: the delay, s (>= 0; scalar or broadcasting against u[..., 0]).

    Returns:
        (..., T).
    """
    u, t = jnp.asarray(u), jnp.asarray(t)
    d = jnp.broadcast_to(jnp.asarray(delay_s, u.dtype), u.shape[:-1])
    flat = lambda a: a.reshape(-1, a.shape[-1])  # noqa: E731
    out = jax.vmap(lambda ui, ti, di: jnp.interp(ti - di, ti, ui))(flat(u), flat(t), d.reshape(-1))
    return out.reshape(u.shape)
