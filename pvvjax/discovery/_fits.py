"""Least-squares fits of discovery: a lag's time constant, a knee or band refined on the
selection's design, the offset of a model."""

from __future__ import annotations

from dataclasses import replace

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pandas as pd

from . import _rules
from ._model import Model, _Ctx, _grid, _lag_grid, _lag_windows, _replay, _selection_column, _Windows, predictions
from .candidates import Candidate
from .effects import band
from .selection import _standardise, gains


# The least-squares residuals are module functions with their data in `args` (optimistix's
# fn(y, args)): a closure over the arrays would make them constants of the compiled solve, and
# XLA would compile a new solve (~3 s) for every candidate and every fit.
def _tau_residuals(log_tau, args):
    y, tg, i, k, target = args
    return _lag_grid(y, tg, jnp.exp(log_tau))[i, k] - target


def _band(theta, center, width):
    """A resonance band kept in its grid cell: centre within one width, width within a factor 2."""
    return center + width * jnp.tanh(theta[0]), width * 2.0 ** jnp.tanh(theta[1])


def _refine_residuals(theta, args):
    x, r, yhat, B, softness, center, width, operator, above, shape = args  # operator, above, shape: static
    if operator == "threshold":
        u = (x - theta[0]) if above else (theta[0] - x)
        column = softness * jax.nn.softplus(u / softness)
    else:
        c, w = _band(theta, center, width)
        column = yhat * band((x - c) / w, shape)
    A = jnp.column_stack([B, column])
    coef = jnp.linalg.lstsq(A, r)[0]
    return r - A @ coef


def _fit_tau(yhat, meas, win: _Windows, full, taus, refine: bool = True) -> tuple[float, float]:
    """Time constant of a lag of the (ensemble) prediction that best fits the measured PVV:
    the best of `taus`, refined (if `refine`) by Levenberg–Marquardt in log τ. Returns (τ, SSE)."""
    sse = [float(np.sum((_lag_windows(yhat[None], win, t)[0][full] - meas[full]) ** 2)) for t in taus]
    t_best = float(taus[int(np.argmin(sse))])
    if not refine:
        return t_best, min(sse)
    i, k, to_grid, tg = _grid(win)
    args = (jnp.asarray(to_grid(yhat)), jnp.asarray(tg), jnp.asarray(i[full]), jnp.asarray(k[full]),
            jnp.asarray(meas[full]))
    sol = optx.least_squares(_tau_residuals, optx.LevenbergMarquardt(rtol=1e-6, atol=1e-9), jnp.log(t_best), args,
                             max_steps=64, throw=False)
    tau = float(jnp.exp(sol.value))
    fit = float(jnp.sum(_tau_residuals(sol.value, args) ** 2))
    # Within the grid's span: beyond it a lag only smooths the prediction flat.
    ok = np.isfinite(fit) and fit <= min(sse) and min(taus) <= tau <= max(taus)
    return (tau, fit) if ok else (t_best, min(sse))


def _lag_identified(tau: float, taus) -> bool:
    """Whether a fitted lag time constant measures a lag: inside the grid `taus`, not at its
    largest value, where the fit only asks for more smoothing (see `_confirm`)."""
    return 0.0 < tau < max(taus) - 1e-9


def _fit_offset(ctx: _Ctx, model: Model, with_lag: bool) -> Model:
    """The offset (grid over `offset_bounds`) and, with `with_lag`, the lag time constant
    (grid, then refined by LM at the best offset) that minimise the held-out window SSE of
    the ensemble median (without `with_lag`, of the model with its own lag)."""
    d = ctx.cfg.discovery
    if not d.offset.calibrate:
        offsets = np.array([d.offset.fixed_s])
    else:
        offsets = np.arange(d.offset.bounds[0], d.offset.bounds[1] + 1e-9, d.offset.step_s)
    best = (np.inf, 0.0, 0.0)
    for off in offsets:
        win = _replay(ctx, float(off))
        full = win.table.weight.to_numpy() >= 0.999
        meas = win.table.measured_g.to_numpy()
        yhat = np.median(predictions(ctx, model._replace(lag_tau_s=0.0) if with_lag else model, win), axis=0)
        if with_lag:
            tau, sse = _fit_tau(yhat, meas, win, full, _rules.LAG_TAUS, refine=False)
        else:
            tau, sse = model.lag_tau_s, float(np.sum((yhat[full] - meas[full]) ** 2))
        if sse < best[0]:
            best = (sse, float(off), tau, yhat, meas, full)
    tau = best[2]
    if with_lag:
        win = _replay(ctx, best[1])
        tau = _fit_tau(best[3], best[4], win, best[5], sorted({tau, *_rules.LAG_TAUS}))[0]
    return model._replace(offset_s=best[1], lag_tau_s=tau)


def _refine(c: Candidate, residual, cands: pd.DataFrame, prediction, base=None) -> Candidate:
    """Refine a knee, or a resonance's centre and width, by variable-projection least
    squares: residual ≈ b0 + base·β + b·candidate(θ) (for a resonance, a gain:
    b·prediction·band(θ)), (b0, β, b) solved inside, θ by LM. `base`: the selection's floor
    covariates on the same windows (a fit without them moves the knee or band to where the
    floor explains as much: measured, a band refined 267.5 → 264.2 rpm that the selection
    credited with a held-out gain of −0.10 against the grid's 0.08). A resonance stays in its
    grid cell: the centre within one grid width of the grid's (c0 + w0·tanh θ0), the width
    within a factor 2 (w0·2^tanh θ1); a band that walks further is another candidate, one the
    selection did not choose (a free fit moved 267.5 → 257.2 rpm, which did not confirm)."""
    if c.operator not in ("threshold", "resonance"):
        return c
    x = jnp.asarray(cands[f"x:{c.channels[0]}"].to_numpy())
    p = c.parameters
    # Standardised (float32 least squares).
    B = jnp.asarray(np.column_stack([np.ones(len(x)), *([] if base is None else [_standardise(np.asarray(base))])]))
    f32 = lambda v: jnp.asarray(v, jnp.float32)  # noqa: E731
    args = (x, jnp.asarray(residual), jnp.asarray(prediction), B, f32(p.get("softness", 1.0)),
            f32(p.get("center", 0.0)), f32(p.get("width", 1.0)), c.operator, bool(p.get("above", True)),
            p.get("shape", "gaussian"))
    th0 = jnp.array([p["knee"]]) if c.operator == "threshold" else jnp.zeros(2)
    sol = optx.least_squares(_refine_residuals, optx.LevenbergMarquardt(rtol=1e-6, atol=1e-10), th0, args,
                             max_steps=100, throw=False)
    th = np.asarray(sol.value)
    sse = lambda th: float(jnp.sum(_refine_residuals(th, args) ** 2))  # noqa: E731
    better = sse(sol.value) <= sse(th0)
    if not (np.all(np.isfinite(th)) and better):
        return c
    lo, hi = float(x.min()), float(x.max())
    if c.operator == "threshold":
        return replace(c, parameters={**p, "knee": float(np.clip(th[0], lo, hi))})
    center, width = (float(v) for v in _band(sol.value, p["center"], p["width"]))
    return replace(c, parameters={**p, "center": float(np.clip(center, lo, hi)), "width": width})


def _keep_better(grid: Candidate, refined: Candidate, win: _Windows, yhat, resid, rows, floor, folds: int, seed: int,
                 log=print) -> Candidate:
    """The refined candidate if the selection's design (its rows and floor covariates, the
    same folds) credits it with at least the grid candidate's held-out gain, else the grid's.
    `_refine` minimises the in-sample error, which a knee fitted to a few conditions can
    lower without predicting the others (measured: knees refined to a held-out gain of 0.027
    against the grid's 0.052, and 0.019 against 0.047)."""
    if refined.key == grid.key:
        return refined
    cols = np.column_stack([_selection_column(c, win.values(c), yhat)[rows] for c in (grid, refined)])
    g = gains(resid[rows], cols, win.table.condition.to_numpy()[rows], base=floor, folds=folds, seed=seed)
    if g[1] >= g[0]:
        return refined
    log(f"  {grid.name}: refined to {refined.name}, held-out gain {g[1]:.3f} < {g[0]:.3f}: kept")
    return grid
