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

Plain NumPy: a few small least-squares problems per candidate; not in any hot loop.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Selected", "cv_sse", "forward_select"]


class Selected(NamedTuple):
    """One selected candidate.

    Attributes:
        index: column of the candidate matrix.
        gain: relative drop of the held-out squared error when it was added.
        explained_fraction: 1 − held-out SSE with the selection so far / without any.
        p_value: permutation p-value of the gain.
    """

    index: int
    gain: float
    explained_fraction: float
    p_value: float


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


def _best_gain(y, X, C, perm, chosen, usable, fid, current) -> float:
    """The best gain of any remaining candidate once the candidates' condition blocks are
    permuted: the null distribution of the *selected* gain (the best of K, not of one)."""
    Cp = C[perm]
    best = -np.inf
    for k in np.flatnonzero(usable):
        if any(s.index == k for s in chosen):
            continue
        best = max(best, 1.0 - cv_sse(y, np.column_stack([X, Cp[:, k]]), fid) / current)
    return best


def forward_select(residual, candidates, groups, *, folds: int = 5, max_effects: int = 3, min_gain: float = 0.02,
                   alpha: float = 0.01, permutations: int = 199, seed: int = 0) -> list[Selected]:
    """Candidates that explain the residual, most explanatory first (possibly none).

    Args:
        residual: (n,) measured − predicted, per window.
        candidates: (n, K) candidate features per window (any scale: standardised here).
        groups: (n,) condition of each window (folds and permutations are by condition).
        folds: k of the k-fold split by condition.
        max_effects: most candidates selected.
        min_gain: smallest relative drop of the held-out error worth a candidate.
        alpha: significance level of the permutation test.
        permutations: permutations per test.
        seed: seed of the folds and permutations.

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
    base = cv_sse(y, np.empty((len(y), 0)), fid)
    chosen: list[Selected] = []
    current = base
    for _ in range(max_effects):
        X = C[:, [s.index for s in chosen]]
        scores = np.full(C.shape[1], np.inf)
        for k in np.flatnonzero(usable):
            if any(s.index == k for s in chosen):
                continue
            scores[k] = cv_sse(y, np.column_stack([X, C[:, k]]), fid)
        k = int(np.argmin(scores))
        if not np.isfinite(scores[k]):
            break
        gain = 1.0 - scores[k] / current
        if gain < min_gain:
            break
        null = np.array([_best_gain(y, X, C, _block_permutation(groups, rng), chosen, usable, fid, current)
                         for _ in range(permutations)])
        p = (1 + int(np.sum(null >= gain))) / (1 + permutations)
        if p > alpha:
            break
        current = scores[k]
        chosen.append(Selected(k, float(gain), float(1.0 - current / base), float(p)))
    return chosen
