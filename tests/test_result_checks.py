"""Results checked like inputs (`dynamics.checks`): a prediction constant through a record
that varies, a parameter that is not finite or an identified response outside what the
campaign can show are named; a score over no window is NaN with its reason, never 0."""

import jax
import numpy as np
import pytest

from pvvjax.dynamics import dynamic_init, heldout_scores
from pvvjax.dynamics.checks import (
    constant_rows,
    parameter_problems,
    prediction_problems,
    response_limits,
)
from pvvjax.nets import mlp_init


def test_constant_rows_against_a_loop_over_rows():
    rng = np.random.default_rng(0)
    measured = 0.1 + 0.05 * rng.random((6, 9))
    measured[1] = 0.1  # a steady record: it does not vary, whatever the prediction
    pred = measured + 0.01 * rng.standard_normal((6, 9))
    pred[0] = 0.12  # constant through a record that varies
    pred[2] = 0.12 + 1e-9 * np.arange(9)  # constant to a billionth
    mask = np.ones((6, 9), bool)
    mask[3, 2:] = False  # two windows: too few to say
    pred[3, :2] = 0.2
    expected = []
    for p, m, k in zip(pred, measured, mask):
        varies = k.sum() >= 3 and m[k].std() > 0.05 * abs(m[k].mean())
        expected.append(bool(varies and p[k].std() <= 1e-3 * m[k].std()))
    np.testing.assert_array_equal(constant_rows(pred, measured, mask), expected)
    assert expected == [True, False, True, False, False, False]
    problems = prediction_problems(pred, measured, mask, [f"c{i}" for i in range(6)])
    assert problems == ["a constant prediction through 2 condition(s) whose vibration varies (c0, c2)"]


def test_a_missing_prediction_is_named():
    measured = np.full((3, 4), 0.1)
    pred = measured.copy()
    pred[1, 2] = np.nan
    assert prediction_problems(pred, measured, np.ones((3, 4), bool), ["a", "b", "c"]) == [
        "no finite prediction on 1 of 3 conditions (b)"]


def test_an_identified_response_outside_the_campaigns_range_and_a_non_finite_parameter_are_named():
    lim = response_limits(20.0, 0.25)  # records of 20 s, a window every 0.25 s
    assert lim.f_n_hz == pytest.approx((1 / (2 * np.pi * 20), 2.0)) and lim.delay_s == (0.0, 10.0)
    static = mlp_init(jax.random.key(0), 3, (4,))
    assert parameter_problems(dynamic_init(static, omega_n=2 * np.pi * 0.5, zeta=0.7, delay_s=0.1), lim) == []
    far = parameter_problems(dynamic_init(static, omega_n=2 * np.pi * 0.5, zeta=0.7, delay_s=50.0), lim)
    assert len(far) == 1 and far[0].startswith("identified delay_s 50 outside its range 0 to 10")
    endless = parameter_problems(dynamic_init(static, omega_n=2 * np.pi * 0.5, zeta=0.7, delay_s=1e6), lim)
    assert endless == ["non-finite parameters in 1 of 13 arrays", "identified delay_s inf outside its range 0 to 10"]
    fast = parameter_problems(dynamic_init(static, omega_n=2 * np.pi * 3.0, zeta=0.7, delay_s=0.1), lim)
    assert fast and "f_n_hz 3" in fast[0]
    first = {**static["layers"][0], "w": static["layers"][0]["w"].at[0, 0].set(np.nan)}
    broken = {**static, "layers": (first, *static["layers"][1:])}
    assert parameter_problems(broken)[0].startswith("non-finite parameters in 1 of")


def test_a_score_over_no_window_is_nan_with_its_reason_never_zero():
    rng = np.random.default_rng(1)
    measured = 0.1 + 0.05 * rng.random((4, 6))
    pred = measured + 0.01
    mask, time = np.ones((4, 6), bool), np.tile(np.arange(6.0), (4, 1))
    s = heldout_scores(pred, measured, mask, time, ["level"] * 4, ("pullup",), 0.1)
    assert s["rms_g"] == pytest.approx(0.01)
    assert np.isnan(s["rms_transient_g"]) and np.isnan(s["time_of_peak_err_median_s"])
    assert "no condition of the transient kinds (pullup)" in s["notes"]
    none = heldout_scores(np.full((4, 6), np.nan), measured, mask, time, ["pullup"] * 4, ("pullup",), 0.1)
    assert np.isnan([none[k] for k in ("rms_g", "rms_transient_g", "faa_pass_share", "kendall_tau",
                                       "peak_err_rms_g")]).all()
    assert none["n_conditions"] == 0 and "no held-out prediction" in none["notes"]
