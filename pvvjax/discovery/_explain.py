"""Which candidates explain a model's residual beyond any function of its inputs, by one
cross-fitted test at one stated level.

Two questions are kept apart, in this order. A **misfit** is structure that a function of
the model's inputs Z explains: whether the residual holds any is the capacity test's question,
and where it does, the misfit is named by the simplest static forms of the inputs that carry
it (knees, bands, products built only from the inputs; forward selection, Holm at the level
in each round: `misfits`). Their out-of-fold fit is taken off the residual first: a misfit
left in it would let any channel that follows the inputs stand in for it. A **missing** input
or response is then what a candidate explains of what is left beyond any function of Z
(`gcm_test`'s partially linear regression, conditions as the units); the family of tests is
held at the level by Holm's step-down; the one with the smallest p-value among those that
pass is named, joins Z, and the rest are tested again given it, until nothing passes.
Candidates that passed beside it and that the data cannot tell from it (each has nothing
left given the other) are named with it as a tied set. A static form of the inputs is never
tested as missing.

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

__all__ = ["Explanation", "Named", "carried_by", "explain", "misfits", "neighbour_left", "out_of_fold_linear"]

# The columns of `Explanation.tests` (one row per candidate and round).
TEST_COLUMNS = ("round", "key", "name", "kind", "statistic", "p_value", "adjusted_p", "theta", "left")

# Operators whose window value is a function of the channels' window means: built from the
# model's inputs only, such a candidate is a function of Z. A rate, a window's spread or a lag
# depends on the time history inside or before the window, which Z does not hold.
STATIC = ("input", "threshold", "product", "resonance")


class Named(NamedTuple):
    """A candidate named by `explain`.

    Attributes:
        candidate: what was named. round: 1 for the first named, and so on (the misfit's
            forms first, then the missing candidates).
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
        named: the candidates named, in order (the misfit's forms, then the missing ones).
        tests: every test of every round: round, key, name, kind ("misfit": a form tested
            given the forms named before it; "missing": a candidate beyond the inputs),
            statistic, p_value, adjusted_p, theta, left (the share of the candidate's variance
            left after the inputs; 1 for a misfit's form).
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


def _forms_of(pool, inputs, table, prediction):
    """The library split: (forms, F) the static candidates built only from the inputs and
    their columns, (rest, X) every other candidate and its columns (unusable columns dropped)."""
    of_inputs = [carried_by(c, inputs) for c in pool]
    forms = [c for c, k in zip(pool, of_inputs) if k]
    rest = [c for c, k in zip(pool, of_inputs) if not k]
    return _usable(forms, _columns(forms, table, prediction)), _usable(rest, _columns(rest, table, prediction))


def _partial(V, A):
    """V minus its least-squares projection on the columns of A (an intercept among them)."""
    return V - A @ np.linalg.lstsq(A, V, rcond=None)[0]


def _check(y, table, inputs, groups, level):
    if len(y) != len(table) or len(groups) != len(y):
        raise ValueError(f"residual ({len(y)}), table ({len(table)}) and groups ({len(groups)}) must have one row "
                         "per window")
    missing = [k for k in inputs if f"x:{k}" not in table]
    if missing:
        raise ValueError(f"inputs {missing}: not columns of the window table (x:<name>)")
    if not 0 < level < 1:
        raise ValueError(f"level = {level:g}: a probability within 0 to 1")


def misfits(residual, table: pd.DataFrame, inputs, groups, *, candidates: list[Candidate] | None = None,
            prediction=None, level: float = 0.05, folds: int = 5, seed: int = 0, max_named: int = 3,
            learner: Callable = default_learner) -> Explanation:
    """The baseline's capacity, and its misfit named by form: is `residual` predictable from
    the model's inputs at all (`capacity_test`), and if so, which static forms of the inputs
    carry it.

    Where the capacity test passes at `level`, the forms (static candidates built only from
    the inputs: knees, bands, products) are named by forward selection: each round tests
    every form for what it explains of the residual given the forms named before (the
    residual and the forms projected off those, a t over units), Holm over the forms at
    `level`; the best that passes is named; the rounds stop when none passes. The named forms
    are the misfit's simplest description, which joins the model before anything is tested as
    missing (`explain`): a misfit left in the residual would let any channel that follows the
    inputs stand in for it.

    Args: as `explain` (`candidates`: the library; only its forms of the inputs are tested).

    Returns:
        `Explanation` with the misfit's forms (kind "misfit", rounds 1, 2, ...) and their
        tests, the keys of every form, and the capacity test.
    """
    y = np.asarray(residual, float)
    groups = np.asarray(groups)
    _check(y, table, inputs, groups, level)
    Z = table[[f"x:{k}" for k in inputs]].to_numpy(float)
    capacity = capacity_test(y, Z, groups, folds, seed, learner)
    pool = candidates if candidates is not None else library(table, model_inputs=tuple(inputs))
    (forms, F), _ = _forms_of(pool, inputs, table, prediction)
    named, rows, chosen = [], [], []
    ones = np.ones((len(y), 1))
    for rnd in range(1, max_named + 1):
        if capacity.p_value >= level or len(chosen) == len(forms):
            break
        A = np.column_stack([ones, F[:, chosen]])
        ry, RF = _partial(y, A), _partial(F, A)
        theta, t, p = regression_tests(ry, RF, groups)
        p[chosen] = 1.0
        adj = holm(p)
        rows += [dict(round=rnd, key=c.key, name=c.name, kind="misfit", statistic=t[j], p_value=p[j],
                      adjusted_p=adj[j], theta=theta[j], left=1.0) for j, c in enumerate(forms) if j not in chosen]
        best = int(np.argmin(p))
        if adj[best] >= level:
            break
        chosen.append(best)
        named.append(Named(forms[best], rnd, float(t[best]), float(p[best]), float(adj[best]), float(theta[best]),
                           "misfit", (), _share(ry, RF[:, best])))
    return Explanation(tuple(named), pd.DataFrame(rows, columns=list(TEST_COLUMNS)), tuple(c.key for c in forms),
                       capacity, level)


def out_of_fold_linear(A, target, fit, fold) -> np.ndarray:
    """(n,) the least-squares fit of `target` on [1, A] ((n, k) columns), each fold's rows
    predicted by the coefficients fitted on the other folds' rows where `fit` holds: a
    parametric term added to a model without its own data leaking into its correction."""
    A = np.column_stack([np.ones(len(target)), np.asarray(A, float).reshape(len(target), -1)])
    out = np.zeros(len(target))
    for k in np.unique(fold):
        rows = fold == k
        out[rows] = A[rows] @ np.linalg.lstsq(A[fit & ~rows], target[fit & ~rows], rcond=None)[0]
    return out


def _missing_rounds(y, Z, pool, X, groups, fold, rounds, level, neighbours, learner) -> tuple[list, list]:
    """`explain`'s rounds of missing candidates: (named, test rows). Each round partials the
    residual (trees) and the candidates X (neighbours) out of Z, names the best that passes
    Holm at `level` with its tied set, and adds it to Z (a lag with every lag of the grid)."""
    named, rows = [], []
    for rnd in rounds:
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
        joins = {best} | ({j for j, c in enumerate(pool) if c.operator == "lag"} if pool[best].operator == "lag"
                          else set())
        Z = np.column_stack([Z, X[:, sorted(joins)]])  # the rest are tested given it
        gone = joins | set(tied)
        pool, X = [c for j, c in enumerate(pool) if j not in gone], np.delete(X, sorted(gone), axis=1)
    return named, rows


def explain(residual, table: pd.DataFrame, inputs, groups, *, candidates: list[Candidate] | None = None,
            responses: tuple[list[Candidate], np.ndarray] | None = None, prediction=None, level: float = 0.05,
            folds: int = 5, seed: int = 0, max_named: int = 3, neighbours: int = 30,
            learner: Callable = default_learner, given: Explanation | None = None) -> Explanation:
    """Name the misfit of the model's inputs where the residual holds one (`misfits`), then
    the candidates that explain what is left beyond any function of those inputs.

    The misfit comes first: its forms' out-of-fold fit (by the units' folds) is taken off the
    residual (and added to `prediction`) before any candidate is tested as missing. A named
    lag joins the inputs with every lag of the grid (`responses` of operator "lag"), so the
    rest is tested given any first-order lag, not only the grid point that was named: a lag
    between grid points, or the lag of a part of the response the model misses, would leave
    rates of the inputs standing in for it.

    Args:
        residual: (n,) the model's out-of-fold residual per window (measured − predicted), g.
        table: (n rows) `candidates.window_table` of the same windows.
        inputs: the model's inputs (channels or derived features of `table`'s `x:` columns).
        groups: (n,) each window's unit (condition): folds and tests are over units.
        candidates: what to test (default: `library(table, model_inputs=inputs)`).
        responses: candidates whose values the table does not hold (a lag of the model's
            prediction), with their (n, m) columns; never functions of the inputs. They are
            taken as given: built from the prediction before the misfit's correction (pass
            `given` to build them from the corrected one).
        prediction: (n,) the model's prediction, g: a resonance's column is its band times
            it. None: the band alone.
        level: the family-wise error of each round (Holm).
        folds, seed: the cross-fitting's folds over units.
        max_named: stop after naming this many of each kind (misfit forms, missing effects).
        neighbours: the nearest neighbours that partial the candidates out of the inputs.
        learner: the nuisance regression of the residual (`default_learner`).
        given: the `misfits` of this residual, already taken off it (`residual` and
            `prediction` corrected by the caller, e.g. on windows beyond these): only the
            missing candidates are tested.

    Returns:
        `Explanation`: the misfit's forms, then the missing candidates, rounds numbered on.
    """
    y = np.asarray(residual, float)
    groups = np.asarray(groups)
    _check(y, table, inputs, groups, level)
    pool = candidates if candidates is not None else library(table, model_inputs=tuple(inputs))
    fold = unit_folds(groups, folds, seed)
    prediction = None if prediction is None else np.asarray(prediction, float)
    if given is None:
        given = misfits(y, table, inputs, groups, candidates=pool, prediction=prediction, level=level, folds=folds,
                        seed=seed, max_named=max_named, learner=learner)
        if given.named:
            shift = out_of_fold_linear(_columns([n.candidate for n in given.named], table, prediction), y,
                                       np.ones(len(y), bool), fold)
            y = y - shift
            prediction = None if prediction is None else prediction + shift
    Z = table[[f"x:{k}" for k in inputs]].to_numpy(float)
    _, (pool, X) = _forms_of(pool, inputs, table, prediction)
    if responses is not None and len(responses[0]):
        more, R = _usable(list(responses[0]), np.asarray(responses[1], float).reshape(len(y), -1))
        pool, X = pool + more, np.column_stack([X, R])
    first = max([n.round for n in given.named], default=0) + 1
    named, rows = _missing_rounds(y, Z, pool, X, groups, fold, range(first, first + max_named), level, neighbours,
                                  learner)
    frames = [f for f in (given.tests, pd.DataFrame(rows, columns=list(TEST_COLUMNS))) if len(f)]
    tests = pd.concat(frames, ignore_index=True) if frames else given.tests
    return Explanation(given.named + tuple(named), tests, given.carried, given.capacity, level)
