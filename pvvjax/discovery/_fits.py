"""Least-squares fits of discovery: a lag's time constant, a knee or a band, the offset of
a model."""

from __future__ import annotations

import warnings
from dataclasses import replace

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pandas as pd

from ._model import Model, _Ctx, _grid, _lag_grid, _replay, _Windows, predictions
from .candidates import Candidate
from .effects import band


# The least-squares residuals are module functions with their data in `args` (optimistix's
# fn(y, args)): a closure over the arrays would make them constants of the compiled solve, and
# XLA would compile a new solve (~3 s) for every candidate and every fit.
def _cell_tau(theta, tau0, cell):
    """A time constant kept within a factor `cell` of `tau0`: τ0 · cell^tanh θ."""
    return tau0 * cell ** jnp.tanh(theta)


def _tau_residuals(theta, args):
    y, tg, i, k, target, sw, tau0, cell = args
    return (_lag_grid(y, tg, _cell_tau(theta, tau0, cell))[i, k] - target) * sw


def _band(theta, center, width):
    """A resonance band kept in its grid cell: centre within one width, width within a factor 2."""
    return center + width * jnp.tanh(theta[0]), width * 2.0 ** jnp.tanh(theta[1])


def _refine_residuals(theta, args):
    x, r, yhat, B, sw, softness, center, width, operator, above, shape = args  # operator, above, shape: static
    if operator == "threshold":
        u = (x - theta[0]) if above else (theta[0] - x)
        column = softness * jax.nn.softplus(u / softness)
    else:
        c, w = _band(theta, center, width)
        column = yhat * band((x - c) / w, shape)
    A = jnp.column_stack([B, column]) * sw[:, None]
    # The inner linear solve by its normal equations (a few columns, standardised): a QR or
    # SVD of the (n, p) matrix in every Jacobian column costs several times more.
    gram = A.T @ A
    coef = jnp.linalg.solve(gram + 1e-6 * jnp.trace(gram) / gram.shape[0] * jnp.eye(gram.shape[0]), A.T @ (r * sw))
    return r * sw - A @ coef


def fit_lag(yhat, meas, win: _Windows, rows, tau_s: float, weights=None, cell: float = 2.0) -> float:
    """The time constant of a first-order lag of the prediction `yhat` (n,) that best fits
    the measured PVV `meas` on `rows` (weighted least squares, `weights` per row: a bootstrap
    over conditions keeps every shape), by Levenberg–Marquardt from `tau_s`, within a factor
    `cell` of it (τ = tau_s · cell^tanh θ): the test named the lag at `tau_s`, and a τ that walks
    further is another candidate (a τ that stops at that bound is warned about). Against the
    measured level alone, a longer lag also smooths the prediction's own noise, so an
    unbounded fit can run to a lag that only smooths."""
    i, k, to_grid, tg = _grid(win)
    w = np.ones(int(np.sum(rows))) if weights is None else np.asarray(weights, float)
    f32 = lambda v: jnp.asarray(v, jnp.float32)  # noqa: E731
    args = (jnp.asarray(to_grid(yhat)), jnp.asarray(tg), jnp.asarray(i[rows]), jnp.asarray(k[rows]),
            jnp.asarray(meas[rows]), jnp.asarray(np.sqrt(w)), f32(tau_s), f32(cell))
    sol = optx.least_squares(_tau_residuals, optx.LevenbergMarquardt(rtol=1e-6, atol=1e-9), jnp.zeros(()), args,
                             max_steps=64, throw=False)
    tau = float(_cell_tau(sol.value, tau_s, cell))
    if not np.isfinite(tau):
        return float(tau_s)
    if weights is None and abs(float(jnp.tanh(sol.value))) > 0.99:  # a bootstrap draw is not warned about
        warnings.warn(f"discovery: the lag's time constant stopped at its search bound ({tau:.3g} s, a factor "
                      f"{cell:g} from the {tau_s:.3g} s the test named): the data hold a lag beyond it, which the "
                      "test did not name; it is reported at the bound", UserWarning, stacklevel=2)
    return tau


def _fit_offset(ctx: _Ctx, model: Model) -> Model:
    """The model at the offset (grid over `offset.bounds`, or `offset.fixed_s`) that
    minimises the held-out window SSE of its ensemble median, its own lag applied."""
    d = ctx.cfg.discovery
    if not d.offset.calibrate:
        offsets = np.array([d.offset.fixed_s])
    else:
        offsets = np.arange(d.offset.bounds[0], d.offset.bounds[1] + 1e-9, d.offset.step_s)
    best = (np.inf, 0.0)
    for off in offsets:
        win = _replay(ctx, float(off))
        full = win.table.weight.to_numpy() >= 0.999
        yhat = np.median(predictions(ctx, model, win), axis=0)
        sse = float(np.sum((yhat[full] - win.table.measured_g.to_numpy()[full]) ** 2))
        if sse < best[0]:
            best = (sse, float(off))
    return model._replace(offset_s=best[1])


def _standardise(A):
    """Columns centred and scaled to unit spread; constant columns dropped."""
    A = np.asarray(A, float)
    sd = A.std(axis=0)
    return ((A - A.mean(axis=0)) / np.where(sd > 0, sd, 1.0))[:, sd > 0]


def _refine(c: Candidate, residual, cands: pd.DataFrame, prediction, base=None, weights=None) -> Candidate:
    """Refine a knee, or a resonance's centre and width, by variable-projection least
    squares: residual ≈ b0 + base·β + b·candidate(θ) (for a resonance, a gain:
    b·prediction·band(θ)), (b0, β, b) solved inside, θ by Levenberg–Marquardt.

    Args:
        c: the candidate (other operators are returned as they are).
        residual, prediction: (n,) per window, g. cands: the `window_table` of the windows.
        base: (n, p) covariates fitted beside it (the model's inputs: a knee of a channel
            that follows them would otherwise take their part).
        weights: (n,) per window (a bootstrap over conditions keeps every shape).

    Returns:
        The candidate with the fitted parameters, or `c` where the fit does not lower the
        error or leaves the data: a knee beyond the 2-98 % range of its channel is a line
        through a few windows; a band stays within one width of where the test found it and
        its width within a factor 2 (further, it is another candidate, which the test did
        not name). A knee kept at its grid point, or a band stopped at a bound, is warned
        about (`UserWarning`), except in a bootstrap draw (`weights` given).
    """
    if c.operator not in ("threshold", "resonance"):
        return c
    x = jnp.asarray(cands[f"x:{c.channels[0]}"].to_numpy())
    p = c.parameters
    # Standardised (float32 least squares).
    B = jnp.asarray(np.column_stack([np.ones(len(x)), *([] if base is None else [_standardise(np.asarray(base))])]))
    f32 = lambda v: jnp.asarray(v, jnp.float32)  # noqa: E731
    sw = jnp.asarray(np.sqrt(np.ones(len(x)) if weights is None else np.asarray(weights, float)))
    args = (x, jnp.asarray(residual), jnp.asarray(prediction), B, sw, f32(p.get("softness", 1.0)),
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
    lo, hi = np.quantile(np.asarray(x), [0.02, 0.98])
    say = weights is None  # a bootstrap draw is not warned about
    if c.operator == "threshold":
        # A knee beyond the bulk of the data is a line through a few windows, not a knee.
        if lo <= th[0] <= hi:
            return replace(c, parameters={**p, "knee": float(th[0])})
        if say:
            warnings.warn(f"discovery: {c.name}: the fit moves the knee to {th[0]:.4g}, beyond the 2-98 % range of "
                          f"{c.channels[0]} ({lo:.4g} to {hi:.4g}), a line through a few windows; it is reported at "
                          f"{p['knee']:.4g}, where the test named it", UserWarning, stacklevel=2)
        return c
    center, width = (float(v) for v in _band(sol.value, p["center"], p["width"]))
    if say and (np.any(np.abs(np.tanh(th)) > 0.99) or not lo <= center <= hi):
        warnings.warn(f"discovery: {c.name}: the band's fit stopped at its search bound (centre {center:.4g} within "
                      f"one width of {p['center']:.4g}, width {width:.3g} within a factor 2 of {p['width']:.3g}, "
                      f"inside the 2-98 % range of {c.channels[0]}): the data hold a band beyond it, which the test "
                      "did not name; it is reported at the bound", UserWarning, stacklevel=2)
    return replace(c, parameters={**p, "center": float(np.clip(center, lo, hi)), "width": width})
