"""The cross-fitted tests on units (`pvvjax.discovery.gcm_test`, `capacity_test`, `holm`):
calibrated where the answer is no (at 5 % they reject about 5 % of worlds drawn under the
null, with windows of one unit correlated, where a test on windows rejects far more), and
powerful where it is yes; checked by simulation against the stated level."""

import numpy as np
import pytest
from conftest import LinearLearner
from scipy import stats

from pvvjax.discovery import capacity_test, cross_fit, gcm_test, holm, unit_folds

UNITS, PER = 60, 20  # conditions, windows per condition




def _world(rng, effect=0.0, shared=1.0):
    """Windows grouped in units: inputs Z, a candidate x that is partly a function of Z, and a
    residual y = f(Z) + effect·(x's own part) + noise; both noises hold a per-unit part
    (`shared`), as a condition's windows do."""
    groups = np.repeat(np.arange(UNITS), PER)
    z = rng.normal(size=(UNITS * PER, 2)) + rng.normal(size=(UNITS, 2))[groups]
    own = rng.normal(size=UNITS * PER) * 0.5 + shared * rng.normal(size=UNITS)[groups]
    x = z[:, 0] + own
    y = 0.8 * z[:, 1] + effect * own + rng.normal(size=UNITS * PER) + shared * rng.normal(size=UNITS)[groups]
    return y, x, z, groups


def test_at_five_per_cent_a_null_world_is_named_about_one_time_in_twenty():
    rng = np.random.default_rng(0)
    p, naive = [], []
    for _ in range(300):
        y, x, z, g = _world(rng)
        p.append(gcm_test(y, x, g, z, learner=LinearLearner).p_value)
        # The same products tested with windows as the units: the per-unit parts make it reject far more.
        fold = unit_folds(g)
        r = cross_fit(y, z, fold, LinearLearner) * cross_fit(x, z, fold, LinearLearner)
        naive.append(2 * stats.norm.sf(abs(r.mean() / (r.std() / np.sqrt(r.size)))))
    rate = np.mean(np.array(p) < 0.05)
    assert 0.02 <= rate <= 0.085, rate  # 5 % within three Monte Carlo standard errors (1.3 points)
    assert np.mean(np.array(naive) < 0.05) > 2 * rate


def test_a_candidate_with_its_own_effect_is_found_and_one_carried_by_the_inputs_is_not():
    rng = np.random.default_rng(1)
    y, x, z, g = _world(rng, effect=1.0)
    assert gcm_test(y, x, g, z, learner=LinearLearner).p_value < 1e-3
    # A channel that follows a knee of an input, with a variation of its own that the residual does not
    # depend on: with trees as the nuisance learner, the knee is carried by the inputs and nothing is left.
    knee = np.maximum(z[:, 1] - 0.5, 0)
    y2 = 0.8 * knee + rng.normal(size=y.size) + rng.normal(size=UNITS)[g]
    ps = [gcm_test(y2, knee + 0.3 * rng.normal(size=y.size), g, z, seed=s).p_value for s in range(2)]
    assert min(ps) > 0.01
    # Without the partialling-out the same knee is plainly correlated with the residual (a misfit's form).
    assert gcm_test(y2, knee, g).p_value < 1e-6


def test_capacity_is_found_where_the_residual_is_a_function_of_the_inputs_and_not_in_noise():
    rng = np.random.default_rng(2)
    y, x, z, g = _world(rng)
    assert capacity_test(y, z, g, learner=LinearLearner).p_value < 1e-4
    noise = [capacity_test(rng.normal(size=y.size) + rng.normal(size=UNITS)[g], z, g, learner=LinearLearner).p_value
             for _ in range(100)]
    assert np.mean(np.array(noise) < 0.05) <= 0.1


def test_holm_and_the_folds():
    np.testing.assert_allclose(holm([0.01, 0.04, 0.03, 0.005]), [0.03, 0.06, 0.06, 0.02])
    assert holm([0.5, 0.9]).max() == 1.0
    g = np.repeat(np.arange(23), 7)
    fold = unit_folds(g, 5, seed=3)
    assert all(len(set(fold[g == u])) == 1 for u in range(23))
    counts = np.bincount(fold[::7])
    assert counts.max() - counts.min() <= 1
    assert not np.array_equal(fold, unit_folds(g, 5, seed=4))
    with pytest.raises(ValueError, match="3 units for 5 folds"):
        unit_folds([0, 1, 2], 5)
