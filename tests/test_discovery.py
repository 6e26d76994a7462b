"""Discovery workflow: its numerical pieces against brute-force references (metrics, the lag
of window series, a lag's and a knee's least-squares fit, the bootstrap over conditions), what
the model's inputs carry, and end to end through the CLI on a world with nothing missing."""

import json

import numpy as np
import pandas as pd
import pytest
from conftest import discovery_config

from pvvjax import ArgumentError
from pvvjax.analysis.databases import DB_INPUTS
from pvvjax.discovery import (
    Candidate,
    _fits,
    _model,
    _tested,
    _workflow,
    bootstrap_weights,
    carried_by,
    floor_features,
    metrics,
    report,
)

_lag_windows, _Windows = _model._lag_windows, _model._Windows


def _windows(n_counters=3, W=12, seed=0):
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n_counters):
        for k in range(W):
            rows.append(dict(counter=f"C{i}", condition=f"K{i}", maneuver="pullup" if i else "level", window=k,
                             time_s=0.25 * k + 0.01 * rng.random(), measured_g=rng.random(), weight=1.0, i=i, k=k))
    t = pd.DataFrame(rows)
    return _Windows(t, (n_counters, W), (), None)


def test_metrics_against_a_loop():
    win = _windows()
    rng = np.random.default_rng(1)
    pred = rng.random((3, len(win.table)))
    m = metrics(pred, win)
    per = []
    for p in pred:
        t = win.table.assign(p=p)
        rms = np.sqrt(np.mean((t.p - t.measured_g) ** 2))
        pk = np.mean([abs(g.p.max() - g.measured_g.max()) for _, g in t.groupby("counter")])
        ph = np.mean([abs(g.time_s.iloc[g.p.argmax()] - g.time_s.iloc[g.measured_g.argmax()])
                      for _, g in t.groupby("counter") if g.maneuver.iloc[0] == "pullup"])
        per.append((rms, pk, ph))
    np.testing.assert_allclose([m["rms_g"], m["peak_error_g"], m["phase_error_s"]], np.median(per, axis=0), rtol=1e-9)
    ens = win.table.assign(p=np.median(pred, axis=0))
    np.testing.assert_allclose(m["ensemble_rms_g"], np.sqrt(np.mean((ens.p - ens.measured_g) ** 2)), rtol=1e-9)
    assert m["ensemble_rms_g"] < m["rms_g"]  # three random predictions: their median is nearer the mean


def test_lag_of_window_series_is_the_exact_recursion():
    from conftest import lag_loop

    win = _windows()
    x = np.random.default_rng(2).random(len(win.table))
    np.testing.assert_allclose(_lag_windows(x[None], win, 0.7)[0], lag_loop(x, win.table, 0.7), rtol=1e-5)


def test_floor_features_are_what_the_inputs_determine():

    assert {"thrust_coefficient", "blade_loading"} <= set(floor_features(DB_INPUTS["db1"]))
    assert "thrust_coefficient" not in floor_features(DB_INPUTS["db3"])  # db3 has no weight
    assert "thrust_coefficient" not in floor_features(DB_INPUTS["db2"])  # db2 has no load factor


def test_what_inputs_compute_is_what_derive_features_computes_from_them():
    # A derived feature is a function of the channels it depends on (moving one moves it),
    # and of no fewer: the rules `computable` follows, against derive_features itself.
    from pvvjax.data.features import derive_features
    from pvvjax.discovery._model import computable

    state = dict(airspeed_kt=120.0, rotor_rpm=258.0, roll_angle_deg=20.0, pitch_rate_dps=5.0, gross_weight_lb=16000.0,
                 density_ratio=0.9)
    f0 = derive_features(state)
    moved = {ch: derive_features({**state, ch: 1.05 * v + 0.5}) for ch, v in state.items()}
    for feature in ("advance_ratio", "mlf", "thrust_coefficient", "blade_loading"):
        depends = {ch for ch, f in moved.items() if not np.isclose(float(f[feature]), float(f0[feature]), rtol=1e-5)}
        assert feature in computable(depends), feature
        for ch in depends:
            assert feature not in computable(depends - {ch}), (feature, ch)
    assert "roll_angle_deg" not in computable(DB_INPUTS["db1"])  # the MLF is one number of three channels


def test_airspeed_is_determined_by_advance_ratio_and_rotor_speed():
    from pvvjax.data.constants import KT_TO_FT_S, RPM_TO_RAD_S
    from pvvjax.data.features import advance_ratio
    _determined = _model._determined

    rng = np.random.default_rng(0)
    v, rpm = rng.uniform(0, 160, 50), rng.uniform(240, 275, 50)
    mu = np.asarray(advance_ratio(v, rpm))
    # Airspeed back from (μ, Ω) alone: a knee of airspeed is one of the map's own inputs.
    from pvvjax.data.features import UH60A

    np.testing.assert_allclose(mu * rpm * RPM_TO_RAD_S * UH60A.rotor_radius_ft / KT_TO_FT_S, v, rtol=1e-5)
    knee = Candidate("threshold", ("airspeed_kt",), {"knee": 80.0})
    for db in ("db1", "db3"):
        assert "airspeed_kt" in _determined(DB_INPUTS[db]) and "airspeed_kt" not in floor_features(DB_INPUTS[db])
        assert carried_by(knee, DB_INPUTS[db])  # never tested as missing: a misfit's form
    assert "airspeed_kt" not in _determined(("gross_weight_lb", "rotor_rpm"))
    assert not carried_by(knee, ("gross_weight_lb", "rotor_rpm"))
    assert not carried_by(Candidate("rate", ("rotor_rpm",)), DB_INPUTS["db1"])  # a rate is not a window mean


def test_gain_net_learns_a_known_magnification_jointly_with_the_response():
    """y = f(x)·(1 + a·b): the nets with a gain column recover a (the net alone would have
    to learn the interaction of b with every input), and `gain_apply` is the plain net
    times the gain."""
    import jax

    from pvvjax.config import TrainConfig
    from pvvjax.discovery import fit_ensemble, gain_apply
    from pvvjax.nets.networks import mlp_apply

    rng = np.random.default_rng(0)
    n = 240
    x = rng.uniform(-1, 1, (n, 2))
    b = np.exp(-0.5 * (rng.uniform(-3, 3, n) / 0.8) ** 2)  # a band, 0..1
    y = (0.12 + 0.04 * x[:, 0] + 0.03 * x[:, 1] ** 2) * (1.0 + 1.5 * b)
    folds = np.arange(n) % 3
    p = fit_ensemble(np.column_stack([x, b]), y, folds, k=3, seeds=2, hidden=(4,), n_gain=1,
                     train_cfg=TrainConfig(max_steps=3000))
    assert p["gain"].shape == (3, 2, 1)
    np.testing.assert_allclose(np.median(p["gain"]), 1.5, atol=0.15)
    one = jax.tree.map(lambda a: a[0, 0], p)
    xb = np.column_stack([x, b]).astype(np.float32)
    np.testing.assert_allclose(gain_apply(one, xb), mlp_apply(one, xb[:, :2]) * (1 + b * one["gain"][0]), rtol=1e-5)


def test_discovery_json_is_strict_json():
    _json_text = report._json_text

    assert json.loads(_json_text({"p_value": 0.01}, "out/discovery.json")) == {"p_value": 0.01}
    with pytest.raises(ValueError, match="out/discovery.json: a value is not a finite number"):
        _json_text({"effects": [{"p_value": float("nan")}]}, "out/discovery.json")


def test_a_misspelt_excluded_channel_is_an_error_naming_it_not_a_candidate_left_in():
    from conftest import tiny_records

    from pvvjax.config import ExperimentConfig
    from pvvjax.data.campaign import campaign_from_frames
    from pvvjax.discovery import discover

    camp = campaign_from_frames(*tiny_records(n_counters=4))
    excluded = ("longitudinal_pct", "longitudnal_pct")
    cfg = ExperimentConfig(discovery=discovery_config(folds=3, exclude_channels=excluded))
    with pytest.raises(ValueError, match=r"discovery.exclude_channels: \['longitudnal_pct'\] are not candidate "
                                         r"channels of campaign <memory> \(channels and derived features: .*'mlf'"):
        discover(camp, cfg, log=lambda m: None)


def test_discover_takes_a_campaign_folder_and_a_bare_discovery_config(tmp_path, monkeypatch):
    # The Python API as the CLI: a folder is loaded (and names the campaign), a DiscoveryConfig
    # stands for an ExperimentConfig with it; anything else is a TypeError naming what it got.
    from conftest import write_tiny

    from pvvjax import discovery as D
    from pvvjax.config import ExperimentConfig

    folder = write_tiny(tmp_path / "c")
    seen = []
    monkeypatch.setattr(_workflow, "_context", lambda campaign, cfg, log: seen.append((campaign, cfg)) or 1 / 0)
    with pytest.raises(ZeroDivisionError):
        D.discover(folder, discovery_config(folds=3), log=lambda m: None)
    campaign, cfg = seen[0]
    assert len(campaign) == 2 and campaign.source == str(folder)
    assert cfg == ExperimentConfig(discovery=discovery_config(folds=3))
    with pytest.raises(ArgumentError, match=r"discover: cfg = \{'folds': 3\}: must be an ExperimentConfig or a Disc"):
        D.discover(folder, {"folds": 3})
    with pytest.raises(ArgumentError, match="discover: campaign = .*: must be a Campaign or a campaign folder"):
        D.discover([folder])


def test_a_gains_column_is_its_band_in_units_of_its_gain_unit():
    # The nets train a gain column of u·band as a gain in steps of 1/u (u = gain_unit): a
    # named band in steps of GAIN_UNIT, a band without a unit in 1.
    from pvvjax.discovery import Model
    _inputs = _model._inputs

    win = _windows()
    rng = np.random.default_rng(2)
    win.table["beta"], win.table["rpm"] = rng.random(len(win.table)), rng.random(len(win.table))
    vals = {"beta": win.table.beta.to_numpy(), "rpm": win.table.rpm.to_numpy()}
    win.values = lambda c: vals[c.channels[0]]
    extra = Candidate("input", ("beta",))
    band = lambda **p: Candidate("resonance", ("rpm",), {"center": 0.5, "width": 0.1, **p})  # noqa: E731
    x = _inputs(Model({}, ("i",), extra=(extra,), gains=(band(gain_unit=10.0), band())), win)
    np.testing.assert_array_equal(x, np.column_stack([win.table.i, vals["beta"], 10.0 * vals["rpm"], vals["rpm"]]))
    assert _tested.GAIN_UNIT == 10.0


# --------------------------------------------------------------------------- end to end
# The hidden-effect case runs in notebooks/discovery.py; the null case here, through the CLI.

# A true null for db1: the base world without the terms db1's inputs cannot express (the
# measured load factor, the rate terms, the 0.6 s lag, the rotor-speed resonance).
_BASE = dict(maneuvers=("level", "climb", "descent", "turn", "roll", "pushover", "pullup", "flare"),
             counts=dict(level=40, climb=10, descent=13, turn=8, roll=6, pushover=4, pullup=6, flare=3),
             load_factor="kinematic",
             effects={"roll_rate": {"enabled": False}, "pitch_rate": {"enabled": False},
                      "rotor_resonance": {"enabled": False}, "dynamic_lag": {"enabled": False}})


@pytest.mark.check
@pytest.mark.heavy
def test_cli_discovers_on_a_micro_world_and_writes_its_summary_and_report(tmp_path):
    # The micro twin of the research check below: the same command on a fifth of the null
    # world's conditions with a few hundred training steps. What it names is not asserted
    # (too few peaks for a verdict); what it writes is.
    from pvvjax.cli import main
    from pvvjax.config import from_dict
    from pvvjax.data.campaign import write_campaign
    from pvvjax.synth import SynthConfig, generate

    micro = dict(level=8, climb=2, descent=3, turn=2, roll=2, pushover=1, pullup=2, flare=1)
    counters, records, _ = generate(from_dict(SynthConfig, {**_BASE, "counts": micro, "name": "null", "seed": 51}))
    folder = write_campaign(tmp_path / "campaign", counters, records)
    (tmp_path / "cfg.toml").write_text("[train]\nmax_steps = 200\n[discovery]\nmax_effects = 1\n"
                                       "[discovery.ensemble]\nseeds = 1\nfolds = 3\n"
                                       "[discovery.offset]\nstep_s = 0.5\n")
    assert main(["discover", "--campaign", str(folder), "--out", str(tmp_path / "out"),
                 "--config", str(tmp_path / "cfg.toml")]) == 0
    js = json.loads((tmp_path / "out" / "discovery.json").read_text())
    assert set(js) == {"campaign", "baseline", "effects", "augmented", "gap_shrink", "level", "capacity", "nuisance"}
    kinds = [e["kind"] for e in js["effects"]]
    assert all(kinds.count(k) <= 1 for k in ("missing", "history", "misfit"))  # max_effects of each kind
    assert set(js["baseline"]["metrics"]) == {"rms_g", "peak_error_g", "phase_error_s"}
    report = (tmp_path / "out" / "report.md").read_text()
    assert "figures/residual_map.png" in report and (tmp_path / "out" / "figures" / "residual_map.png").exists()


@pytest.mark.check
def test_cli_on_a_true_null_writes_its_summary_and_every_name_carries_its_test(tmp_path):
    # Whether a null names nothing is a rate over many worlds at the stated level (the
    # benchmark's, research/discovery-benchmark.md; the simulation lane's check below runs the
    # exact law as the baseline); here, one world through the command: what it writes, and
    # that anything named passed the test at the level, with its kind and intervals.
    from pvvjax.cli import main
    from pvvjax.config import from_dict
    from pvvjax.data.campaign import write_campaign
    from pvvjax.synth import SynthConfig, generate

    counters, records, _ = generate(from_dict(SynthConfig, {**_BASE, "name": "null", "seed": 51}))
    folder = write_campaign(tmp_path / "campaign", counters, records)
    (tmp_path / "cfg.toml").write_text("[discovery]\nmax_effects = 1\n[discovery.ensemble]\nseeds = 3\n"
                                       "[discovery.offset]\nstep_s = 0.25\n")
    assert main(["discover", "--campaign", str(folder), "--out", str(tmp_path / "out"),
                 "--config", str(tmp_path / "cfg.toml")]) == 0
    js = json.loads((tmp_path / "out" / "discovery.json").read_text())
    assert set(js) == {"campaign", "baseline", "effects", "augmented", "gap_shrink", "level", "capacity", "nuisance"}
    assert js["level"] == 0.05
    assert set(js["capacity"]) == {"statistic", "p_value", "misfit", "carried", "tied_with_misfit"}
    for e in js["effects"]:
        assert e["adjusted_p"] < js["level"] and e["kind"] in ("missing", "history", "misfit") and "intervals" in e
    # Every round of the history and missing kinds reports its learners' out-of-fold skill,
    # none below the mean's.
    assert js["nuisance"] and all(r["residual_skill"] >= 0 and r["candidates_min_skill"] >= 0
                                  for r in js["nuisance"])
    assert {r["kind"] for r in js["nuisance"]} <= {"history", "missing"}
    assert set(js["baseline"]["metrics"]) == {"rms_g", "peak_error_g", "phase_error_s"}
    report = (tmp_path / "out" / "report.md").read_text()
    assert "figures/residual_map.png" in report and (tmp_path / "out" / "figures" / "residual_map.png").exists()
    assert "## The tests, by round" in report


def _steps(n_counters=8, W=80, seed=4):
    """Counters of steady levels, every other one with a step at its 30th window."""
    win = _windows(n_counters=n_counters, W=W, seed=seed)
    rng = np.random.default_rng(seed + 1)
    level = rng.uniform(0.05, 0.15, n_counters)[win.table.i.to_numpy()]
    return win, level + 0.08 * ((win.table.k.to_numpy() >= 30) & (win.table.i.to_numpy() % 2 == 1))


@pytest.mark.parametrize("tau", [0.7, 4.0, 9.0])
def test_a_lags_time_constant_is_fitted_between_the_grid_points(tau):
    # The measurement lags the prediction by τ: from the nearest point of the lag candidates'
    # grid (a factor √2 apart) the fit finds τ, a 4 s or 9 s lag as well as a fast one, and
    # stays within a factor 2 of where it started.
    win, signal = _steps()
    meas = _lag_windows(signal[None], win, tau)[0]
    rows = np.ones(len(signal), bool)
    grid = np.asarray(_tested.LAG_TAUS)
    start = float(grid[np.argmin(np.abs(np.log(grid / tau)))])
    assert _fits.fit_lag(signal, meas, win, rows, start) == pytest.approx(tau, rel=1e-2)
    w = bootstrap_weights(win.table.condition.to_numpy(), 1, 0)[0]
    assert _fits.fit_lag(signal, meas, win, rows, start, weights=w) == pytest.approx(tau, rel=1e-2)
    with pytest.warns(UserWarning, match="stopped at its search bound"):  # its cell, and said so
        assert _fits.fit_lag(signal, meas, win, rows, tau / 5) <= 2 * tau / 5 + 1e-6


def test_a_knee_is_refined_from_a_grid_neighbour_and_weights_of_one_change_nothing():
    rng = np.random.default_rng(0)
    x = rng.uniform(0, 100, 600)
    resid = 0.002 * np.maximum(x - 63.0, 0) + 0.01 * rng.standard_normal(600)
    cands = pd.DataFrame({"x:collective_pct": x})
    grid = Candidate("threshold", ("collective_pct",), {"knee": 55.0, "above": True, "softness": 1.0})
    fitted = _fits._refine(grid, resid, cands, np.ones(600))
    assert fitted.parameters["knee"] == pytest.approx(63.0, abs=2.0)
    same = _fits._refine(grid, resid, cands, np.ones(600), weights=np.ones(600))
    assert same.parameters["knee"] == pytest.approx(fitted.parameters["knee"], rel=1e-5)
    # A knee the fit pushes beyond the bulk of the channel is not a knee: the grid's is kept.
    flat = 0.01 * rng.standard_normal(600) + 0.001 * x
    edge = Candidate("threshold", ("collective_pct",), {"knee": 97.0, "above": True, "softness": 1.0})
    with pytest.warns(UserWarning, match="beyond the 2-98 % range of collective_pct"):  # and said so
        assert _fits._refine(edge, flat, cands, np.ones(600)).parameters["knee"] == 97.0


def test_a_band_stopped_at_its_search_bound_is_warned_about():
    # The residual's band sits two widths above the test's grid point: the fit moves the centre
    # by one width at most, and says it stopped there.
    from pvvjax.discovery.effects import band

    rng = np.random.default_rng(1)
    x = rng.uniform(240.0, 280.0, 800)
    pred = np.full(800, 0.1)
    resid = 0.5 * pred * band((x - 267.0) / 1.0, "gaussian", np) + 0.002 * rng.standard_normal(800)
    grid = Candidate("resonance", ("rotor_rpm",), {"center": 265.0, "width": 1.0})
    with pytest.warns(UserWarning, match="stopped at its search bound"):
        fitted = _fits._refine(grid, resid, pd.DataFrame({"x:rotor_rpm": x}), pred)
    assert fitted.parameters["center"] == pytest.approx(266.0, abs=0.05)  # 265 + one width


def test_bootstrap_weights_deal_whole_conditions_with_replacement():
    groups = np.repeat(["a", "b", "c", "d", "e"], [3, 1, 4, 2, 5])
    w = bootstrap_weights(groups, 200, 0)
    assert w.shape == (200, len(groups))
    for draw in w:  # one weight per condition, the units drawn summing to their count
        per = pd.Series(draw).groupby(groups).agg(["min", "max"])
        assert (per["min"] == per["max"]).all()
        assert per["min"].sum() == 5
    assert np.allclose(w.mean(axis=0), 1.0, atol=0.2)
    np.testing.assert_array_equal(w, bootstrap_weights(groups, 200, 0))  # determinism


def test_the_lag_candidates_span_slow_lags_and_are_the_lagged_prediction_minus_it():
    from conftest import lag_loop

    win = _windows()
    yhat = np.random.default_rng(3).random(len(win.table))
    cands, cols = _tested.response_candidates(yhat, win)
    taus = [c.parameters["tau_s"] for c in cands]
    assert min(taus) <= 0.25 and max(taus) >= 8.0 and all(c.operator == "lag" for c in cands)
    np.testing.assert_allclose(cols[:, 4], lag_loop(yhat, win.table, taus[4]) - yhat, rtol=1e-4, atol=1e-6)


@pytest.fixture(scope="module")
def slow_lag_discovery():
    """Discovery on a true null for db1 with a 4 s lag of the vibration behind the state
    (beyond where the retired lag grid stopped)."""
    from pvvjax.config import ExperimentConfig, from_dict
    from pvvjax.data.campaign import campaign_from_frames
    from pvvjax.discovery import discover
    from pvvjax.synth import SynthConfig, generate

    effects = {**_BASE["effects"], "slow_lag": {"enabled": True, "params": {"tau_s": 4.0}}}
    counters, records, _ = generate(from_dict(SynthConfig, {**_BASE, "name": "slow-lag", "seed": 52,
                                                            "effects": effects}))
    return discover(campaign_from_frames(counters, records, source="slow-lag"),
                    ExperimentConfig(discovery=discovery_config(seeds=3, offset_step_s=0.25)), log=lambda m: None)


def _first_response(res):
    return next((e for e in res.effects if e.kind == "history"), None)


@pytest.mark.check
def test_a_slow_lag_is_named_first_as_a_history_misfit_with_its_interval(slow_lag_discovery):
    # A lag of the prediction is a response the baseline lacks, a form of its inputs' history,
    # never a missing input; nothing is named missing on this world.
    first = _first_response(slow_lag_discovery)
    assert first is not None, [e.name for e in slow_lag_discovery.effects]
    assert first.operator == "lag", [e.name for e in slow_lag_discovery.effects]
    assert [e for e in slow_lag_discovery.effects if e.kind == "missing"] == []
    lo, hi = first.intervals["tau_s"]  # the same fit over a bootstrap of conditions holds it
    tau = first.parameters["tau_s"]
    assert lo * (1 - 1e-6) <= tau <= hi * (1 + 1e-6)


@pytest.mark.check
@pytest.mark.xfail(strict=True, reason="#96 item 4: a named lag's τ is fitted within a factor 2 of the grid point the "
                                       "test named; the 4 s lag is named as history at the grid's 1 s and its fit "
                                       "stops at the cell's bound, 2 s")
def test_a_slow_lags_time_constant_is_within_20_percent(slow_lag_discovery):
    assert _first_response(slow_lag_discovery).parameters["tau_s"] == pytest.approx(4.0, rel=0.2)


@pytest.mark.check
@pytest.mark.parametrize("hidden", [False, True])
def test_the_users_own_simulation_is_a_baseline_and_what_it_lacks_is_named(hidden):
    # A simulation that is the world's law without noise (the generator's own, taking the
    # channels its law uses) leaves nothing to name but what the world adds to it: a hidden
    # sideslip effect is named, beyond any function of the simulation's inputs; without it,
    # nothing missing is named.
    from conftest import SMALL_COUNTS, research

    from pvvjax.config import ExperimentConfig, TrainConfig, from_dict
    from pvvjax.data.campaign import campaign_from_frames
    from pvvjax.discovery import discover
    from pvvjax.synth import SynthConfig, generate

    wt = research("world_truth")
    effects = {**_BASE["effects"], **({"sideslip": {"enabled": True, "scale": 6.0}} if hidden else {})}
    world = from_dict(SynthConfig, {**_BASE, "counts": SMALL_COUNTS, "name": "sim", "seed": 53, "effects": effects})
    counters, records, _ = generate(world)
    records = wt.with_simulation(world, records, spread=0.0)  # the base law, planted effects left out
    inputs = ["airspeed_kt", "rotor_rpm", "gross_weight_lb", "density_ratio", "roll_angle_deg", "pitch_rate_dps",
              "climb_rate_fpm"]
    d = discovery_config(folds=5, simulation=wt.SIMULATION_COLUMN, simulation_inputs=inputs)
    res = discover(campaign_from_frames(counters, records, source="sim"),
                   ExperimentConfig(train=TrainConfig(max_steps=100), discovery=d), log=lambda m: None)
    missing = [e for e in res.effects if e.kind == "missing"]
    if hidden:
        assert missing and any("sideslip" in k for k in (missing[0].key, *missing[0].tied)), [e.name for e in missing]
        assert res.after["rms_g"] < res.before["rms_g"]
    else:
        assert missing == [], [e.name for e in missing]
    assert res.database == f"simulation:{wt.SIMULATION_COLUMN}" and res.baseline.params == {}


def test_a_simulation_takes_a_named_lag_and_a_named_channel_fitted_out_of_fold():
    # measured = the simulation lagged by 2 s, plus 0.3 per unit of a channel it lacks: with
    # both named, the simulation after matches the measured level within the noise, its
    # linear term fitted on the other folds' conditions only.
    from types import SimpleNamespace

    from pvvjax.discovery._explain import Named
    from pvvjax.discovery._simulation import simulated_after

    win, sim = _steps(n_counters=12)
    rng = np.random.default_rng(7)
    x = rng.standard_normal(12)[win.table.i.to_numpy()]
    win._cands = pd.DataFrame({"x:beta": x})
    noise = 0.002 * rng.standard_normal(len(x))
    win.table["measured_g"] = _lag_windows(sim[None], win, 2.0)[0] + 0.3 * x + noise
    ctx = SimpleNamespace(counter_fold=np.arange(12) % 3)
    named = lambda c: _tested.Fitted(Named(c, 1, 5.0, 0.0, 0.0, 1.0), c, {})  # noqa: E731
    lag, beta = Candidate("lag", (), {"tau_s": 2.0}), Candidate("input", ("beta",))
    after = simulated_after(ctx, win, sim[None], (named(lag), named(beta)))[0]
    assert np.sqrt(np.mean((after - win.table.measured_g) ** 2)) < 0.004
    only_lag = simulated_after(ctx, win, sim[None], (named(lag),))[0]
    np.testing.assert_allclose(only_lag, _lag_windows(sim[None], win, 2.0)[0])


def test_a_misfit_joins_the_model_as_an_out_of_fold_linear_term_without_retraining():
    # measured = prediction + 0.3 × a form of the inputs: the misfit's form becomes the model's
    # linear term (the nets are not retrained: no context to train with is needed), and its
    # shift on one fold's conditions does not move when that fold's measured level changes.
    from types import SimpleNamespace

    from pvvjax.discovery._explain import Named

    win, y = _steps(n_counters=12)
    rng = np.random.default_rng(3)
    x = rng.standard_normal(12)[win.table.i.to_numpy()]
    win._cands = pd.DataFrame({"x:airspeed_kt": x})
    win.table["measured_g"] = y + 0.3 * x + 0.002 * rng.standard_normal(len(x))
    form = Candidate("input", ("airspeed_kt",))
    base = _model.Model({"w": 1}, ("airspeed_kt",), offset_s=0.4)
    fitted = _tested.Fitted(Named(form, 1, 5.0, 0.0, 0.0, 1.0, kind="misfit"), form, {})
    final = _tested.with_effects(None, base, (fitted,))
    assert final.linear == (form,) and final.params is base.params and final.extra == ()
    ctx = SimpleNamespace(counter_fold=np.arange(12) % 3)
    shift = _tested.linear_shift(ctx, win, y, final.linear)
    assert np.sqrt(np.mean((y + shift - win.table.measured_g) ** 2)) < 0.004
    fold0 = ctx.counter_fold[win.table.i.to_numpy()] == 0
    win.table.loc[fold0, "measured_g"] += 1.0
    np.testing.assert_array_equal(_tested.linear_shift(ctx, win, y, final.linear)[fold0], shift[fold0])


def test_an_optional_channel_missing_in_one_record_is_left_out_of_the_candidates_by_name():
    # One flight whose logger did not record nz_g, and one whose columns come in another order: discovery
    # used to refuse the campaign ("channels differ"); the channel is now warned about by name and left out of
    # the candidates, and every record keeps its place.
    from conftest import tiny_records

    from pvvjax.config import ExperimentConfig
    from pvvjax.data.campaign import CampaignWarning, campaign_from_frames
    from pvvjax.discovery import channels_lacking, window_table

    counters, records = tiny_records(n_counters=4)
    for k in records:
        records[k]["nz_g"] = 1.0
    records["C2"] = records["C2"].drop(columns=["nz_g"])
    records["C3"] = records["C3"][records["C3"].columns[::-1]]
    camp = campaign_from_frames(counters, records)
    assert channels_lacking(camp, camp.names) == {"nz_g": ["C2"]}
    iv = pd.DataFrame(dict(counter=["C1", "C2", "C3", "C4"], t0=1.0, t1=3.0))
    table = window_table(camp, iv)
    assert "x:nz_g" not in table and "x:airspeed_kt" in table and table.notna().all().all()
    np.testing.assert_allclose(table["x:airspeed_kt"], [100.0, 101.0, 102.0, 103.0], rtol=1e-12)
    cfg = ExperimentConfig(discovery=discovery_config(folds=3))
    with pytest.warns(CampaignWarning, match=r"nz_g is missing in 1 counter\(s\) \(C2\): not candidates"):
        _workflow._context(camp, cfg, lambda m: None)
