"""The nuisance regressions of discovery's test: what the model's inputs (and their history)
explain of the residual and of each candidate, fitted out of fold by units.

The test holds its level only where these regressions remove what the inputs carry. A
baseline's misfit is often a sharp function of a physical composite of several inputs (the
blade loading W·n/(ρΩ²) at the load factor the inputs hold, the advance ratio V/(ΩR)), which
trees on the raw inputs learn only in part from a few hundred conditions; what they leave, a
candidate that follows the composite takes up. So the regressions see the composites
(`composites`) beside the inputs, and each target is fitted by the better, out of fold, of
three learners: the mean of the other folds, an additive spline of the inputs (hinges at
their quantiles, ridge least squares for every column at once, the penalty chosen out of
fold) and, where asked, trees
(`default_learner`). The one with the smaller out-of-fold squared error is kept, so no
target is partialled worse than by its mean, and its out-of-fold skill (1 − SSE/SST) is
reported.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np
import pandas as pd

from ._citest import default_learner
from ._model import computable

__all__ = ["Partialled", "composites", "input_history", "partial_out"]

# Knots of the additive spline: hinges at these quantiles of each standardised input.
KNOTS = (0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95)

# Ridge penalties of the additive spline, times its basis's mean eigenvalue: a few hundred
# hinges against a hundred-odd conditions overfit without one; each target keeps the penalty
# that predicts it best out of fold.
RIDGES = (1e-4, 1e-2, 1.0)

# The operators of a candidate that depend on the time history inside or before its window.
HISTORY = ("rate", "abs_rate", "window", "lag")


class Partialled(NamedTuple):
    """Targets partialled out of the inputs.

    Attributes:
        left: (n, m) each target minus its out-of-fold prediction.
        skill: (m,) each target's out-of-fold skill, 1 − SSE/SST (0: the mean's).
        learner: (m,) which learner each target kept: "mean", "spline" or "trees".
    """

    left: np.ndarray
    skill: np.ndarray
    learner: np.ndarray


def composites(table: pd.DataFrame, inputs) -> tuple[np.ndarray, list[str]]:
    """(n, k) the physical composites of the model's inputs, from their window values, and
    their names: the blade loading W·n/(ρΩ²) (up to the rotor's constants) at 1 g and at each
    load factor among the inputs (the measured n_z, the maneuver load factor), and the
    advance ratio or the airspeed where the inputs hold the other two of V, μ and Ω. Each is a
    function of the inputs that a flexible learner of the raw inputs finds only in part."""
    have = computable(inputs)
    col = lambda k: table[f"x:{k}"].to_numpy(np.float64)  # noqa: E731
    out, names = [], []
    if {"gross_weight_lb", "density_ratio", "rotor_rpm"} <= have and all(
            f"x:{k}" in table for k in ("gross_weight_lb", "density_ratio", "rotor_rpm")):
        w = col("gross_weight_lb") / np.maximum(col("density_ratio") * col("rotor_rpm") ** 2, 1e-12)
        out.append(w), names.append("loading at 1 g")
        for n in ("nz_g", "mlf"):
            if n in have and f"x:{n}" in table:
                out.append(w * col(n)), names.append(f"loading at {n}")
    if "rotor_rpm" in have and "x:rotor_rpm" in table:
        rpm = np.maximum(col("rotor_rpm"), 1e-12)
        if "airspeed_kt" in inputs and "advance_ratio" not in inputs and "x:airspeed_kt" in table:
            out.append(col("airspeed_kt") / rpm), names.append("advance ratio")
        if "advance_ratio" in inputs and "airspeed_kt" not in inputs and "x:advance_ratio" in table:
            out.append(col("advance_ratio") * rpm), names.append("airspeed")
    return (np.column_stack(out) if out else np.zeros((len(table), 0))), names


def input_history(table: pd.DataFrame, inputs) -> tuple[np.ndarray, list[str]]:
    """(n, k) the history of the model's inputs in each window and the columns' names: the
    rate, the rate's magnitude and the spread inside the window of every channel the inputs
    compute (`computable`), where the table holds them."""
    have = computable(inputs)
    names = [f"{op}:{k}" for k in sorted(have) for op in ("rate", "abs_rate", "spread") if f"{op}:{k}" in table]
    X = table[names].to_numpy(np.float64) if names else np.zeros((len(table), 0))
    keep = np.all(np.isfinite(X), axis=0) & (np.ptp(X, axis=0) > 0) if X.size else np.zeros(0, bool)
    return X[:, keep], [n for n, k in zip(names, keep) if k]


def _basis(Z: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """The additive spline's columns of Z: 1, each input and its hinges max(0, z − knot) at
    the `KNOTS` quantiles of `ref` (the training rows), inputs standardised by `ref` and held
    within its range (a fold's rows beyond the training rows' range are predicted at its
    edge, not by extrapolating the outer hinges)."""
    mu, sd = ref.mean(axis=0), ref.std(axis=0)
    sd = np.where(sd > 0, sd, 1.0)
    Zs, Rs = (np.clip(Z, ref.min(axis=0), ref.max(axis=0)) - mu) / sd, (ref - mu) / sd
    knots = np.quantile(Rs, KNOTS, axis=0)  # (K, p)
    hinges = np.maximum(Zs[:, None, :] - knots[None], 0.0).reshape(len(Z), -1)
    return np.column_stack([np.ones(len(Z)), Zs, hinges])


def _spline_oof(Y: np.ndarray, Z: np.ndarray, fold: np.ndarray) -> np.ndarray:
    """(len(RIDGES), n, m) the out-of-fold predictions of every column of Y by the additive
    spline of Z, at each ridge penalty of `RIDGES` (times the basis's mean eigenvalue): one
    eigendecomposition per fold serves them all."""
    out = np.empty((len(RIDGES),) + Y.shape)
    for k in np.unique(fold):
        test = fold == k
        B = _basis(Z[~test], Z[~test])
        s, V = np.linalg.eigh(B.T @ B)
        proj = V.T @ (B.T @ Y[~test])
        Bt = _basis(Z[test], Z[~test]) @ V
        scale = max(float(s.mean()), 1e-300)
        for r, lam in enumerate(RIDGES):
            out[r][test] = Bt @ (proj / (np.maximum(s, 0.0) + lam * scale)[:, None])
    return out


def _mean_oof(Y: np.ndarray, fold: np.ndarray) -> np.ndarray:
    out = np.empty_like(Y)
    for k in np.unique(fold):
        test = fold == k
        out[test] = Y[~test].mean(axis=0)
    return out


def _trees_oof(y: np.ndarray, Z: np.ndarray, fold: np.ndarray, learner: Callable) -> np.ndarray:
    out = np.empty_like(y)
    for k in np.unique(fold):
        test = fold == k
        out[test] = learner().fit(Z[~test], y[~test]).predict(Z[test])
    return out


def partial_out(Y, Z, fold, *, trees: bool | np.ndarray = False, learner: Callable = default_learner) -> Partialled:
    """Every column of Y partialled out of Z by the best of the mean, the additive spline and
    (where `trees`) the trees, out of fold.

    Args:
        Y: (n,) or (n, m) targets. Z: (n, p) what they are partialled out of (the inputs, their
            composites and history). fold: (n,) the fold of each row (by units).
        trees: also try `learner` (one fit per fold and column): True for every column, or a
            (m,) mask of the columns.
        learner: a factory of a scikit-learn style regressor.

    Returns:
        `Partialled` (2-D even for a 1-D Y).
    """
    Y = np.asarray(Y, np.float64)
    Y = Y[:, None] if Y.ndim == 1 else Y
    Z = np.asarray(Z, np.float64).reshape(len(Y), -1)
    mean = _mean_oof(Y, fold)
    sse = lambda P: np.sum((Y - P) ** 2, axis=0)  # noqa: E731
    sst = np.maximum(sse(mean), 1e-300)
    best, err = mean, sse(mean)
    chosen = np.full(Y.shape[1], "mean", dtype=object)
    if Z.shape[1]:
        for spline in _spline_oof(Y, Z, fold):
            e = sse(spline)
            better = e < err
            best = np.where(better[None], spline, best)
            err, chosen[better] = np.where(better, e, err), "spline"
        mask = np.broadcast_to(np.asarray(trees, bool), (Y.shape[1],))
        for j in np.flatnonzero(mask):
            p = _trees_oof(Y[:, j], Z, fold, learner)
            e = float(np.sum((Y[:, j] - p) ** 2))
            if e < err[j]:
                best[:, j], err[j], chosen[j] = p, e, "trees"
    return Partialled(Y - best, 1.0 - err / sst, chosen)
