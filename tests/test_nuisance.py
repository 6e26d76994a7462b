"""The nuisance regressions of discovery's test (`pvvjax.discovery.partial_out`): each target
partialled out of the inputs by the best of the mean, an additive spline and trees, out of
fold; never worse than the mean, exact on what the spline spans, and the trees kept where a
target is an interaction the spline cannot carry."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from pvvjax.discovery import partial_out, unit_folds


def _data(seed, n_units=40, per=10, p=3):
    rng = np.random.default_rng(seed)
    g = np.repeat(np.arange(n_units), per)
    Z = rng.standard_normal((g.size, p))
    return rng, g, Z, unit_folds(g, 5, 0)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.0, 3.0))
def test_no_target_is_partialled_worse_than_by_its_mean(seed, signal):
    rng, g, Z, fold = _data(seed)
    Y = np.column_stack([rng.standard_normal(len(g)), signal * Z[:, 0] ** 2 + rng.standard_normal(len(g)),
                         rng.standard_normal(40)[g]])  # noise, a curve, a per-unit offset the inputs lack
    out = partial_out(Y, Z, fold)
    assert np.all(out.skill >= 0)
    mean_left = np.concatenate([Y[fold == k] - Y[fold != k].mean(axis=0) for k in range(5)])
    order = np.concatenate([np.flatnonzero(fold == k) for k in range(5)])
    sse_mean = np.sum(mean_left**2, axis=0)
    np.testing.assert_array_less(np.sum(out.left[order] ** 2, axis=0), sse_mean * (1 + 1e-9))
    assert set(out.learner) <= {"mean", "spline"}


def test_a_target_the_spline_spans_is_removed_out_of_fold_to_its_ridge_and_the_data_range():
    # A line of two inputs and a hinge of a third: what the additive spline spans, up to its
    # smallest ridge penalty and the rows beyond the training folds' range (held at its edge).
    _, g, Z, fold = _data(1)
    y = 2.0 * Z[:, 1] - 0.5 * Z[:, 2] + np.maximum(Z[:, 0] - 0.3, 0)
    out = partial_out(y, Z, fold)
    assert out.learner[0] == "spline" and out.skill[0] > 0.99
    # Without a penalty, a basis of 25 columns on 40 units would fit their noise; each
    # target keeps the penalty that predicts it best, never worse than its mean.
    rng = np.random.default_rng(3)
    noise = rng.standard_normal(40)[g] + rng.standard_normal(len(g))
    assert partial_out(noise, Z, fold).skill[0] >= 0


def test_trees_are_kept_where_the_target_is_an_interaction():
    rng, g, Z, fold = _data(2, n_units=80, per=20)
    y = np.where((Z[:, 0] > 0) & (Z[:, 1] > 0), 1.0, 0.0) + 0.05 * rng.standard_normal(len(g))
    without, with_trees = partial_out(y, Z, fold), partial_out(y, Z, fold, trees=True)
    assert with_trees.learner[0] == "trees" and with_trees.skill[0] > without.skill[0] + 0.2
    # The mask asks for trees on some columns only.
    two = partial_out(np.column_stack([y, y]), Z, fold, trees=np.array([False, True]))
    assert list(two.learner) == ["spline", "trees"]
    np.testing.assert_allclose(two.left[:, 1], with_trees.left[:, 0])
