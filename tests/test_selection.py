"""Effect selection: a planted candidate is found first and alone, a pure-noise residual
yields nothing, and within-condition correlation does not pass for an effect."""

import numpy as np
import pytest

from pvvjax.discovery import selection
from pvvjax.discovery.selection import cv_sse, forward_select


def _data(n_cond=60, per=25, K=30, seed=0):
    rng = np.random.default_rng(seed)
    groups = np.repeat(np.arange(n_cond), per)
    # Candidates vary within and between conditions (smooth inside each condition).
    C = rng.standard_normal((n_cond, K))[groups] + 0.5 * rng.standard_normal((n_cond * per, K))
    noise = 0.02 * rng.standard_normal(n_cond * per) + 0.01 * rng.standard_normal(n_cond)[groups]
    return C, groups, noise


def test_a_planted_effect_is_selected_first_and_alone():
    C, groups, noise = _data()
    y = 0.03 * C[:, 7] + noise
    sel = forward_select(y, C, groups, permutations=99)
    assert [s.index for s in sel] == [7]
    assert sel[0].p_value <= 0.01 and sel[0].explained_fraction > 0.5


def test_two_effects_in_order_of_strength():
    C, groups, noise = _data(seed=1)
    y = 0.04 * C[:, 3] + 0.015 * C[:, 11] + noise
    sel = forward_select(y, C, groups, permutations=99)
    assert [s.index for s in sel][:2] == [3, 11]
    assert sel[0].explained_fraction < sel[1].explained_fraction


@pytest.mark.parametrize("seed", [2, 3, 4])
def test_noise_and_within_condition_correlation_yield_nothing(seed):
    C, groups, noise = _data(seed=seed)
    # The residual has a strong per-condition component unrelated to any candidate: a
    # window-level test would call candidates that are constant per condition significant.
    rng = np.random.default_rng(seed + 10)
    y = noise + 0.05 * rng.standard_normal(60)[groups]
    assert forward_select(y, C, groups, permutations=99) == []


def test_cv_sse_and_errors():
    rng = np.random.default_rng(0)
    x = rng.standard_normal((200, 1))
    y = 2.0 * x[:, 0] + 1.0
    folds = np.arange(200) % 5
    assert cv_sse(y, x, folds) == pytest.approx(0.0, abs=1e-18)
    assert cv_sse(y, np.empty((200, 0)), folds) > 100
    with pytest.raises(ValueError, match="shapes"):
        forward_select(y, x[:10], np.zeros(200))
    with pytest.raises(ValueError, match="finite"):
        forward_select(np.r_[np.nan, y[1:]], x, np.arange(200) % 50)
    with pytest.raises(ValueError, match="fewer than"):
        forward_select(y, x, np.zeros(200))


def test_vectorised_scores_equal_one_least_squares_per_candidate():
    _folds = selection._folds
    _scores = selection._scores

    C, groups, noise = _data(n_cond=30, per=10, K=12, seed=5)
    y = 0.02 * C[:, 2] + noise
    X = C[:, [4, 5]]
    fid = _folds(groups, 5, 0)
    ref = [cv_sse(y, np.column_stack([X, C[:, k]]), fid) for k in range(C.shape[1])]
    np.testing.assert_allclose(_scores(y, X, C, fid), ref, rtol=1e-9)
    # Duplicate covariates (rank deficiency) change nothing.
    np.testing.assert_allclose(_scores(y, np.column_stack([X, X[:, :1]]), C, fid), ref, rtol=1e-7)


def test_base_covariates_absorb_what_they_explain():
    C, groups, noise = _data(seed=6)
    floor = C[:, 0] ** 2  # a misfit of the model's own inputs...
    y = 0.05 * (floor - floor.mean()) + noise
    cands = np.column_stack([C[:, 1:], floor + 0.3 * C[:, 1]])  # ...that a candidate partly re-expresses
    assert forward_select(y, cands, groups, permutations=49, alpha=0.02)  # found without the floor covariates
    assert forward_select(y, cands, groups, base=floor[:, None], permutations=49, alpha=0.02) == []


def test_heldout_errors_equal_a_least_squares_fit_per_fold():
    _Design = selection._Design
    _folds = selection._folds

    C, groups, noise = _data(n_cond=30, per=10, K=6, seed=7)
    y = 0.02 * C[:, 1] + noise
    X, fid = C[:, [4]], _folds(groups, 5, 0)
    err = _Design(y, X, fid).errors(C)
    for k in range(C.shape[1]):
        A = np.column_stack([np.ones(len(y)), X, C[:, k]])
        for f in range(5):
            te = fid == f
            coef, *_ = np.linalg.lstsq(A[~te], y[~te], rcond=None)
            np.testing.assert_allclose(err[te, k], y[te] - A[te] @ coef, atol=1e-12)


def test_parsimony_names_the_simpler_of_two_equivalent_candidates():
    from pvvjax.discovery.selection import equivalent
    _Design = selection._Design
    _folds = selection._folds

    C, groups, noise = _data(seed=8)
    rng = np.random.default_rng(0)
    y = 0.03 * C[:, 5] + noise
    # Column 9: the effect re-expressed with a little noise of its own (which of 5 and 9 fits
    # best is chance); column 10: the effect buried in noise (clearly worse).
    cands = np.column_stack([C[:, :9], C[:, 5] + 0.02 * rng.standard_normal(len(y)),
                             C[:, 5] + rng.standard_normal(len(y))])
    kw = dict(permutations=49, alpha=0.05, max_effects=1)
    best = forward_select(y, cands, groups, **kw)[0].index
    other = {5: 9, 9: 5}[best]
    complexity = np.ones(cands.shape[1], int)
    complexity[best] = 3  # the best fit is the complex one: parsimony names the other
    simple = forward_select(y, cands, groups, complexity=complexity, parsimony=1.0, **kw)
    assert simple[0].index == other
    assert forward_select(y, cands, groups, complexity=complexity, parsimony=0.0, **kw)[0].index == best
    # The rule's test: the best is equivalent to itself and to its twin, not to the noisy copy.
    cz = (cands - cands.mean(0)) / cands.std(0)
    same = equivalent(_Design(y, np.empty((len(y), 0)), _folds(groups, 5, 0)), cz, np.array([best, other, 10]),
                      best, groups)
    assert same.tolist() == [True, True, False]
    # Nothing simpler among the equivalents when the noisy copy is the only simple one.
    complexity = np.full(cands.shape[1], 3)
    complexity[10] = 1
    assert forward_select(y, cands, groups, complexity=complexity, parsimony=1.0, **kw)[0].index in (5, 9)


def test_gain_is_what_forward_select_credits_its_first_pick_with():
    from pvvjax.discovery.selection import gain

    C, groups, noise = _data(seed=5)
    rng = np.random.default_rng(6)
    base = rng.standard_normal((len(groups), 3))
    y = 0.03 * C[:, 4] + 0.02 * base[:, 0] + noise
    first = forward_select(y, C, groups, base=base, permutations=19, alpha=0.1, seed=3)[0]
    assert first.index == 4
    assert gain(y, C[:, 4], groups, base=base, seed=3) == pytest.approx(first.gain, rel=1e-9)
    # Independent reference: the held-out SSE of explicit least-squares fits, same folds.
    _folds = selection._folds

    fid = _folds(groups, 5, 3)
    with_c = cv_sse(y, np.column_stack([base, C[:, 4]]), fid)
    assert gain(y, C[:, 4], groups, base=base, seed=3) == pytest.approx(1 - with_c / cv_sse(y, base, fid), rel=1e-9)
    assert gain(y, np.ones(len(y)), groups, base=base) == 0.0  # a constant explains nothing new


def test_gains_of_many_columns_equal_one_least_squares_fit_each():
    from pvvjax.discovery.selection import gains
    _folds = selection._folds

    C, groups, noise = _data(seed=7)
    y = 0.03 * C[:, 2] - 0.01 * C[:, 9] + noise
    base = C[:, 20:22]
    cols = np.column_stack([C[:, :12], np.full(len(y), 3.0)])  # the last constant
    got = gains(y, cols, groups, base=base, seed=1)
    fid = _folds(groups, 5, 1)
    ref = [1 - cv_sse(y, np.column_stack([base, c]), fid) / cv_sse(y, base, fid) for c in cols[:, :12].T]
    np.testing.assert_allclose(got[:12], ref, rtol=1e-9)
    assert got[12] == 0.0 and np.argmax(got) == 2
