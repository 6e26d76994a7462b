"""Sparse, cross-validated selection of candidate effects that explain a residual, with a
permutation test of significance (the "explain" step of the discovery workflow).

Forward selection: at each step every remaining candidate is tried beside the ones already
chosen in a linear model of the residual; the score is the squared error on held-out
conditions (k-fold by condition, never by window: windows of one condition are strongly
correlated). The best candidate is kept if it lowers the held-out error by more than
`min_gain` (relative) and if that gain is significant: the candidates are permuted
*between conditions* (each condition's block of windows gets another condition's
candidate values, so within-condition correlation is kept), and the best gain of *any*
candidate is recomputed, so that picking the best of K is part of the null; the p-value is
the share of permutations that do as well. A residual the model already explains
therefore yields no effect.

Plain NumPy: every candidate is scored at once per fold (`_scores`), so a permutation
costs a few (windows × candidates) products.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Selected", "cv_sse", "equivalent", "forward_select", "gain", "gains"]


class Selected(NamedTuple):
    """One selected candidate.

    Attributes:
        index: column of the candidate matrix.
        gain: relative drop of the held-out squared error when it was added.
        explained_fraction: 1 − held-out SSE with the selection so far / without any.
        p_value: permutation p-value of the gain.
        alternatives: ((column, gain), ...) of the five next best candidates at the same
            step; those within the permutation spread explain the residual about as well.
        equivalents: ((column, gain), ...) of the candidates the selection cannot tell from
            the best (`equivalent`, within `parsimony` standard errors; `index` first), simplest
            first, then by gain.
        source: "selection" (this module); "probe": a rotor-speed band that discovery's
            resonance probe proposed, with no p-value or explained fraction of the selection's
            (NaN; its retraining gives them); or "rival": a runner-up that discovery retrains
            beside a weak name (`discovery._confirm._rival`), with the gain of its column and
            the p-value of the step it ran up in; or "source": a candidate of a channel that a
            derived input hides (`discovery._propose._source_tries`), with its column's gain
            and no p-value.
    """

    index: int
    gain: float
    explained_fraction: float
    p_value: float
    alternatives: tuple = ()
    equivalents: tuple = ()
    source: str = "selection"


def _folds(groups, k: int, seed: int) -> np.ndarray:
    names = np.unique(groups)
    rng = np.random.default_rng(seed)
    fold_of = dict(zip(names, rng.permutation(len(names)) % k))
    return np.array([fold_of[g] for g in groups])


def cv_sse(y, X, folds) -> float:
    """Held-out sum of squared errors of y ~ 1 + X, k-fold by the given fold ids."""
    n = y.shape[0]
    A = np.column_stack([np.ones(n), X]) if X.size else np.ones((n, 1))
    sse = 0.0
    for f in np.unique(folds):
        te = folds == f
        coef, *_ = np.linalg.lstsq(A[~te], y[~te], rcond=None)
        sse += float(np.sum((y[te] - A[te] @ coef) ** 2))
    return sse


def _block_permutation(groups, rng):
    """Indices that give each condition's windows the values of another condition's windows
    (cyclically repeated when the block sizes differ)."""
    names, inverse = np.unique(groups, return_inverse=True)
    members = [np.flatnonzero(inverse == i) for i in range(len(names))]
    perm = rng.permutation(len(names))
    idx = np.empty(len(groups), int)
    for i, m in enumerate(members):
        src = members[perm[i]]
        idx[m] = src[np.arange(len(m)) % len(src)]
    return idx


class _Design:
    """Per-fold projections of y ~ 1 + X that do not depend on the candidates, so that a
    permutation (which only permutes the candidates) costs one product per fold."""

    def __init__(self, y, X, fid):
        n = y.shape[0]
        A = np.column_stack([np.ones(n), X])
        self.n, self.folds = n, []
        for f in np.unique(fid):
            te = fid == f
            U, sv, Vt = np.linalg.svd(A[~te], full_matrices=False)
            keep = sv > sv[0] * 1e-9  # an orthonormal basis of the covariates, rank-deficient or not
            Q, W = U[:, keep], Vt[keep].T / sv[keep]  # coef = W @ (Qᵀ rhs): the least-squares solution
            y_tr = y[~te] - Q @ (Q.T @ y[~te])
            e0 = y[te] - A[te] @ (W @ (Q.T @ y[~te]))
            self.folds.append((~te, te, Q, W, A[te], y_tr, e0))

    def _fits(self, C):
        """Per fold: (test rows, e0, β, D): the held-out residual with column k of C added is
        e0 − β_k D[:, k] (β the coefficient of c_k's part orthogonal to the covariates on the
        training rows, D the test rows of c_k minus their covariate prediction)."""
        for tr, te, Q, W, A_te, y_tr, e0 in self.folds:
            C_tr = C[tr]
            QC = Q.T @ C_tr
            cc = np.einsum("ij,ij->j", C_tr, C_tr) - np.einsum("ij,ij->j", QC, QC)  # |c_tr − Q Qᵀ c_tr|²
            beta = np.where(cc > 1e-12 * self.n, (C_tr.T @ y_tr) / np.maximum(cc, 1e-300), 0.0)
            yield te, e0, beta, C[te] - A_te @ (W @ QC)

    def scores(self, C) -> np.ndarray:
        """Held-out SSE of y ~ 1 + X + c_k for every column c_k of C (see `_scores`)."""
        sse = np.zeros(C.shape[1])
        for _, e0, beta, D in self._fits(C):
            sse += e0 @ e0 - 2.0 * beta * (D.T @ e0) + beta**2 * np.einsum("ij,ij->j", D, D)
        return sse

    def errors(self, C) -> np.ndarray:
        """(n, K) held-out residual of every window (in its test fold) with each column of C
        added; `scores` is the column sums of their squares."""
        err = np.zeros((self.n, C.shape[1]))
        for te, e0, beta, D in self._fits(C):
            err[te] = e0[:, None] - D * beta
        return err


def _scores(y, X, C, fid) -> np.ndarray:
    """Held-out SSE of y ~ 1 + X + c_k for every column c_k of C at once, k-fold by `fid`.

    By Frisch–Waugh–Lovell the coefficient of c_k is that of its part orthogonal to
    [1, X] on the training rows, so each fold costs a few (n × K) products instead of K
    least-squares solves.
    """
    return _Design(y, X, fid).scores(C)


def equivalent(design: _Design, C, cols, best: int, groups, width: float = 1.0) -> np.ndarray:
    """Which candidates explain the residual as well as `best`, within `width` standard
    errors: the paired difference of their held-out squared errors, summed per condition
    (conditions are the independent units), is compared with its standard error (the
    one-standard-error rule of cross-validated model choice).

    Args:
        design: the selection's design (covariates so far).
        C: (n, K) candidates; cols: the columns to compare (including `best`).
        best: the column with the least held-out error.
        groups: (n,) condition of each window.

    Returns:
        bool mask over `cols`.
    """
    cols = np.asarray(cols)
    sq = design.errors(C[:, cols]) ** 2
    _, inverse = np.unique(groups, return_inverse=True)
    per = np.zeros((inverse.max() + 1, len(cols)))
    np.add.at(per, inverse, sq)
    d = per - per[:, [int(np.flatnonzero(cols == best)[0])]]
    se = np.sqrt(per.shape[0]) * d.std(axis=0, ddof=1)
    return d.sum(axis=0) <= width * se + 1e-12


def _standardise(A):
    """Columns centred and scaled to unit spread; constant columns dropped."""
    sd = A.std(axis=0)
    return ((A - A.mean(axis=0)) / np.where(sd > 0, sd, 1.0))[:, sd > 0]


def _base(base, n: int) -> np.ndarray:
    """The base covariates (n, B), standardised; (n, 0) if none."""
    return np.empty((n, 0)) if base is None else _standardise(np.asarray(base, float).reshape(n, -1))


def gains(residual, columns, groups, *, base=None, folds: int = 5, seed: int = 0) -> np.ndarray:
    """The held-out gain `forward_select` credits each column with as its first effect:
    1 − (held-out SSE with the base covariates and the column) / (with the base only), with
    the same folds by condition (the same `seed`). For any per-window columns, e.g. a known
    effect, to ask whether the selection could have preferred it.

    Args:
        residual: (n,). columns: (n,) or (n, K). groups: (n,) condition of each window.
        base, folds, seed: as in `forward_select`.

    Returns:
        (K,) the relative drop of the held-out squared error (0 for a constant column).
    """
    y = np.asarray(residual, float)
    B = _base(base, len(y))
    C = np.asarray(columns, float).reshape(len(y), -1)
    fid = _folds(np.asarray(groups), folds, seed)
    varying = C.std(axis=0) > 0
    out = np.zeros(C.shape[1])
    if varying.any():
        out[varying] = 1.0 - _Design(y, B, fid).scores(_standardise(C)) / cv_sse(y, B, fid)
    return out


def gain(residual, column, groups, *, base=None, folds: int = 5, seed: int = 0) -> float:
    """`gains` of one column."""
    return float(gains(residual, np.asarray(column, float).reshape(-1, 1), groups, base=base, folds=folds,
                       seed=seed)[0])


def _remaining(chosen, usable):
    free = usable.copy()
    free[[s.index for s in chosen]] = False
    return free


def _permutation_p(design, C, groups, gain: float, current: float, rng, alpha: float, permutations: int) -> float:
    """The block-permutation p-value of the best gain `gain`. Null: the best gain of *any*
    candidate (a column of `C`) once the candidates' condition blocks are permuted (the
    selected gain is a best of K, not of one). Stops as soon as p > alpha is certain."""
    null = []
    for _ in range(permutations):
        perm = _block_permutation(groups, rng)
        null.append(1.0 - np.min(design.scores(C[perm])) / current)
        if 1 + np.sum(np.array(null) >= gain) > alpha * (1 + permutations):
            break  # p > alpha whatever the remaining permutations give
    return (1 + int(np.sum(np.array(null) >= gain))) / (1 + permutations)


def forward_select(residual, candidates, groups, *, base=None, folds: int = 5, max_effects: int = 3,
                   min_gain: float = 0.02, alpha: float = 0.01, permutations: int = 199,
                   seed: int = 0, complexity=None, parsimony: float = 0.0, compare: int = 20) -> list[Selected]:
    """Candidates that explain the residual, most explanatory first (possibly none).

    Args:
        residual: (n,) measured − predicted, per window.
        candidates: (n, K) candidate features per window (any scale: standardised here).
        groups: (n,) condition of each window (folds and permutations are by condition).
        base: (n, B) covariates always in the model and never permuted (e.g. a basis of the
            model's own inputs, so that a candidate must explain more than a better fit of
            those inputs could); gains are relative to the error with them.
        folds: k of the k-fold split by condition.
        max_effects: most candidates selected.
        min_gain: smallest relative drop of the held-out error worth a candidate.
        alpha: significance level of the permutation test.
        permutations: permutations per test.
        seed: seed of the folds and permutations.
        complexity: (K,) complexity of each candidate (e.g. its number of operators and
            fitted parameters), for `parsimony`.
        parsimony: > 0: once the best candidate's gain is significant, name instead the
            simplest of the `compare` best candidates that are `equivalent` to it within
            `parsimony` standard errors (the simpler explanation of the same miss).

    Returns:
        list of `Selected`.
    """
    y = np.asarray(residual, float)
    C = np.asarray(candidates, float)
    groups = np.asarray(groups)
    if C.ndim != 2 or C.shape[0] != y.shape[0] or groups.shape[0] != y.shape[0]:
        raise ValueError(f"shapes: residual {y.shape}, candidates {C.shape}, groups {groups.shape}")
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(C))):
        raise ValueError("residual and candidates must be finite")
    if np.unique(groups).size < folds:
        raise ValueError(f"{np.unique(groups).size} conditions, fewer than {folds} folds")
    sd = C.std(axis=0)
    C = (C - C.mean(axis=0)) / np.where(sd > 0, sd, 1.0)
    usable = sd > 0
    fid = _folds(groups, folds, seed)
    rng = np.random.default_rng(seed + 1)
    B = _base(base, len(y))
    start = cv_sse(y, B, fid)
    chosen: list[Selected] = []
    current = start
    for _ in range(max_effects):
        X = np.column_stack([B, C[:, [s.index for s in chosen]]])
        free = _remaining(chosen, usable)
        if not free.any():
            break
        design = _Design(y, X, fid)
        scores = np.full(C.shape[1], np.inf)
        scores[free] = design.scores(C[:, free])
        k = int(np.argmin(scores))
        gain = 1.0 - scores[k] / current
        if gain < min_gain:
            break
        p = _permutation_p(design, C[:, free], groups, gain, current, rng, alpha, permutations)
        if p > alpha:
            break
        same = (k,)
        if parsimony > 0 and complexity is not None:
            top = np.argsort(scores)[:compare]
            top = top[np.isfinite(scores[top])]
            same = tuple(int(j) for j in sorted(top[equivalent(design, C, top, k, groups, parsimony)],
                                                key=lambda j: (complexity[j], scores[j])))
            k = same[0]
            gain = 1.0 - scores[k] / current
        same = tuple((j, float(1.0 - scores[j] / current)) for j in same)
        current_before = current
        current = scores[k]
        order = [j for j in np.argsort(scores) if j != k and np.isfinite(scores[j])][:5]
        alts = tuple((int(j), float(1.0 - scores[j] / current_before)) for j in order)
        chosen.append(Selected(k, float(gain), float(1.0 - current / start), float(p), alts, same))
    return chosen
