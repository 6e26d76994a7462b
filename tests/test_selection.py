"""Effect selection: a planted candidate is found first and alone, a pure-noise residual
yields nothing, and within-condition correlation does not pass for an effect."""

import numpy as np
import pytest

from pvvjax.selection import cv_sse, forward_select


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
    from pvvjax.selection import _folds, _scores

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
