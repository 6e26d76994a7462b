"""Cross-fitted conditional-independence tests with records as the units.

Does a candidate x explain the residual y beyond any function of the model's inputs Z? Both
are regressed on Z by a flexible learner, out of fold with the folds drawn over units
(conditions: the windows of one are not independent), and what is left of y is regressed on
what is left of x: double machine learning's partially linear model (Chernozhukov et al.
2018), whose score at θ = 0 is the generalised covariance measure (Shah & Peters 2020). Its
t takes a cluster-robust standard error with the units as clusters, evaluated at the fitted
coefficient (the units' jackknife), so an effect carried by a few conditions is not hidden
by its own spread over them (the units' sums of products at θ = 0 would put the signal into
the variance), and a unit that holds much of a candidate's spread does not make it reject
more often than its level. A
candidate that is a function of Z has nothing left after the partialling-out, so it is never
taken for a missing input; whether the residual holds structure that Z itself explains (a
misfit of the model's inputs) is a test of its own (`capacity_test`).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np
from scipy import sparse, stats

__all__ = ["UnitTest", "capacity_test", "cross_fit", "default_learner", "gcm_test", "holm", "regression_tests",
           "unit_folds"]


class UnitTest(NamedTuple):
    """A test on units.

    Attributes:
        statistic: a t with `units` − 1 degrees of freedom.
        p_value: two-sided for `gcm_test`, one-sided (skill above none) for `capacity_test`.
        units: how many units (conditions) entered.
        estimate: `gcm_test`: the coefficient θ of the residual left on the candidate left
            (g per unit of the candidate: 1 where the candidate is exactly what the model
            lacks); `capacity_test`: the squared error removed per unit, g².
    """

    statistic: float
    p_value: float
    units: int
    estimate: float


def default_learner():
    """The nuisance regression: gradient-boosted trees (scikit-learn's histogram GBM),
    flexible enough for knees, bands and products of the inputs and fast on 10⁴–10⁵ rows."""
    from sklearn.ensemble import HistGradientBoostingRegressor

    return HistGradientBoostingRegressor(max_iter=200, learning_rate=0.1, max_leaf_nodes=15, min_samples_leaf=40,
                                         early_stopping=False, random_state=0)


def unit_folds(groups, folds: int = 5, seed: int = 0) -> np.ndarray:
    """(n,) the fold of each row: the units (`groups`) dealt at random into `folds` folds
    of about equal count, every row of a unit in its unit's fold."""
    units, inverse = np.unique(np.asarray(groups), return_inverse=True)
    if len(units) < folds:
        raise ValueError(f"{len(units)} units for {folds} folds: need at least one unit per fold")
    deal = np.empty(len(units), int)
    deal[np.random.default_rng(seed).permutation(len(units))] = np.arange(len(units)) % folds
    return deal[inverse]


def cross_fit(target, Z, fold: np.ndarray, learner: Callable = default_learner) -> np.ndarray:
    """(n,) `target` minus its out-of-fold regression on `Z` ((n, p)): each fold predicted
    by a learner fitted on the other folds."""
    target = np.asarray(target, float)
    Z = np.asarray(Z, float).reshape(len(target), -1)
    out = np.empty_like(target)
    for k in np.unique(fold):
        test = fold == k
        model = learner().fit(Z[~test], target[~test])
        out[test] = target[test] - model.predict(Z[test])
    return out


def _t_on_units(scores, groups) -> UnitTest:
    """One-sided t (above 0) of the units' sums of `scores`."""
    units, inverse = np.unique(np.asarray(groups), return_inverse=True)
    s = np.bincount(inverse, weights=scores, minlength=len(units))
    g = len(units)
    sd = s.std(ddof=1)
    t = float(s.mean() / (sd / np.sqrt(g))) if sd > 0 else 0.0
    return UnitTest(t, float(stats.t.sf(t, g - 1)), g, float(s.mean()))


def unit_members(groups) -> sparse.csr_matrix:
    """(G, n) the membership of each row in its unit (`groups`: G distinct units): a product
    with it sums rows' scores per unit."""
    units, inverse = np.unique(np.asarray(groups), return_inverse=True)
    n = len(inverse)
    return sparse.csr_matrix((np.ones(n), (inverse, np.arange(n))), shape=(len(units), n))


def regression_tests(ry, RX, groups) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per column of RX ((n, m) candidates left after the inputs): θ of ry = θ·rx, its t and
    two-sided p on G − 1 degrees of freedom (G units). The variance is the units' jackknife
    (each unit's score over 1 − its leverage, the share of Σ rx² it holds): a unit that
    carries much of a candidate's spread would make the plain cluster-robust variance too
    small, and the test reject more often than its level."""
    RX = np.asarray(RX, float).reshape(len(ry), -1)
    member = unit_members(groups)
    g = member.shape[0]
    if g < 2:
        m = RX.shape[1]
        return np.zeros(m), np.zeros(m), np.ones(m)
    sxx = np.sum(RX**2, axis=0)
    safe = np.where(sxx > 0, sxx, 1.0)
    theta = np.where(sxx > 0, ry @ RX / safe, 0.0)
    score = member @ ((ry[:, None] - RX * theta) * RX)
    leverage = np.minimum(member @ RX**2 / safe, 1.0 - 1e-9)
    se = np.sqrt(np.sum((score / (1.0 - leverage)) ** 2, axis=0)) / safe
    t = np.where(se > 0, theta / np.where(se > 0, se, 1.0), 0.0)
    return theta, t, 2 * stats.t.sf(np.abs(t), g - 1)


def _regression_t(ry, rx, groups) -> UnitTest:
    """`regression_tests` of one candidate, as a `UnitTest`."""
    theta, t, p = regression_tests(ry, np.asarray(rx, float)[:, None], groups)
    return UnitTest(float(t[0]), float(p[0]), len(np.unique(np.asarray(groups))), float(theta[0]))


def gcm_test(residual, candidate, groups, Z=None, folds: int = 5, seed: int = 0, learner: Callable = default_learner,
             residual_left: np.ndarray | None = None) -> UnitTest:
    """Does `candidate` explain `residual` beyond any function of `Z`?

    Args:
        residual: (n,) the model's out-of-fold residual per window (measured − predicted), g.
        candidate: (n,) the candidate's value per window.
        groups: (n,) the unit of each window (condition): folds and the test are over units.
        Z: (n, p) the model's inputs per window; None: no partialling-out (is the residual
            correlated with the candidate at all: the test of a misfit's form).
        folds, seed: the cross-fitting's folds, dealt over units by `seed`.
        learner: a factory of a scikit-learn style regressor (fit, predict).
        residual_left: the residual already partialled on `Z` with the same folds
            (`cross_fit`), when several candidates are tested against one residual.

    Returns:
        `UnitTest`, two-sided: θ of (residual left) on (candidate left) and its t.
    """
    y, x = np.asarray(residual, float), np.asarray(candidate, float)
    if Z is None:
        ry, rx = y - y.mean(), x - x.mean()
    else:
        fold = unit_folds(groups, folds, seed)
        ry = cross_fit(y, Z, fold, learner) if residual_left is None else np.asarray(residual_left, float)
        rx = cross_fit(x, Z, fold, learner)
    return _regression_t(ry, rx, groups)


def capacity_test(residual, Z, groups, folds: int = 5, seed: int = 0, learner: Callable = default_learner) -> UnitTest:
    """Is the model's out-of-fold residual predictable from its own inputs `Z` at all?

    The residual is regressed on `Z` out of fold; each unit scores the squared error it
    removes (Σ residual² − Σ (residual − prediction)² over its windows). A model that has
    learned what its inputs carry leaves a residual no learner predicts out of fold, and
    the units' scores are at most 0 on average; one-sided t on units.
    """
    y = np.asarray(residual, float)
    left = cross_fit(y, Z, unit_folds(groups, folds, seed), learner)
    return _t_on_units(y**2 - left**2, groups)


def holm(p_values) -> np.ndarray:
    """Holm's step-down adjustment: family-wise error at the level the adjusted p-values
    are compared with, over any dependence between the tests."""
    p = np.asarray(p_values, float)
    order = np.argsort(p)
    adjusted = np.minimum(1.0, np.maximum.accumulate(p[order] * (len(p) - np.arange(len(p)))))
    out = np.empty_like(p)
    out[order] = adjusted
    return out
