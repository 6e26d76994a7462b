"""Which candidates explain a model's residual beyond any function of its inputs, by one
cross-fitted test at one stated level.

Every candidate of the library is tested against the model's out-of-fold residual given the
model's inputs Z (`gcm_test`'s partially linear regression, conditions as the units); the
family of tests is held at the level by Holm's step-down; the one with the smallest p-value
among those that pass is named, joins Z, and the rest are tested again given it, until
nothing passes. Candidates built only from the model's own inputs (a knee or a band of one
of them) are functions of Z: they are never tested as missing, and whether the residual
holds such structure at all is the capacity test's question (a misfit of the inputs).

The residual is partialled out of Z by the learner given (trees); the candidates, hundreds
of columns, by the mean of each window's nearest neighbours in Z, fitted once per fold for
all of them.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np
import pandas as pd

from ._citest import UnitTest, capacity_test, cross_fit, default_learner, holm, regression_tests, unit_folds
from ._model import _DERIVED_FROM
from .candidates import Candidate, library, values

__all__ = ["Explanation", "Named", "carried_by", "explain", "neighbour_left"]


class Named(NamedTuple):
    """A candidate named as missing from the model.

    Attributes:
        candidate: what was named. round: 1 for the first named, and so on.
        statistic, p_value: its test in that round; adjusted_p: Holm-adjusted over the
            candidates tested in that round. theta: the residual's coefficient on it (g per
            unit of the candidate, both partialled out of the inputs).
    """

    candidate: Candidate
    round: int
    statistic: float
    p_value: float
    adjusted_p: float
    theta: float


class Explanation(NamedTuple):
    """What `explain` found.

    Attributes:
        named: the candidates named, in order.
        tests: every test of every round: round, key, name, statistic, p_value, adjusted_p,
            theta, left (the share of the candidate's variance left after the inputs).
        carried: the keys of candidates built only from the model's inputs (not tested).
        capacity: is the residual predictable from the inputs at all (`capacity_test`).
        level: the family-wise level of each round.
    """

    named: tuple[Named, ...]
    tests: pd.DataFrame
    carried: tuple[str, ...]
    capacity: UnitTest
    level: float


def _inputs_of(names) -> set[str]:
    out = set()
    for n in names:
        out |= set(_DERIVED_FROM.get(n, (n,)))
    return out


def carried_by(c: Candidate, inputs) -> bool:
    """Whether a candidate is built only from the model's inputs (or features computed
    from them only)."""
    have = _inputs_of(inputs) | set(inputs)
    return all(ch in have or set(_DERIVED_FROM.get(ch, (None,))) <= have for ch in c.channels)


def neighbour_left(X, Z, fold, neighbours: int = 30) -> np.ndarray:
    """(n, m) X minus its out-of-fold mean over each row's `neighbours` nearest rows in Z
    (standardised; the neighbours drawn from the other folds): every column partialled out of
    Z at once, the candidates' nuisance regression."""
    from sklearn.neighbors import KNeighborsRegressor

    scale = Z.std(axis=0)
    Zs = Z / np.where(scale > 0, scale, 1.0)
    out = np.empty_like(X)
    for k in np.unique(fold):
        test = fold == k
        model = KNeighborsRegressor(n_neighbors=min(neighbours, int((~test).sum()))).fit(Zs[~test], X[~test])
        out[test] = X[test] - model.predict(Zs[test])
    return out


def explain(residual, table: pd.DataFrame, inputs, groups, *, candidates: list[Candidate] | None = None,
            level: float = 0.05, folds: int = 5, seed: int = 0, max_named: int = 3, neighbours: int = 30,
            learner: Callable = default_learner) -> Explanation:
    """Name the candidates that explain `residual` beyond any function of the model's inputs.

    Args:
        residual: (n,) the model's out-of-fold residual per window (measured − predicted), g.
        table: (n rows) `candidates.window_table` of the same windows.
        inputs: the model's inputs (channels or derived features of `table`'s `x:` columns).
        groups: (n,) each window's unit (condition): folds and tests are over units.
        candidates: what to test (default: `library(table, model_inputs=inputs)`).
        level: the family-wise error of each round (Holm).
        folds, seed: the cross-fitting's folds over units.
        max_named: stop after naming this many.
        neighbours: the nearest neighbours that partial the candidates out of the inputs.
        learner: the nuisance regression of the residual (`default_learner`).

    Returns:
        `Explanation`.
    """
    y = np.asarray(residual, float)
    groups = np.asarray(groups)
    if len(y) != len(table) or len(groups) != len(y):
        raise ValueError(f"residual ({len(y)}), table ({len(table)}) and groups ({len(groups)}) must have one row "
                         "per window")
    missing = [k for k in inputs if f"x:{k}" not in table]
    if missing:
        raise ValueError(f"inputs {missing}: not columns of the window table (x:<name>)")
    if not 0 < level < 1:
        raise ValueError(f"level = {level:g}: a probability within 0 to 1")
    Z = table[[f"x:{k}" for k in inputs]].to_numpy(float)
    fold = unit_folds(groups, folds, seed)
    capacity = capacity_test(y, Z, groups, folds, seed, learner)
    pool = candidates if candidates is not None else library(table, model_inputs=tuple(inputs))
    of_inputs = [carried_by(c, inputs) for c in pool]
    carried = tuple(c.key for c, k in zip(pool, of_inputs) if k)
    pool = [c for c, k in zip(pool, of_inputs) if not k]
    X = np.column_stack([values(c, table) for c in pool]) if pool else np.zeros((len(y), 0))
    keep = np.ptp(X, axis=0) > 0 if X.size else np.zeros(0, bool)
    pool, X = [c for c, k in zip(pool, keep) if k], X[:, keep]
    named, rows = [], []
    for rnd in range(1, max_named + 1):
        if not pool:
            break
        ry = cross_fit(y, Z, fold, learner)
        RX = neighbour_left(X, Z, fold, neighbours)
        left = RX.var(axis=0) / np.maximum(X.var(axis=0), 1e-300)
        theta, t, p = regression_tests(ry, RX, groups)
        adj = holm(p)
        rows += [dict(round=rnd, key=c.key, name=c.name, statistic=t[j], p_value=p[j], adjusted_p=adj[j],
                      theta=theta[j], left=left[j]) for j, c in enumerate(pool)]
        best = int(np.argmin(p))
        if adj[best] >= level:
            break
        named.append(Named(pool[best], rnd, float(t[best]), float(p[best]), float(adj[best]), float(theta[best])))
        Z = np.column_stack([Z, X[:, best]])  # the rest are tested given it
        pool, X = pool[:best] + pool[best + 1:], np.delete(X, best, axis=1)
    tests = pd.DataFrame(rows, columns=["round", "key", "name", "statistic", "p_value", "adjusted_p", "theta", "left"])
    return Explanation(tuple(named), tests, carried, capacity, level)
