"""Which candidates explain a model's residual beyond any function of its inputs, by one
cross-fitted test at one stated level, for each of three kinds in turn.

1. A **misfit of the inputs** is structure that a function of the inputs' window values Z
   explains (Z holds the inputs and their physical composites: the blade loading at the
   load factors they hold, the advance ratio). Whether the residual holds any is the capacity
   test's question; where it does, the misfit is named by the simplest static forms of the
   inputs that carry it (knees, bands, products; forward selection, Holm at the level in
   each round: `misfits`), and their out-of-fold fit is taken off the residual first.
2. A **misfit of the inputs' history** is what the history of the inputs explains beyond Z:
   their rates, their spreads inside the window, lags of the model's prediction. It is a
   response, or the window-averaging of a state that moves, that the baseline lacks, not a
   missing channel, and it is named by its form (a lag's τ, a rate, a spread).
3. A **missing** channel, or its history, is what a candidate explains of what is left
   beyond both: Z and the whole history of the inputs.

Within a kind, every candidate is tested by `gcm_test`'s partially linear regression
(conditions as the units) against the residual, both partialled out of what is held fixed;
the one with the smallest p-value is named where it passes Holm's first step at the level
over the round's family, joins what is held fixed, and the rest are tested again given it,
until nothing passes. Candidates that passed beside it and that the data cannot tell from
it (each has nothing left given the other) are named with it as a tied set.

The nuisance regressions (`_nuisance.partial_out`) keep, per target, the best out of fold
of the mean, an additive spline of what is held fixed and (for the residual and for the
candidates that may be named) gradient-boosted trees: every candidate is screened with the
spline, and only one the trees confirmed is named. Each round's learners and their
out-of-fold skill are reported (`Explanation.nuisance`).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np
import pandas as pd
from scipy import stats

from ._citest import UnitTest, capacity_test, default_learner, holm, regression_tests, unit_folds, unit_members
from ._model import computable
from ._nuisance import HISTORY, Partialled, composites, input_history, partial_out
from .candidates import Candidate, columns_of, library, values

__all__ = ["Explanation", "Named", "carried_by", "explain", "misfits", "of_history", "out_of_fold_linear", "shadow",
           "static_inputs"]

# The columns of `Explanation.tests` (one row per candidate and round).
TEST_COLUMNS = ("round", "key", "name", "kind", "statistic", "p_value", "adjusted_p", "theta", "left", "learner",
                "skill")

# The columns of `Explanation.nuisance` (one row per round of the history and missing kinds).
NUISANCE_COLUMNS = ("round", "kind", "residual_learner", "residual_skill", "candidates_median_skill",
                    "candidates_min_skill")

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
        kind: "misfit" (a function of the inputs' window values that the model did not
            learn), "history" (a form of the inputs' history: a rate, a spread, a lag of the
            prediction) or "missing" (beyond both).
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
        named: the candidates named, in order (the misfit's forms, the history's, then the
            missing ones).
        tests: every test of every round: round, key, name, kind ("misfit": a form tested
            given the forms named before it; "history": a form of the inputs' history beyond
            their window values; "missing": a candidate beyond both), statistic, p_value,
            adjusted_p (Holm over the round; a named candidate's is its p times the round's
            family), theta, left (the share of the candidate's variance left after what is
            held fixed; 1 for a misfit's form), learner and skill (which learner partialled
            it, and its out-of-fold skill, 1 − SSE/SST).
        carried: the keys of the static candidates built only from the model's inputs (not
            tested as missing).
        capacity: is the residual predictable from the inputs at all (`capacity_test`).
        level: the family-wise level of each round.
        nuisance: per round of the history and missing kinds, the residual's learner and its
            out-of-fold skill, and the candidates' median and smallest skill
            (`NUISANCE_COLUMNS`).
        with_misfit: the keys of the candidates the inputs nearly determine that passed the
            screen but explain nothing once their shadow (the candidate as the inputs predict
            it) is held fixed: the data cannot tell them from a misfit of the inputs, so they
            are not named as missing (tied with the misfit).
    """

    named: tuple[Named, ...]
    tests: pd.DataFrame
    carried: tuple[str, ...]
    capacity: UnitTest
    level: float
    nuisance: pd.DataFrame | None = None
    with_misfit: tuple[str, ...] = ()


def static_inputs(table: pd.DataFrame, inputs) -> np.ndarray:
    """(n, p) what the test holds fixed as the model's inputs: their window values and their
    physical composites (`composites`: the blade loading at the load factors they hold, the
    advance ratio or airspeed), which the nuisance regressions would otherwise learn only in
    part."""
    comp, _ = composites(table, inputs)
    return np.column_stack([table[[f"x:{k}" for k in inputs]].to_numpy(float), comp])


def of_history(c: Candidate, inputs) -> bool:
    """Whether a candidate is a form of the inputs' history: a rate, a rate's magnitude, a
    spread inside the window of channels the inputs compute, or a lag of the model's
    prediction (a response, or the window-averaging, that the baseline lacks)."""
    return c.operator in HISTORY and set(c.channels) <= computable(inputs)


def carried_by(c: Candidate, inputs) -> bool:
    """Whether a candidate is a function of the model's inputs: a static operator (`STATIC`)
    of channels or features computable from the inputs alone (`computable`: the advance
    ratio from airspeed and rotor speed, airspeed from the advance ratio and rotor speed)."""
    return c.operator in STATIC and set(c.channels) <= computable(inputs)


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
    capacity = capacity_test(y, static_inputs(table, inputs), groups, folds, seed, learner)
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


# Candidates re-partialled by trees in a round, at most: the smallest screened p-values first,
# until the smallest is one the trees gave (only a confirmed candidate is named), and only
# those whose screened p-value times the round's family is below 1.
CONFIRM = 4


def shadow(c: Candidate, table: pd.DataFrame, Z, fold, prediction=None) -> np.ndarray | None:
    """(n,) a candidate's shadow in what is held fixed: the candidate computed from its
    channels' columns as Z predicts them out of fold (`partial_out`), through its own operator
    (a knee of the shaft power the inputs predict). It is a function of Z alone, with the
    candidate's own shape: held fixed beside Z, it lets the residual's regression take the part
    of a misfit that the candidate would carry only because its channel follows the inputs.
    None for a candidate without channels (a lag of the prediction)."""
    cols = columns_of(c)
    if not c.channels or not all(k in table for k in cols):
        return None
    raw = table[cols].to_numpy(float)
    hat = pd.DataFrame(raw - partial_out(raw, Z, fold).left, columns=cols)
    return tested_column(c, hat, prediction)


def _round(y, Z, X, groups, fold, learner, pool=None, table=None, prediction=None):
    """One round's tests: the residual partialled out of Z by the best learner (trees
    among them), the candidates X screened by the mean or the additive spline, and the
    smallest p-values confirmed (`CONFIRM` at most): the candidate and the residual both
    partialled, trees tried too, out of Z and the candidate's `shadow` (where `pool` and
    `table` give it). Returns ry, RX, (theta, t, p), the candidates' `Partialled`, the
    residual's, the confirmed mask, the screen's columns and its p-values."""
    res = partial_out(y, Z, fold, trees=True, learner=learner)
    ry = res.left[:, 0]
    screen = partial_out(X, Z, fold)
    RX, skill, chosen = screen.left.copy(), screen.skill.copy(), screen.learner.copy()
    theta, t, p = regression_tests(ry, RX, groups)
    screened_p = p.copy()
    confirmed = np.zeros(len(p), bool)
    for _ in range(min(CONFIRM, len(p))):
        best = int(np.argmin(np.where(confirmed, np.inf, p)))
        if (confirmed.any() and p[best] >= p[confirmed].min()) or p[best] * len(p) >= 1.0:
            break  # a candidate the screen puts beyond any level is not worth the trees
        s = None if pool is None or table is None else shadow(pool[best], table, Z, fold, prediction)
        Zj = Z if s is None else np.column_stack([Z, s])
        ryj = ry if s is None else partial_out(y, Zj, fold, trees=True, learner=learner).left[:, 0]
        one = partial_out(X[:, best], Zj, fold, trees=True, learner=learner)
        RX[:, best], skill[best], chosen[best] = one.left[:, 0], one.skill[0], one.learner[0]
        th, tt, pp = regression_tests(ryj, RX[:, [best]], groups)
        theta[best], t[best], p[best] = th[0], tt[0], pp[0]
        confirmed[best] = True
    return ry, RX, (theta, t, p), Partialled(RX, skill, chosen), res, confirmed, screen.left, screened_p


def _kind_rounds(y, Z, pool, X, groups, fold, rounds, level, kind, learner, table=None,
                 prediction=None) -> tuple[list, list, list, np.ndarray, list]:
    """`explain`'s rounds of one kind ("history" or "missing"): (named, test rows, nuisance
    rows, Z with the named columns). Each round partials the residual and the candidates X
    out of Z (`_round`), names the confirmed candidate with the smallest p where it passes
    Holm's first step at `level` over the round's family (p · m), with its tied set, and adds
    it to Z (a lag with every lag of the grid). Also returns the keys of the candidates that
    passed the screen but not once their shadow was held fixed (tied with the misfit)."""
    named, rows, nuisance, with_misfit = [], [], [], []
    for rnd in rounds:
        if not pool:
            break
        ry, RX, (theta, t, p), part, res, confirmed, screened, screened_p = _round(y, Z, X, groups, fold, learner,
                                                                                 pool, table, prediction)
        m = len(p)
        with_misfit += [pool[j].key for j in np.flatnonzero(confirmed & (screened_p * m < level) & (p * m >= level))]
        left = RX.var(axis=0) / np.maximum(X.var(axis=0), 1e-300)
        adj = holm(p)
        rows += [dict(round=rnd, key=c.key, name=c.name, kind=kind, statistic=t[j], p_value=p[j],
                      adjusted_p=adj[j], theta=theta[j], left=left[j], learner=part.learner[j], skill=part.skill[j])
                 for j, c in enumerate(pool)]
        nuisance.append(dict(round=rnd, kind=kind, residual_learner=res.learner[0], residual_skill=res.skill[0],
                             candidates_median_skill=float(np.median(part.skill)),
                             candidates_min_skill=float(np.min(part.skill))))
        if not confirmed.any():
            break
        best = int(np.argmin(np.where(confirmed, p, np.inf)))
        decision = min(1.0, p[best] * m)
        if decision >= level:
            break
        # Ties are told apart on one learner's columns (the screen's): two learners' fits of
        # one candidate differ by more than a stand-in differs from it.
        tied = _ties(ry, screened, best, np.flatnonzero(adj < level), groups, level)
        named.append(Named(pool[best], rnd, float(t[best]), float(p[best]), float(decision), float(theta[best]),
                           kind, tuple(pool[j].key for j in tied), _share(ry, RX[:, best])))
        joins = {best} | ({j for j, c in enumerate(pool) if c.operator == "lag"} if pool[best].operator == "lag"
                          else set())
        Z = np.column_stack([Z, X[:, sorted(joins)]])  # the rest are tested given it
        gone = joins | set(tied)
        pool, X = [c for j, c in enumerate(pool) if j not in gone], np.delete(X, sorted(gone), axis=1)
    return named, rows, nuisance, Z, with_misfit


def explain(residual, table: pd.DataFrame, inputs, groups, *, candidates: list[Candidate] | None = None,
            responses: tuple[list[Candidate], np.ndarray] | None = None, prediction=None, level: float = 0.05,
            folds: int = 5, seed: int = 0, max_named: int = 3,
            learner: Callable = default_learner, given: Explanation | None = None) -> Explanation:
    """Name the misfit of the model's inputs where the residual holds one (`misfits`), then
    the forms of the inputs' history that explain what is left beyond their window values,
    then the candidates that explain what is left beyond both (the module docstring).

    The misfit comes first: its forms' out-of-fold fit (by the units' folds) is taken off the
    residual (and added to `prediction`) before anything else is tested. A named
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
        max_named: stop after naming this many of each kind (misfit forms, history forms,
            missing effects).
        learner: the flexible learner among the nuisance regressions (`default_learner`).
        given: the `misfits` of this residual, already taken off it (`residual` and
            `prediction` corrected by the caller, e.g. on windows beyond these): only the
            history and missing candidates are tested.

    Returns:
        `Explanation`: the misfit's forms, the history's, then the missing candidates,
        rounds numbered on.
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
    Z = static_inputs(table, inputs)
    _, (pool, X) = _forms_of(pool, inputs, table, prediction)
    if responses is not None and len(responses[0]):
        more, R = _usable(list(responses[0]), np.asarray(responses[1], float).reshape(len(y), -1))
        pool, X = pool + more, np.column_stack([X, R])
    past = np.array([of_history(c, inputs) for c in pool], bool)
    hist, H = [c for c, k in zip(pool, past) if k], X[:, past]
    rest, XR = [c for c, k in zip(pool, ~past) if k], X[:, ~past]
    first = max([n.round for n in given.named], default=0) + 1
    named_h, rows_h, nuis_h, Zh, tied_h = _kind_rounds(y, Z, hist, H, groups, fold, range(first, first + max_named),
                                                       level, "history", learner, table, prediction)
    first = max([r["round"] for r in rows_h], default=first - 1) + 1
    # What is missing is tested beyond both: the inputs, their composites, the history forms
    # named and the inputs' history in the window (the lags of the prediction, a dozen columns
    # of one series, join only where named: as a block they cost the residual's learner more
    # than they hold).
    beyond = np.column_stack([Zh, input_history(table, inputs)[0]])
    named_m, rows_m, nuis_m, _, tied_m = _kind_rounds(y, beyond, rest, XR, groups, fold,
                                                     range(first, first + max_named), level, "missing", learner,
                                                     table, prediction)
    frames = [f for f in (given.tests, pd.DataFrame(rows_h + rows_m, columns=list(TEST_COLUMNS))) if len(f)]
    tests = pd.concat(frames, ignore_index=True) if frames else given.tests
    return Explanation(given.named + tuple(named_h) + tuple(named_m), tests, given.carried, given.capacity, level,
                       pd.DataFrame(nuis_h + nuis_m, columns=list(NUISANCE_COLUMNS)), tuple(tied_h + tied_m))
