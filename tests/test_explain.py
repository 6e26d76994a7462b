"""Naming by one calibrated test (`pvvjax.discovery.explain`): on window tables where the
answer is known, it names the missing channel and nothing else, names nothing missing where
nothing is (at about the stated rate over many draws), never tests a candidate built from
the model's own inputs as missing but names their misfit by its form, names a second effect
given the first, names a stand-in that the data cannot tell apart beside it, and tests
responses given as columns; the misfit is named first (by forward selection over the forms)
and taken off, so a channel that follows it is not named missing, and a named lag joins the
inputs with every lag."""

import numpy as np
import pandas as pd
import pytest
from conftest import LinearLearner

from pvvjax.discovery import Candidate, carried_by, explain, misfits, out_of_fold_linear, unit_folds
from pvvjax.discovery.candidates import values

UNITS, PER = 50, 16
INPUTS = ("advance_ratio", "rotor_rpm")
CANDS = [Candidate("input", ("yaw_rate_dps",), {"transform": "abs"}), Candidate("input", ("sideslip_deg",)),
         Candidate("input", ("pedal_pct",)), Candidate("input", ("airspeed_kt",)),
         Candidate("threshold", ("rotor_rpm",), {"knee": 0.5, "above": True, "softness": 0.05})]




def _world(rng, yaw=0.0, sideslip=0.0):
    """Windows of conditions: two model inputs, channels a model lacks (yaw rate, sideslip,
    pedal that follows the sideslip, airspeed that follows the inputs), and a residual of a
    function of the inputs, the effects asked for and noise with a per-condition part."""
    g = np.repeat(np.arange(UNITS), PER)
    n = g.size
    mu = rng.uniform(0.0, 0.3, UNITS)[g] + 0.01 * rng.standard_normal(n)
    rpm = rng.uniform(0.0, 1.0, UNITS)[g] + 0.05 * rng.standard_normal(n)
    r = rng.standard_normal(UNITS)[g] * 5 + rng.standard_normal(n)
    beta = rng.standard_normal(UNITS)[g] * 3 + rng.standard_normal(n)
    table = pd.DataFrame({"x:advance_ratio": mu, "x:rotor_rpm": rpm, "x:yaw_rate_dps": r, "abs:yaw_rate_dps": np.abs(r),
                          "x:sideslip_deg": beta, "x:pedal_pct": 50 + 2 * beta + rng.standard_normal(n),
                          "x:airspeed_kt": 400 * mu * (1 + 0.1 * rpm)})
    y = (0.3 * mu + 0.05 * rpm + yaw * np.abs(r) + sideslip * beta
         + rng.standard_normal(UNITS)[g] * 0.5 + rng.standard_normal(n) * 0.5)
    return y, table, g


def _named(res, kind):
    return [n.candidate.key for n in res.named if n.kind == kind]


def _missing(res):
    return _named(res, "missing")


def test_the_missing_channel_is_named_and_nothing_else():
    y, table, g = _world(np.random.default_rng(0), yaw=0.08)
    res = explain(y, table, INPUTS, g, candidates=CANDS)
    assert _missing(res) == [CANDS[0].key]
    assert res.named[0].adjusted_p < 0.05 and res.named[0].theta > 0 and res.named[0].tied == ()
    assert CANDS[4].key in res.carried  # a knee of an input: never tested as missing
    assert CANDS[4].key not in set(res.tests[res.tests["round"] > 0].key)
    assert set(res.tests["round"]) == {1, 2}  # a second round given it, where nothing passed


def test_a_second_effect_is_named_given_the_first():
    y, table, g = _world(np.random.default_rng(1), yaw=0.08, sideslip=0.15)
    res = explain(y, table, INPUTS, g, candidates=CANDS)
    keys = _missing(res)
    assert set(keys[:2]) == {CANDS[0].key, CANDS[1].key} or set(keys[:2]) == {CANDS[0].key, CANDS[2].key}
    assert len(keys) == 2  # the pedal, which follows the sideslip, has nothing left once it is named


def test_where_nothing_is_missing_nothing_is_named_at_about_the_level():
    rng = np.random.default_rng(2)
    named = [bool(_missing(explain(y, t, INPUTS, g, candidates=CANDS, learner=LinearLearner)))
             for y, t, g in (_world(rng) for _ in range(60))]
    assert np.mean(named) <= 0.12  # 5 % family-wise, within about three Monte Carlo errors


def test_candidates_of_the_inputs_are_carried_and_arguments_are_checked():
    assert carried_by(Candidate("threshold", ("blade_loading",), {"knee": 0.1}),
                      ("advance_ratio", "gross_weight_lb", "rotor_rpm", "density_ratio", "mlf", "climb_rate_fpm"))
    assert not carried_by(Candidate("input", ("nz_g",)), ("mlf",))
    y, table, g = _world(np.random.default_rng(3))
    with pytest.raises(ValueError, match="inputs"):
        explain(y, table, ("no_such",), g, candidates=CANDS)
    with pytest.raises(ValueError, match="one row per window"):
        explain(y[:-1], table, INPUTS, g, candidates=CANDS)


def test_a_stand_in_the_data_cannot_tell_apart_is_named_beside_the_effect():
    # The pedal follows the sideslip within a little noise: where the sideslip acts, either
    # explains the residual and neither has anything left given the other.
    # Whether a pair is told apart is itself a test at the level, so over a few draws the pair
    # is named together in most.
    rng = np.random.default_rng(4)
    together = 0
    for _ in range(5):
        y, table, g = _world(rng, sideslip=0.15)
        table["x:pedal_pct"] = 50 + 2 * table["x:sideslip_deg"] + 0.02 * rng.standard_normal(len(y))
        res = explain(y, table, INPUTS, g, candidates=CANDS, learner=LinearLearner)
        first = res.named[0]
        assert first.candidate.key in (CANDS[1].key, CANDS[2].key)
        together += {first.candidate.key, *first.tied} == {CANDS[1].key, CANDS[2].key}
        if first.tied:
            assert _missing(res) == [first.candidate.key]  # the tied one is named with it, not again
    assert together >= 4


def test_a_misfit_of_the_inputs_is_named_by_its_form_never_as_missing():
    # The residual holds a knee of rotor speed (an input): the capacity test finds it, and the
    # knee is named as a misfit; no channel is named as missing.
    rng = np.random.default_rng(5)
    y, table, g = _world(rng)
    rpm = table["x:rotor_rpm"].to_numpy()
    y = 0.5 * np.maximum(rpm - 0.5, 0) + 0.02 * rng.standard_normal(len(y))
    res = explain(y, table, INPUTS, g, candidates=CANDS)
    assert res.capacity.p_value < 0.05
    assert [(n.candidate.key, n.kind, n.round) for n in res.named] == [(CANDS[4].key, "misfit", 1)]
    # Airspeed, which the advance ratio and rotor speed determine, is a form of the inputs too.
    assert set(res.tests[res.tests.kind == "misfit"].key) == {CANDS[3].key, CANDS[4].key}


def test_the_misfit_is_taken_off_the_residual_before_anything_is_tested_as_missing():
    # A knee of rotor speed (an input) and a sideslip effect: the knee is named first as the
    # misfit; the missing round sees the residual less the knee's out-of-fold fit, exactly
    # as if the caller had taken it off and passed the misfit as given.
    rng = np.random.default_rng(7)
    y, table, g = _world(rng, sideslip=0.15)
    y = y + 8.0 * np.maximum(table["x:rotor_rpm"].to_numpy() - 0.5, 0)
    res = explain(y, table, INPUTS, g, candidates=CANDS)
    assert [n.kind for n in res.named][:1] == ["misfit"] and res.named[0].candidate.key == CANDS[4].key
    assert _missing(res)[:1] in ([CANDS[1].key], [CANDS[2].key])
    m = misfits(y, table, INPUTS, g, candidates=CANDS)
    shift = out_of_fold_linear(np.column_stack(
        [values(n.candidate, table) for n in m.named]), y, np.ones(len(y), bool), unit_folds(g, 5, 0))
    again = explain(y - shift, table, INPUTS, g, candidates=CANDS, given=m)
    pd.testing.assert_frame_equal(res.tests, again.tests)
    # Without the correction, the missing round would have seen the knee in the residual.
    raw = explain(y, table, INPUTS, g, candidates=CANDS, given=m)
    def first(r):  # the first missing round's coefficients
        m = r.tests[r.tests.kind == "missing"]
        return m[m["round"] == m["round"].min()].theta.to_numpy()

    assert not np.allclose(first(raw), first(res))


def test_misfit_forms_are_named_by_forward_selection_each_given_the_ones_before():
    rng = np.random.default_rng(8)
    y, table, g = _world(rng)
    mu, rpm = table["x:advance_ratio"].to_numpy(), table["x:rotor_rpm"].to_numpy()
    knee_mu = Candidate("threshold", ("advance_ratio",), {"knee": 0.2, "above": True, "softness": 0.01})
    y = 0.5 * np.maximum(rpm - 0.5, 0) + 2.0 * np.maximum(mu - 0.2, 0) + 0.02 * rng.standard_normal(len(y))
    res = misfits(y, table, INPUTS, g, candidates=CANDS + [knee_mu])
    assert {n.candidate.key for n in res.named} == {CANDS[4].key, knee_mu.key}
    assert [n.round for n in res.named] == [1, 2] and all(n.kind == "misfit" for n in res.named)
    # The third round tested the rest given both and named nothing.
    assert set(res.tests["round"]) == {1, 2, 3}


def test_a_named_lag_joins_the_inputs_with_every_lag_so_a_stand_in_of_another_lag_is_not_named():
    rng = np.random.default_rng(9)
    y, table, g = _world(rng)
    lag_a = rng.standard_normal(len(y)) * 0.5 + rng.standard_normal(UNITS)[g]
    lag_b = rng.standard_normal(len(y)) * 0.5 + rng.standard_normal(UNITS)[g]
    table["rate:collective_pct"] = lag_b + 0.3 * rng.standard_normal(len(y))  # stands in for the second lag
    resp = [Candidate("lag", (), {"tau_s": 1.0}), Candidate("lag", (), {"tau_s": 8.0})]
    cands = CANDS[:3] + [Candidate("rate", ("collective_pct",))]
    res = explain(y + 0.3 * lag_a + 0.15 * lag_b, table, INPUTS, g, candidates=cands,
                  responses=(resp, np.column_stack([lag_a, lag_b])), learner=LinearLearner)
    assert _named(res, "history") == [resp[0].key] and _missing(res) == []


def test_out_of_fold_linear_fits_each_fold_on_the_others_only():
    rng = np.random.default_rng(10)
    A, fold = rng.standard_normal((60, 2)), np.repeat(np.arange(3), 20)
    target = A @ [1.0, -2.0] + 0.1 * rng.standard_normal(60)
    fit = rng.uniform(size=60) > 0.2
    got = out_of_fold_linear(A, target, fit, fold)
    for k in range(3):
        rows = (fold != k) & fit
        coef = np.linalg.lstsq(np.column_stack([np.ones(rows.sum()), A[rows]]), target[rows], rcond=None)[0]
        np.testing.assert_allclose(got[fold == k], np.column_stack([np.ones(20), A[fold == k]]) @ coef, atol=1e-12)


def test_a_response_given_as_a_column_is_tested_and_named():
    rng = np.random.default_rng(6)
    y, table, g = _world(rng)
    lag = rng.standard_normal(len(y)) * 0.5 + rng.standard_normal(UNITS)[g]  # a lagged prediction minus it
    resp = [Candidate("lag", (), {"tau_s": 4.0}), Candidate("lag", (), {"tau_s": 8.0})]
    cols = np.column_stack([lag, rng.standard_normal(len(y))])
    res = explain(y + 0.2 * lag, table, INPUTS, g, candidates=CANDS[:3], responses=(resp, cols),
                  learner=LinearLearner)
    # A lag of the prediction is a form of the inputs' history, never a missing input.
    assert _named(res, "history") == [resp[0].key] and res.named[0].explained > 0 and _missing(res) == []


def test_a_rate_of_an_input_is_named_as_history_and_a_missing_channel_beyond_it():
    # The residual holds a rate of rotor speed (an input's history) and the yaw rate (a
    # channel the model lacks): the rate is named by its form as history, the yaw rate as
    # missing, tested beyond the inputs' whole history.
    rng = np.random.default_rng(11)
    y, table, g = _world(rng, yaw=0.08)
    rate = rng.standard_normal(UNITS)[g] + 0.5 * rng.standard_normal(len(y))
    table["rate:rotor_rpm"] = rate
    table["abs_rate:rotor_rpm"] = np.abs(rate)
    table["spread:rotor_rpm"] = np.abs(rng.standard_normal(len(y)))
    cands = CANDS + [Candidate("rate", ("rotor_rpm",)), Candidate("window", ("rotor_rpm",))]
    res = explain(y + 0.2 * rate, table, INPUTS, g, candidates=cands, learner=LinearLearner)
    assert _named(res, "history") == [cands[5].key]
    assert _missing(res) == [CANDS[0].key]
    assert set(res.tests[res.tests.key == cands[5].key].kind) == {"history"}  # never tested as missing
    assert (res.nuisance.residual_skill >= 0).all() and (res.nuisance.candidates_min_skill >= 0).all()
    assert set(res.nuisance.kind) == {"history", "missing"}


def test_a_sharp_function_of_a_composite_of_the_inputs_is_not_taken_for_a_stand_in_channel():
    # The residual is a stall knee of the blade loading W·n/(ρΩ²), a composite of four inputs;
    # shaft power follows the blade loading. Given the composite, the nuisance regressions
    # learn the knee, and no knee of shaft power is named as missing (on the raw inputs the
    # trees leave part of the knee, which the stand-in's knee takes up).
    rng = np.random.default_rng(12)
    units, per = 120, 20
    g = np.repeat(np.arange(units), per)
    n = g.size
    w = rng.uniform(14000, 22000, units)[g]
    rho = rng.uniform(0.8, 1.0, units)[g]
    rpm = rng.uniform(245, 265, units)[g] + 0.5 * rng.standard_normal(n)
    nz = 1 + np.abs(rng.normal(0, 0.4, units))[g] * np.sin(np.linspace(0, np.pi, per))[np.tile(np.arange(per), units)]
    load = w * nz / (rho * rpm**2)
    power = 1500 * load / load.mean() + 20 * rng.standard_normal(n)
    table = pd.DataFrame({"x:gross_weight_lb": w, "x:density_ratio": rho, "x:rotor_rpm": rpm, "x:nz_g": nz,
                          "x:shaft_power_hp": power})
    knee = np.quantile(load, 0.77)  # between the spline's knots
    y = 0.05 * np.maximum(load - knee, 0) / load.std() + 0.01 * rng.standard_normal(units)[g] \
        + 0.01 * rng.standard_normal(n)
    inputs = ("gross_weight_lb", "density_ratio", "rotor_rpm", "nz_g")
    cands = [Candidate("threshold", ("shaft_power_hp",), {"knee": float(np.quantile(power, q)), "above": True,
                                                           "softness": 10.0}) for q in (0.5, 0.75, 0.9)]
    cands.append(Candidate("input", ("shaft_power_hp",)))
    res = explain(y, table, inputs, g, candidates=cands)
    assert _missing(res) == []
    assert res.capacity.p_value < 0.05  # the misfit is there, and is a function of the inputs


def test_the_composites_are_the_blade_loading_and_advance_ratio_up_to_the_rotors_constants():
    from pvvjax.data.features import advance_ratio, blade_loading
    from pvvjax.discovery import composites

    rng = np.random.default_rng(13)
    t = pd.DataFrame({"x:gross_weight_lb": rng.uniform(14e3, 22e3, 50), "x:density_ratio": rng.uniform(0.7, 1, 50),
                      "x:rotor_rpm": rng.uniform(240, 270, 50), "x:nz_g": rng.uniform(0.5, 2.5, 50),
                      "x:airspeed_kt": rng.uniform(0, 160, 50)})
    C, names = composites(t, ("airspeed_kt", "rotor_rpm", "gross_weight_lb", "density_ratio", "nz_g"))
    assert names == ["loading at 1 g", "loading at nz_g", "advance ratio"]
    col = lambda k: t[f"x:{k}"].to_numpy()  # noqa: E731
    ref = [blade_loading(col("gross_weight_lb"), col("density_ratio"), col("rotor_rpm")),
           blade_loading(col("gross_weight_lb"), col("density_ratio"), col("rotor_rpm"), col("nz_g")),
           advance_ratio(col("airspeed_kt"), col("rotor_rpm"))]
    for j, r in enumerate(ref):
        ratio = C[:, j] / np.asarray(r)
        np.testing.assert_allclose(ratio, ratio[0], rtol=1e-5)
    assert composites(t, ("airspeed_kt",))[1] == []  # nothing to compose from one channel
