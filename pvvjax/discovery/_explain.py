"""Which candidates explain a model's residual beyond any function of its inputs, by one
cross-fitted test at one stated level.

Every candidate of the library is tested against the model's out-of-fold residual given the
model's inputs Z (`gcm_test`'s partially linear regression, conditions as the units); the
family of tests is held at the level by Holm's step-down; the one with the smallest p-value
among those that pass is named, joins Z, and the rest are tested again given it, until
nothing passes. Candidates that passed beside it and that the data cannot tell from it (each
has nothing left given the other) are named with it as a tied set.

Two questions are kept apart. A **missing** input or response is what a candidate explains
beyond any function of Z. A **misfit** is structure that a function of Z explains: a static
candidate built only from the model's inputs (a knee, a band or a product of them) is never
tested as missing; whether the residual holds such structure at all is the capacity test's
question, and where it does, the misfit is named by the simplest form that carries it (the
static candidate of the inputs whose form alone the residual covaries with most, Holm at the
level).

The residual is partialled out of Z by the learner given (trees); the candidates, hundreds
of columns, by the mean of each window's nearest neighbours in Z, fitted once per fold for
all of them.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np
import pandas as pd
from scipy import stats

from ._citest import (
    UnitTest,
    capacity_test,
    cross_fit,
    default_learner,
    holm,
    regression_tests,
    unit_folds,
    unit_members,
)
from ._model import computable
from .candidates import Candidate, library, values

__all__ = ["Explanation", "Named", "carried_by", "explain", "neighbour_left"]

# Operators whose window value is a function of the channels' window means: built from the
# model's inputs only, such a candidate is a function of Z. A rate, a window's spread or a lag
# depends on the time history inside or before the window, which Z does not hold.
STATIC = ("input", "threshold", "product", "resonance")


class Named(NamedTuple):
    """A candidate named by `explain`.

    Attributes:
        candidate: what was named. round: 1 for the first named, and so on.
        statistic, p_value: its test in that round; adjusted_p: Holm-adjusted over the
            candidates tested in that round. theta: the residual's coefficient on it (g per
            unit of the candidate, both partialled out of the inputs; a misfit: of the
            residual on its form).
        kind: "missing" (beyond any function of the inputs) or "misfit" (a function of the
            inputs that the model did not learn).
        tied: the keys of the candidates the data cannot tell from it (each has nothing left
            at the level given the other), which the name stands for as well.
        explained: the share of the (partialled) residual's variance it explains in its round.
    """

    candidate: Candidate
    round: int
    statistic: float
    p_value: float
    adjusted_p: float
    theta: float
    kind: str = "missing"
    tied: tuple[str, ...] = ()
    explained: float = 0.0


class Explanation(NamedTuple):
    """What `explain` found.

    Attributes:
        named: the candidates named, in order (missing ones, then a misfit).
        tests: every test of every round: round, key, name, kind, statistic, p_value,
            adjusted_p, theta, left (the share of the candidate's variance left after the
            inputs; 1 for a misfit's form).
        carried: the keys of the static candidates built only from the model's inputs (not
            tested as missing).
        capacity: is the residual predictable from the inputs at all (`capacity_test`).
        level: the family-wise level of each round.
    """

    named: tuple[Named, ...]
    tests: pd.DataFrame
    carried: tuple[str, ...]
    capacity: UnitTest
    level: float


def carried_by(c: Candidate, inputs) -> bool:
    """Whether a candidate is a function of the model's inputs: a static operator (`STATIC`)
    of channels or features computable from the inputs alone (`computable`: the advance
    ratio from airspeed and rotor speed, airspeed from the advance ratio and rotor speed)."""
    return c.operator in STATIC and set(c.channels) <= computable(inputs)


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


def _given(ry, a, b, groups) -> float:
    """Two-sided p of a's coefficient in ry ≈ α·a + β·b, the variance clustered by units:
    does `a` explain anything that `b` does not."""
    member = unit_members(groups)
    g = member.shape[0]
    A = np.column_stack([a, b])
    gram = A.T @ A
    if abs(np.linalg.det(gram)) <= 1e-12 * np.prod(np.diag(gram)) or g < 3:
        return 1.0
    inv = np.linalg.inv(gram)
    coef = inv @ (A.T @ ry)
    score = member @ (A * (ry - A @ coef)[:, None])
    se = np.sqrt((inv @ (score.T @ score) @ inv)[0, 0])
    return float(2 * stats.t.sf(abs(coef[0]) / se, g - 1)) if se > 0 else 1.0


def _ties(ry, RX, best: int, passed, groups, level: float) -> list[int]:
    """Of the candidates that `passed` beside `best`, those the data cannot tell from it:
    neither explains anything at `level` given the other."""
    return [j for j in passed if j != best and _given(ry, RX[:, best], RX[:, j], groups) >= level
            and _given(ry, RX[:, j], RX[:, best], groups) >= level]


def tested_column(c: Candidate, table: pd.DataFrame, prediction=None) -> np.ndarray:
    """(n,) a candidate's column as the test sees it: its window values from `table`, a
    resonance's times the model's `prediction` (a mode magnifies the response; None: the band
    alone)."""
    v = values(c, table)
    return v * prediction if c.operator == "resonance" and prediction is not None else v


def _columns(pool, table, prediction) -> np.ndarray:
    """The candidates' columns (`tested_column`), (n, len(pool))."""
    cols = [tested_column(c, table, prediction) for c in pool]
    return np.column_stack(cols) if cols else np.zeros((len(table), 0))


def _usable(pool, X):
    keep = np.all(np.isfinite(X), axis=0) & (np.ptp(X, axis=0) > 0) if X.size else np.zeros(0, bool)
    return [c for c, k in zip(pool, keep) if k], X[:, keep]


def _share(ry, rx) -> float:
    """The share of ry's sum of squares that its regression on rx explains (r²)."""
    return float((ry @ rx) ** 2 / max(float(rx @ rx) * float(ry @ ry), 1e-300))


def _misfit(y, forms, F, groups, level, capacity) -> tuple[list[dict], Named | None]:
    """Where the capacity test finds structure the inputs explain, the simplest static form
    of the inputs that carries it: the residual on each form alone, Holm over the forms, the
    best named if it passes."""
    if capacity.p_value >= level or not forms:
        return [], None
    theta, t, p = regression_tests(y - y.mean(), F - F.mean(axis=0), groups)
    adj = holm(p)
    rows = [dict(round=0, key=c.key, name=c.name, kind="misfit", statistic=t[j], p_value=p[j], adjusted_p=adj[j],
                 theta=theta[j], left=1.0) for j, c in enumerate(forms)]
    best = int(np.argmin(p))
    if adj[best] >= level:
        return rows, None
    return rows, Named(forms[best], 0, float(t[best]), float(p[best]), float(adj[best]), float(theta[best]), "misfit",
                       (), _share(y - y.mean(), F[:, best] - F[:, best].mean()))


def explain(residual, table: pd.DataFrame, inputs, groups, *, candidates: list[Candidate] | None = None,
            responses: tuple[list[Candidate], np.ndarray] | None = None, prediction=None, level: float = 0.05,
            folds: int = 5, seed: int = 0, max_named: int = 3, neighbours: int = 30,
            learner: Callable = default_learner) -> Explanation:
    """Name the candidates that explain `residual` beyond any function of the model's inputs,
    and a misfit of those inputs where the residual holds one.

    Args:
        residual: (n,) the model's out-of-fold residual per window (measured − predicted), g.
        table: (n rows) `candidates.window_table` of the same windows.
        inputs: the model's inputs (channels or derived features of `table`'s `x:` columns).
        groups: (n,) each window's unit (condition): folds and tests are over units.
        candidates: what to test (default: `library(table, model_inputs=inputs)`).
        responses: candidates whose values the table does not hold (a lag of the model's
            prediction), with their (n, m) columns; never functions of the inputs.
        prediction: (n,) the model's prediction, g: a resonance's column is its band times
            it. None: the band alone.
        level: the family-wise error of each round (Holm).
        folds, seed: the cross-fitting's folds over units.
        max_named: stop after naming this many missing effects.
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
    forms, F = _usable([c for c, k in zip(pool, of_inputs) if k],
                       _columns([c for c, k in zip(pool, of_inputs) if k], table, prediction))
    pool, X = _usable([c for c, k in zip(pool, of_inputs) if not k],
                      _columns([c for c, k in zip(pool, of_inputs) if not k], table, prediction))
    if responses is not None and len(responses[0]):
        more, R = _usable(list(responses[0]), np.asarray(responses[1], float).reshape(len(y), -1))
        pool, X = pool + more, np.column_stack([X, R])
    named, rows = [], []
    for rnd in range(1, max_named + 1):
        if not pool:
            break
        ry = cross_fit(y, Z, fold, learner)
        RX = neighbour_left(X, Z, fold, neighbours)
        left = RX.var(axis=0) / np.maximum(X.var(axis=0), 1e-300)
        theta, t, p = regression_tests(ry, RX, groups)
        adj = holm(p)
        rows += [dict(round=rnd, key=c.key, name=c.name, kind="missing", statistic=t[j], p_value=p[j],
                      adjusted_p=adj[j], theta=theta[j], left=left[j]) for j, c in enumerate(pool)]
        best = int(np.argmin(p))
        if adj[best] >= level:
            break
        tied = _ties(ry, RX, best, np.flatnonzero(adj < level), groups, level)
        named.append(Named(pool[best], rnd, float(t[best]), float(p[best]), float(adj[best]), float(theta[best]),
                           "missing", tuple(pool[j].key for j in tied), _share(ry, RX[:, best])))
        Z = np.column_stack([Z, X[:, best]])  # the rest are tested given it
        gone = {best, *tied}
        pool, X = [c for j, c in enumerate(pool) if j not in gone], np.delete(X, sorted(gone), axis=1)
    misfit_rows, misfit = _misfit(y, forms, F, groups, level, capacity)
    tests = pd.DataFrame(rows + misfit_rows, columns=["round", "key", "name", "kind", "statistic", "p_value",
                                                      "adjusted_p", "theta", "left"])
    return Explanation(tuple(named) + ((misfit,) if misfit else ()), tests, tuple(c.key for c in forms), capacity,
                       level)
