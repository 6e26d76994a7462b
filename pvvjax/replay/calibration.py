"""Calibration of the input-to-vibration offset, the window length and the stick lag by
gradient, and brute-force cost grids to check it.

A calibration fits θ = (offset_s, window_revs, stick_offset_s), or any subset of it, to a
group of counters: the cost of a group is the mean `replay_cost` of its counters. Groups
are independent (one θ for the whole campaign, one per maneuver kind, one per counter), so
the solve is vmapped over groups; it vmaps over databases as well (stack their models).

The cost is not convex in the offset (a peak can match the wrong bump), so a solve starts
from the best point of a coarse grid and then refines it with Levenberg-Marquardt on the
cost's residuals (`_levenberg_marquardt`). Parameters are clipped to their bounds.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .quasistatic import CostWeights, ReplayRecord, Settings, cost_terms, replay, residuals

__all__ = ["PARAMS", "Bounds", "Calibration", "calibrate", "cost_grid", "counter_costs", "group_members"]

PARAMS = ("offset_s", "window_revs", "stick_offset_s")


class Bounds(NamedTuple):
    """(lo, hi) of each calibrated parameter (s, revolutions, s); traced by `calibrate`."""

    offset_s: tuple[float, float] = (-1.0, 3.0)
    window_revs: tuple[float, float] = (4.0, 16.0)
    stick_offset_s: tuple[float, float] = (-2.0, 2.0)


class Calibration(NamedTuple):
    """Result per group (leading axis G).

    Attributes:
        theta: (G, 3) calibrated (offset_s, window_revs, stick_offset_s).
        start: (G, 3) the coarse-grid starting point.
        cost: (G,) group cost at theta. start_cost: (G,) at the start.
        steps: (G,) Levenberg-Marquardt steps. ok: (G,) solver converged.
    """

    theta: jax.Array
    start: jax.Array
    cost: jax.Array
    start_cost: jax.Array
    steps: jax.Array
    ok: jax.Array


def group_members(groups, n_groups: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Counter indices of each group, padded: (members (G, M), mask (G, M)).

    Args:
        groups: (N,) group id of each counter, in [0, G).
    """
    groups = np.asarray(groups)
    n_groups = int(groups.max()) + 1 if n_groups is None else n_groups
    lists = [np.flatnonzero(groups == g) for g in range(n_groups)]
    if any(len(m) == 0 for m in lists):
        raise ValueError(f"empty group(s): {[g for g, m in enumerate(lists) if len(m) == 0]}")
    M = max(len(m) for m in lists)
    members = np.stack([np.pad(m, (0, M - len(m)), constant_values=m[0]) for m in lists])
    mask = np.stack([np.arange(M) < len(m) for m in lists])
    return members.astype(np.int32), mask


def _take(tree, idx):
    return jax.tree.map(lambda a: a[idx], tree)


def _clip(theta, bounds):
    """θ clipped to `bounds`, a (3, 2) array of (lo, hi) (data: other bounds, same program)."""
    bounds = jnp.asarray(bounds, theta.dtype)
    return jnp.clip(theta, bounds[:, 0], bounds[:, 1])


def _replay_counter(model, rec, theta, settings, apply):
    return replay(model, rec, theta[0], theta[1], theta[2], settings=settings, apply=apply)


def _group_residuals(theta, models, recs, mask, settings, weights, apply):
    """Residuals of a group's members, scaled so that their squares sum to the mean cost."""
    res = jax.vmap(lambda m, r: residuals(_replay_counter(m, r, theta, settings, apply), weights))(models, recs)
    n = jnp.maximum(jnp.sum(mask), 1)
    return (res * (mask[:, None] / jnp.sqrt(n))).reshape(-1)


def _group_cost(theta, models, recs, mask, settings, weights, apply):
    return jnp.sum(_group_residuals(theta, models, recs, mask, settings, weights, apply) ** 2)


@partial(jax.jit, static_argnames=("apply",))
def counter_costs(models, recs: ReplayRecord, theta, *, settings: Settings, weights: CostWeights = CostWeights(),
                  apply=None) -> dict:
    """Cost terms of every counter at its own θ.

    Args:
        models: per-counter models (leading axis N; see `replay`).
        recs: `ReplayRecord`s (leading axis N).
        theta: (N, 3) or (3,) (offset_s, window_revs, stick_offset_s).

    Returns:
        dict of (N,) arrays: cost, peak_error_g, phase_error_s, rms_g.
    """
    theta = jnp.broadcast_to(jnp.asarray(theta, recs.time.dtype), (recs.time.shape[0], 3))

    def one(m, r, th):
        rep = _replay_counter(m, r, th, settings, apply)
        return dict(cost=jnp.sum(residuals(rep, weights) ** 2), **cost_terms(rep, weights))

    return jax.vmap(one)(models, recs, theta)


@partial(jax.jit, static_argnames=("apply",))
def cost_grid(models, recs: ReplayRecord, members, mask, offsets, lengths, base=(0.0, 8.0, 0.0), *,
              settings: Settings, weights: CostWeights = CostWeights(), apply=None):
    """Brute-force group cost on a grid of offsets × window lengths.

    Args:
        models, recs: per-counter models and records (leading axis N).
        members, mask: `group_members`.
        offsets: (K,) s. lengths: (J,) revolutions.
        base: θ for the parameters not on the grid (the stick offset).

    Returns:
        (G, J, K) mean cost of each group.
    """
    base = jnp.asarray(base, recs.time.dtype)

    offsets, lengths = jnp.asarray(offsets, base.dtype), jnp.asarray(lengths, base.dtype)
    points = jnp.stack(jnp.meshgrid(lengths, offsets, indexing="ij"), -1).reshape(-1, 2)

    def group(mem, msk):
        m, r = _take(models, mem), _take(recs, mem)
        cost = lambda p: _group_cost(base.at[0].set(p[1]).at[1].set(p[0]), m, r, msk, settings, weights, apply)  # noqa: E731
        # Points in batches: vmapping the whole grid would hold every replay in memory at once.
        return jax.lax.map(cost, points, batch_size=8).reshape(lengths.shape[0], offsets.shape[0])

    return jax.lax.map(lambda a: group(*a), (members, mask))


def _levenberg_marquardt(fn, y0, *, max_steps: int, rtol: float, atol: float):
    """Minimise sum(fn(y, None)²) over a few parameters y from y0: Marquardt's scaled
    damping, forward-mode Jacobian (one linearisation per step).

    Converged when a step changes every parameter by at most atol + rtol·|y| and lowers the
    cost by at most atol + rtol·cost (a rejected step that small: the minimum, to float
    precision). Written out rather than `optimistix.LevenbergMarquardt`: for 1-3
    parameters it takes the same kind of steps, but a vmapped `calibrate` compiles in about
    half the time (21 s -> 9 s on the test problem), which is most of a calibration's first call.
    The loop's first pass linearises at y0 (accepted against an infinite cost), so that the
    program holds one linearisation of `fn`, not a second one before the loop: the replay's
    forward-mode derivative is most of what XLA compiles.

    Returns:
        (y, fn(y) (the residuals of the last accepted step: no separate evaluation), steps
        taken, converged).
    """
    eye = jnp.eye(y0.shape[0], dtype=y0.dtype)

    def step(J, r, lam):
        H = J.T @ J
        d = jnp.diag(H)
        floor = 1e-12 * jnp.max(d) + jnp.sqrt(jnp.finfo(d.dtype).tiny)  # a flat cost: a zero step, not 0 / 0
        return jnp.linalg.solve(H + jnp.diag(lam * d + floor), -(J.T @ r))

    def body(s):
        y, r, J, c, lam, k, _, dy = s
        r1, lin = jax.linearize(lambda v: fn(v, None), y + dy)
        J1 = jax.vmap(lin, out_axes=1)(eye)
        c1 = jnp.sum(r1**2)
        first = k < 0  # the start point itself: accepted if finite, neither a step nor converged
        accept = jnp.isfinite(c1) & (c1 < c)
        small = ~first & jnp.all(jnp.abs(dy) <= atol + rtol * jnp.abs(y)) & (c - c1 <= atol + rtol * c)
        pick = lambda new, old: jnp.where(accept, new, old)  # noqa: E731
        y, r, J, c = pick(y + dy, y), pick(r1, r), pick(J1, J), pick(c1, c)
        lam = jnp.where(first, lam, jnp.where(accept, jnp.maximum(lam / 3.0, 1e-12), lam * 4.0))
        return y, r, J, c, lam, k + 1, small, step(J, r, lam)

    # Step -1 tries y0 itself: r and J are placeholders until it is accepted.
    r_shape = jax.eval_shape(lambda v: fn(v, None), y0)
    r0 = jnp.zeros(r_shape.shape, r_shape.dtype)
    init = (y0, r0, jnp.zeros(r0.shape + y0.shape, r0.dtype), jnp.asarray(jnp.inf, r0.dtype),
            jnp.asarray(1e-3, y0.dtype), jnp.asarray(-1, jnp.int32), jnp.asarray(False), jnp.zeros_like(y0))
    y, r, _, _, _, steps, ok, _ = jax.lax.while_loop(lambda s: (s[5] < max_steps) & ~s[6], body, init)
    return y, r, steps, ok


@partial(jax.jit, static_argnames=("free", "apply"))
def calibrate(models, recs: ReplayRecord, members, mask, init, coarse, *, free: tuple[str, ...] = ("offset_s",),
              bounds: Bounds = Bounds(), settings: Settings, weights: CostWeights = CostWeights(), apply=None,
              max_steps: int = 64, rtol: float = 1e-5, atol: float = 1e-6) -> Calibration:
    """Fit θ per group: coarse grid, then Levenberg-Marquardt on the residuals.

    Only the structure keys the compiled program (`free`, `apply`, and the shapes and
    static plan of the records and settings); bounds, cost weights, step budget and
    tolerances are traced data, so calibrating with other values reuses it.

    Args:
        models, recs: per-counter models and records (leading axis N).
        members, mask: `group_members` (G groups).
        init: (3,) or (G, 3) θ; the parameters not in `free` stay at it.
        coarse: (K, len(free)) candidate values of the free parameters; the best one
            (lowest group cost) starts the solve.
        free: names of the fitted parameters (in `PARAMS`).
        bounds: parameter bounds (θ is clipped to them).
        settings, weights, apply: see `replay` and `CostWeights`.
        max_steps, rtol, atol: Levenberg-Marquardt's step budget and convergence tolerances.

    Returns:
        `Calibration` with leading axis G.
    """
    unknown = [f for f in free if f not in PARAMS]
    if unknown or not free:
        raise ValueError(f"free parameters must be a non-empty subset of {PARAMS}, got {free}")
    fi = jnp.array([PARAMS.index(f) for f in free])
    dt = recs.time.dtype
    bounds = jnp.asarray(bounds, dt)
    init = jnp.broadcast_to(jnp.asarray(init, dt), (members.shape[0], 3))
    coarse = jnp.asarray(coarse, dt)

    def group(mem, msk, th0):
        m, r = _take(models, mem), _take(recs, mem)
        full = lambda y: _clip(th0.at[fi].set(y), bounds)  # noqa: E731
        fn = lambda y, _: _group_residuals(full(y), m, r, msk, settings, weights, apply)  # noqa: E731
        costs = jax.lax.map(lambda y: jnp.sum(fn(y, None) ** 2), coarse)
        y0 = coarse[jnp.argmin(costs)]
        y, r, steps, ok = _levenberg_marquardt(fn, y0, max_steps=max_steps, rtol=rtol, atol=atol)
        c = jnp.sum(r**2)
        c0 = jnp.min(costs)
        # Keep the start if the solve made it worse (it cannot, unless it failed).
        better = c <= c0
        return (jnp.where(better, full(y), full(y0)), full(y0), jnp.minimum(c, c0), c0, steps, ok)

    out = jax.vmap(group)(members, mask, init)
    return Calibration(*out)
