"""The lag test: de-lagging against the exact lag recursion, the sign-flip test, and the test
inside the workflow."""


import numpy as np
import pandas as pd
import pytest
from conftest import discovery_config

from pvvjax.discovery import _confirm, _lag, _model, _rules, delag
from pvvjax.discovery._results import Predicted

_lag_windows, _Windows = _model._lag_windows, _model._Windows


def _slow_windows(n_counters=4, W=160, dt=0.25):
    rows = [dict(i=i, k=k, time_s=dt * k, weight=1.0) for i in range(n_counters) for k in range(W)]
    return _Windows(pd.DataFrame(rows), (n_counters, W), (), None)


def test_delag_undoes_the_exact_lag_recursion():
    # A slow vibration (periods 9-15 s, like a maneuver) through the exact first-order lag of
    # the replay; de-lagging recovers it to the central difference's error, in any row order.
    win = _slow_windows()
    t, i = win.table.time_s.to_numpy(), win.table.i.to_numpy()
    u = 0.12 + 0.05 * np.sin(2 * np.pi * t / (9 + 2 * i) + i)
    y = _lag_windows(u[None], win, 2.0)[0]
    got = delag(y, t, i, 2.0)
    inner = t > 8.0  # past the start at rest (and its one-sided difference)
    inner &= t < t.max() - 1.0
    assert np.max(np.abs(got - u)[inner]) < 0.005 < 0.03 < np.max(np.abs(y - u)[inner])
    perm = np.random.default_rng(0).permutation(len(u))
    np.testing.assert_allclose(delag(y[perm], t[perm], i[perm], 2.0), got[perm], rtol=1e-12)
    np.testing.assert_array_equal(delag(y, t, i, 0.0), y)


def test_sign_flip_test_against_exact_enumeration():
    # Ten conditions: all 2^10 sign patterns give the exact one-sided p-value of the total
    # difference of squared errors; the random sign flips estimate it.
    from itertools import product

    _paired_sign_flip = _confirm._paired_sign_flip

    rng = np.random.default_rng(3)
    rows = pd.DataFrame([dict(counter=c, window=w, condition=f"c{c}", maneuver="level", weight=1.0, measured_g=0.0)
                         for c in range(10) for w in range(5)])
    ea = 0.03 + 0.01 * rng.random(len(rows))
    eb = ea * (1.0 - 0.4 * rng.random(len(rows)) + 0.2 * (rows.counter.to_numpy() < 3))

    def trial(e):
        return Predicted(np.stack([e, e + 1e-9, e - 1e-9]), _Windows(rows, (10, 5), (), None))

    p, explained = _paired_sign_flip(trial(ea), trial(eb), 20000, 0)
    dc = pd.Series(ea**2 - eb**2).groupby(rows.condition).sum().to_numpy()
    exact = np.mean([np.array(s) @ dc >= dc.sum() - 1e-15 for s in product([-1.0, 1.0], repeat=10)])
    assert abs(p - exact) < 0.01 and 0.0 < exact < 0.2
    assert explained == pytest.approx(1.0 - np.sum(eb**2) / np.sum(ea**2))
    assert _paired_sign_flip(trial(eb), trial(ea), 2000, 0)[0] > 0.8  # the other way round


def test_lag_test_is_judged_by_the_learned_tau_and_adds_the_slow_lag_against_the_best_fast_one(monkeypatch):
    # The learned τ (median over folds × seeds) against lag_slow_s decides; the trainings
    # through lags add it: the reference is the best ensemble with τ <= lag_fast_s (none or
    # the fast lag), the slow lag the best above it, and its gain (over all windows and in
    # the pull-ups' step, where a lag acts) is reported.
    from pvvjax import discovery as D
    from pvvjax.config import ExperimentConfig

    rng = np.random.default_rng(0)
    rows = pd.DataFrame([dict(counter=c, window=w, condition=f"c{c}", maneuver="pullup" if c % 2 else "level",
                              time_s=0.25 * w, weight=1.0, i=c, k=w) for c in range(60) for w in range(10)])
    step = np.where((rows.maneuver == "pullup") & (rows.window >= 5), 0.1, 0.0)
    rows = rows.assign(measured_g=0.1 + step + 0.02 * rng.random(len(rows)))
    win = _Windows(rows, (60, 10), (), None)
    pullup = (rows.maneuver == "pullup").to_numpy()

    def trials(errors):
        out = []
        for (tau, off), sd in errors.items():
            sd = np.where(pullup, *sd) if isinstance(sd, tuple) else sd  # (in pull-ups, in level flight)
            pred = rows.measured_g.to_numpy() + sd * rng.standard_normal((3, len(rows)))
            ens = float(np.sqrt(np.mean((np.median(pred, 0) - rows.measured_g.to_numpy()) ** 2)))
            out.append(dict(tau_s=tau, train_offset_s=off, model=D.Model({}, (), offset_s=off, lag_tau_s=tau), win=win,
                            pred=pred, metrics=dict(rms_g=ens, peak_error_g=0.0, phase_error_s=0.0, ensemble_rms_g=ens),
                            ensemble_rms_g=ens))
        return out

    def learned(taus):
        tau = np.asarray(taus, float).reshape(5, -1)
        m = dict(rms_g=0.01, peak_error_g=0.0, phase_error_s=0.0, ensemble_rms_g=0.009)
        return lambda ctx, log: dict(tau_s=tau, tau_median_s=float(np.median(tau)), offset_s=0.0, metrics=m)

    class Ctx:
        cfg = ExperimentConfig(discovery=discovery_config(lag_test=True, lag_slow_s=2.0))

    lagged = {(0.0, 0.0): 0.03, (0.0, 1.0): 0.025, (1.0, 0.0): 0.02, (2.0, 0.0): 0.012, (3.0, 0.0): 0.016}
    monkeypatch.setattr(_lag, "_lag_trials", lambda *a, **k: trials(lagged))
    monkeypatch.setattr(_lag, "_learned_lag", learned(np.linspace(2.6, 3.4, 10)))
    got = _lag._lag_test(Ctx(), 1.0, log=lambda m: None)
    assert got["confirmed"] and not got["why"] and got["p_value"] <= 0.01  # consistent over the conditions
    assert got["reference"]["tau_s"] == 1.0 and got["slow"]["tau_s"] == 2.0  # against the fast lag, not τ = 0
    assert got["judged_in"] == "pullup" and got["local"] > 0.3
    t = got["table"]
    assert list(t.role) == ["learned"] + ["reference"] * 3 + ["slow"] * 2
    assert list(t.chosen) == [False, False, False, True, True, False]
    assert t.tau_s[0] == pytest.approx(3.0) and (t.tau_min_s[0], t.tau_max_s[0]) == pytest.approx((2.6, 3.4))
    assert t.ensemble_rms_g[0] == 0.009 and t.tau_min_s[1:].isna().all()
    assert got["drop"] == pytest.approx(t["drop"][4]) and t["drop"][3] == 0.0

    # A learned τ of the fast dynamics (the seed-46 null: the slow lag's trainings gained
    # 6.7 % there): nothing to name, whatever the trainings would gain, so they do not run;
    # the table and round 0 hold the learned lag alone. Asked to, they run.
    columns = list(t.columns)
    ran = []
    monkeypatch.setattr(_lag, "_lag_trials", lambda *a, **k: ran.append(1) or trials(lagged))
    monkeypatch.setattr(_lag, "_learned_lag", learned(np.linspace(1.0, 1.4, 10)))
    got = _lag._lag_test(Ctx(), 1.0, log=lambda m: None)
    assert not got["confirmed"] and ran == [] and got["reference"] is None and np.isnan(got["drop"])
    assert got["why"] == "the learned τ 1.20 s (folds × seeds 1.00-1.40 s) is below lag_test.slow_s 2 s"
    t = got["table"]
    assert list(t.columns) == columns and list(t.role) == ["learned"] and not t.chosen[0] and np.isnan(t["drop"][0])
    assert t.tau_s[0] == pytest.approx(1.2) and (t.tau_min_s[0], t.tau_max_s[0]) == pytest.approx((1.0, 1.4))
    row, effect = _lag._lag_round(None, got, ("advance_ratio",))
    assert effect is None and not row["confirmed"] and row["why_not"] == got["why"]
    assert row["augment"] == "learned" and row["runners_up"] == "learned τ 1.20 s" and np.isnan(row["shrink"])

    got = _lag._lag_test(Ctx(), 1.0, log=lambda m: None, always_trials=True)
    assert ran == [1] and not got["confirmed"] and got["drop"] > 0.3 and len(got["table"]) == 6

    # A learned slow lag whose trainings through it gain nothing (held-out lags 35, 36:
    # +7.3 % and −1.2 %): the lag is named, the trainings' gain reported as it is.
    flat = {**lagged, (2.0, 0.0): 0.021, (3.0, 0.0): 0.022}
    monkeypatch.setattr(_lag, "_lag_trials", lambda *a, **k: trials(flat))
    monkeypatch.setattr(_lag, "_learned_lag", learned(np.full(10, 2.9)))
    got = _lag._lag_test(Ctx(), 1.0, log=lambda m: None)
    assert got["confirmed"] and got["drop"] < 0.0


# A micro world with the research check's lag (tests/test_discovery.py's base world, a
# fifth of its conditions).
_MICRO = dict(level=8, climb=2, descent=3, turn=2, roll=2, pushover=1, pullup=2, flare=1)


@pytest.mark.check
@pytest.mark.heavy
def test_the_lag_test_runs_end_to_end_on_a_micro_world(monkeypatch, tmp_path):
    # The micro twin of the research check below: the same code path (the learned lag, the
    # trainings through lags against the reference, the report and its table) with a few
    # hundred steps on a fifth of the conditions. Its verdict is not asserted (too few
    # windows); what every lag test writes is.
    from test_discovery import _BASE

    from pvvjax import discovery as D
    from pvvjax.config import ExperimentConfig, TrainConfig, from_dict
    from pvvjax.data.campaign import campaign_from_frames
    from pvvjax.discovery.report import write_discovery
    from pvvjax.synth import SynthConfig, generate

    effects = {**_BASE["effects"], "dynamic_lag": {"params": {"tau_s": 2.0}}}
    camp = campaign_from_frames(*generate(from_dict(SynthConfig, {**_BASE, "counts": _MICRO, "effects": effects,
                                                                  "name": "lag", "seed": 31}))[:2])
    monkeypatch.setattr(_lag, "_LAG_REFERENCE_OFFSETS", ())
    monkeypatch.setattr(_rules, "TRAIN_STRIDE", 16)
    monkeypatch.setattr(_rules, "LAG_TEST_TAUS", (3.0,))
    monkeypatch.setattr(_rules, "LAG_LEARN_STEPS", 100)
    cfg = ExperimentConfig(train=TrainConfig(max_steps=200),
                           discovery=discovery_config(seeds=1, folds=3, proposals=1, max_effects=1, offset_step_s=0.5,
                                                      lag_test=True))
    res = D.discover(camp, cfg, log=lambda m: None, lag_trials=True)
    base, learned, t = res.lag_test.iloc[0], res.lag_test.iloc[1], res.lag_test.iloc[2:].reset_index(drop=True)
    assert base.role == "baseline" and learned.role == "learned" and list(t.tau_s) == [0.0, 3.0]
    assert learned.tau_min_s <= learned.tau_s <= learned.tau_max_s
    assert base["drop"] == pytest.approx(1 - base.ensemble_rms_g / t.ensemble_rms_g[0])
    named_lag = [e.operator for e in res.effects][:1] == ["lag"]
    assert res.final.through_lag == named_lag and (res.final.lag_tau_s == 3.0) == named_lag
    report = write_discovery(res, tmp_path, cfg).read_text()
    assert "## Lag test (round 0)" in report and pd.read_csv(tmp_path / "lag_test.csv").shape == (4, 12)


@pytest.mark.check
def test_discover_names_a_long_lag_first_with_nets_trained_through_it(monkeypatch, tmp_path):
    # A world whose vibration lags its state by 2 s: the lag learned inside one training
    # (τ above lag_slow_s: the slow lag plus the delay and the fast dynamics) names the lag
    # first, and the trainings through it (here τ = 0 at the peak nets' offset against τ = 3 s)
    # add it: the baseline becomes the test's reference window nets, the model carries the
    # lag and trains through it. τ = 3 s, as the benchmark fits on this world (the τ = 2 s
    # trial starts 1 s after the peak nets' 3 s offset and loses to the reference there);
    # every 16th window (every 32nd: too few windows, and the lag loses 5 %).
    from test_discovery import _BASE

    from pvvjax import discovery as D
    from pvvjax.config import ExperimentConfig, TrainConfig, from_dict
    from pvvjax.data.campaign import campaign_from_frames
    from pvvjax.discovery.report import write_discovery
    from pvvjax.synth import SynthConfig, generate

    effects = {**_BASE["effects"], "dynamic_lag": {"params": {"tau_s": 2.0}}}
    # The full-size world (the lag needs its windows: on half the counters it loses 4-7 %).
    camp = campaign_from_frames(*generate(from_dict(SynthConfig, {**_BASE, "counts": {}, "effects": effects,
                                                                  "name": "lag", "seed": 31}))[:2])
    monkeypatch.setattr(_lag, "_LAG_REFERENCE_OFFSETS", ())
    monkeypatch.setattr(_rules, "TRAIN_STRIDE", 16)
    monkeypatch.setattr(_rules, "LAG_TEST_TAUS", (3.0,))
    monkeypatch.setattr(_rules, "LAG_LEARN_STEPS", 600)
    cfg = ExperimentConfig(train=TrainConfig(max_steps=2000),  # the lag's verdict as with 6000, in a third of the steps
                           discovery=discovery_config(seeds=3, proposals=2, max_effects=1, offset_step_s=0.25,
                                                      lag_test=True))
    res = D.discover(camp, cfg, log=lambda m: None)
    js = D.summary(res)
    assert [e["operator"] for e in js["effects"]] == ["lag"], (res.lag_test, res.tries.iloc[0])
    params = js["effects"][0]["parameters"]
    assert params["tau_s"] == 3.0 and 0.0 < js["effects"][0]["p_value"] <= 1.0
    base, learned, t = res.lag_test.iloc[0], res.lag_test.iloc[1], res.lag_test.iloc[2:].reset_index(drop=True)
    assert learned.role == "learned" and learned.tau_min_s <= learned.tau_s <= learned.tau_max_s
    assert learned.tau_s == pytest.approx(params["learned_tau_s"]) and learned.tau_s >= cfg.discovery.lag_test.slow_s
    assert list(t.tau_s) == [0.0, 3.0] and t["drop"][1] >= cfg.discovery.min_shrink
    # The first row: the peak nets the test started from, at their offset (the window nets
    # learn the maneuvers: a lower RMS).
    assert base.role == "baseline" and np.isnan(base.tau_s) and not base.chosen
    assert base.ensemble_rms_g > t.ensemble_rms_g[0] and base["drop"] == pytest.approx(
        1 - base.ensemble_rms_g / t.ensemble_rms_g[0])
    assert res.baseline.through_lag and res.baseline.lag_tau_s == 0.0
    assert res.final.through_lag and res.final.lag_tau_s == 3.0 and res.final.offset_s == t.offset_s[1]
    row = res.tries.iloc[0]
    assert row["round"] == 0 and row.confirmed and row.chosen
    assert row.ensemble_rms_after_g == pytest.approx(t.ensemble_rms_g[1])
    assert res.after["rms_g"] < res.before["rms_g"]
    report = write_discovery(res, tmp_path, cfg).read_text()
    assert "## Lag test (round 0)" in report and "the lag test's reference: window nets" in report
    assert pd.read_csv(tmp_path / "lag_test.csv").shape == (4, 12)
