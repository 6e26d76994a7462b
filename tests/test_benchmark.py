"""Scoring of the hidden-effect benchmark (research/discovery_benchmark.py): the
attributable shrink against the right reference. The discovery runs themselves are tested
in test_discovery.py and the discovery notebook."""

import importlib.util
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from pvvjax.config import to_dict

ROOT = Path(__file__).parents[1]


@pytest.fixture(scope="module")
def bench():
    path = ROOT / "research" / "discovery_benchmark.py"
    spec = importlib.util.spec_from_file_location("discovery_benchmark", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _baseline(rms, peak=0.03):  # the ensemble's RMS 10 % below the seeds' median
    return SimpleNamespace(before=dict(rms_g=rms, peak_error_g=peak, phase_error_s=4.0, ensemble_rms_g=0.9 * rms),
                           baseline=SimpleNamespace(through_lag=False), lag_test=None)


def _row(scenario, rms_before, rms_after, lag_baseline=False, gap_metric="rms_g", ensemble=None):
    ens = ensemble or (0.9 * rms_before, 0.9 * rms_after)
    return dict(scenario=scenario, seed=1, hidden="x", rms_before_g=rms_before, rms_after_g=rms_after, region="",
                ensemble_before_g=ens[0], ensemble_after_g=ens[1],
                lag_baseline=lag_baseline, gap_metric=gap_metric, peak_before_g=0.04, peak_after_g=0.035,
                phase_before_s=4.0, phase_after_s=4.0)


def test_attributable_shrink_is_against_the_null_of_the_seed_or_the_scenarios_own_reference(bench):
    rows = pd.DataFrame([
        _row("effect", 0.060, 0.050),                  # gap 0.02 over the null's 0.04: closes half
        _row("missing-input", 0.050, 0.045),           # against its own reference (0.045): closes all
        _row("below-null", 0.035, 0.034),              # before under the null's: no gap to attribute
        _row("lagged", 0.060, 0.050, lag_baseline=True),  # reference nets of a lag test the null never ran
        _row("peaks", 0.060, 0.050, gap_metric="peak_error_g"),
        # the ensemble's gap 0.054 - 0.036, closed by 0.009; the seeds' RMS did not move
        _row("ensemble", 0.060, 0.060, gap_metric="ensemble_rms_g", ensemble=(0.054, 0.045)),
    ])
    out = bench.attributable(rows, {1: _baseline(0.040)}, {"missing-input": _baseline(0.045)})
    got = dict(zip(out.scenario, out.attributable_shrink))
    assert got["effect"] == pytest.approx(0.5) and got["missing-input"] == pytest.approx(1.0)
    assert np.isnan(got["below-null"]) and np.isnan(got["lagged"])
    assert got["peaks"] == pytest.approx((0.04 - 0.035) / (0.04 - 0.03))  # on the peak error
    assert dict(zip(out.scenario, out.rms_null_g))["missing-input"] == 0.045
    assert got["ensemble"] == pytest.approx(0.5) and dict(zip(out.scenario, out.attributable_rms))["ensemble"] == 0.0
    assert dict(zip(out.scenario, out.attributable_ensemble))["effect"] == pytest.approx(0.5)


def test_a_null_whose_lag_test_confirmed_is_measured_by_the_nets_of_the_scenarios_kind(bench):
    # The seed-46 null: its lag test confirmed, so its `before` is the test's window reference
    # (0.0207 g), not the peak nets that the seed's roll-rate world starts from. A scenario
    # without a lag baseline takes the null's "baseline" row of the lag table; a lag-baseline
    # scenario its reference, which is then the null's `before`.
    table = pd.DataFrame([
        dict(role="baseline", chosen=False, rms_g=0.045, peak_error_g=0.03, phase_error_s=4.0, ensemble_rms_g=0.040),
        dict(role="reference", chosen=True, rms_g=0.028, peak_error_g=0.02, phase_error_s=1.5, ensemble_rms_g=0.021),
        dict(role="slow", chosen=True, rms_g=0.025, peak_error_g=0.02, phase_error_s=1.1, ensemble_rms_g=0.019)])
    null = SimpleNamespace(before=dict(rms_g=0.028, peak_error_g=0.02, phase_error_s=1.5, ensemble_rms_g=0.021),
                           baseline=SimpleNamespace(through_lag=True), lag_test=table, windows=None)
    rows = pd.DataFrame([_row("effect", 0.060, 0.050, gap_metric="ensemble_rms_g", ensemble=(0.050, 0.045)),
                         _row("lagged", 0.040, 0.030, lag_baseline=True)])
    out = bench.attributable(rows, {1: null}).set_index("scenario")
    assert out.loc["effect", "ensemble_null_g"] == 0.040
    assert out.loc["effect", "attributable_shrink"] == pytest.approx(0.5)  # not (0.05 - 0.045) / (0.05 - 0.021)
    assert out.loc["lagged", "rms_null_g"] == 0.028
    # A table written before the baseline row: no reference, no attributable shrink (not a wrong one).
    null.lag_test = table[table.role != "baseline"]
    assert np.isnan(bench.attributable(rows, {1: null}).set_index("scenario").loc["effect", "attributable_shrink"])


def test_the_nulls_of_the_lag_scenarios_seeds_run_the_trainings_through_lags(bench, monkeypatch):
    # A lag scenario's gap is measured by its null's window nets (the lag test's reference
    # row, above), which discover trains only where it confirms a lag, unless told to.
    scenarios, overrides = bench.scenario_configs(ROOT / "research" / "configs" / "benchmark.toml", 3)
    by = {s["name"]: s for s in scenarios}
    assert [s["name"] for s in scenarios if s["lag_trials"]] == ["null-31"]
    assert by["null-31"]["seed"] == by["long-lag"]["seed"] == 34
    seen = []
    monkeypatch.setattr(bench, "_campaign", lambda synth: None)
    monkeypatch.setattr(bench, "discover", lambda campaign, cfg, **kw: seen.append((cfg.discovery, kw)) or 1 / 0)
    for name in ("null-31", "null-41"):
        with pytest.raises(ZeroDivisionError):
            bench.run_scenario(by[name], overrides, None)
    assert [kw["lag_trials"] for _, kw in seen] == [True, False] and all(d.lag_test.enabled for d, _ in seen)


def test_the_weight_scenarios_reference_is_its_world_without_the_weights_effect(bench):
    scenarios, _ = bench.scenario_configs(ROOT / "research" / "configs" / "benchmark.toml", 2)
    (weight,) = [s for s in scenarios if s["reference_world"] is not None]
    # its world is the null world of its seed: nothing hidden in the generator, db3 lacks the weight
    (null,) = [s for s in scenarios if s["truth"] is None and s["seed"] == weight["seed"]]
    assert weight["synth"].effects == null["synth"].effects and weight["seed"] == 43
    assert weight["database"] == "db3"
    # the reference: the same campaign, the vibration seeing one weight
    ref = weight["reference_world"]
    assert ref.vibration_weight_lb == 18000.0 and weight["synth"].vibration_weight_lb is None
    assert to_dict(ref) == {**to_dict(weight["synth"]), "name": ref.name, "vibration_weight_lb": 18000.0}
    assert weight["reference_label"] == "vibration_weight_lb = 18000"


def test_an_update_replaces_its_scenarios_rows_and_keeps_the_others(bench, tmp_path):
    from conftest import discovery_config

    from pvvjax.config import ExperimentConfig
    from pvvjax.io import write_table

    old = pd.DataFrame(dict(scenario=["null-1", "a", "b"], seed=[1, 1, 2], x=[1.0, 2.0, 3.0]))
    new = pd.DataFrame(dict(scenario=["c", "a"], seed=[3, 1], x=[9.0, 8.0], y=[0.5, 0.6]))
    got = bench.merged(old, new)
    assert list(got.scenario) == ["null-1", "a", "b", "c"] and list(got.x) == [1.0, 8.0, 3.0, 9.0]
    assert np.isnan(got.y[0]) and got.y[1] == 0.6
    # only into results of the same settings
    cfg = ExperimentConfig(discovery=discovery_config(lag_test=True))
    write_table(old, tmp_path / "results", cfg)
    pd.testing.assert_frame_equal(bench._previous(tmp_path / "results.parquet", cfg), old)
    with pytest.raises(SystemExit, match="other settings"):
        bench._previous(tmp_path / "results.parquet", ExperimentConfig(discovery=discovery_config(lag_test=False)))
    with pytest.raises(SystemExit, match="no results to update"):
        bench._previous(tmp_path / "none.parquet", cfg)
    # a hidden scenario measured against a null needs that null beside it
    scenarios, _ = bench.scenario_configs(ROOT / "research" / "configs" / "benchmark.toml")
    by = {s["name"]: s for s in scenarios}
    bench._check_update([by["weight-missing-db3"]])  # its own reference world
    bench._check_update([by["null-41"], by["roll-rate"]])
    with pytest.raises(SystemExit, match=r"roll-rate \(seed 41\) need the null"):
        bench._check_update([by["roll-rate"], by["null-31"]])


def test_a_resumed_run_reads_back_the_finished_scenarios_and_scores_as_an_uninterrupted_one(bench, tmp_path,
                                                                                             monkeypatch):
    from pvvjax.io import write_table

    overrides = dict(lag_test=dict(enabled=False))
    scenarios = [dict(name=n, seed=1, database="db1", truth=t, reference_world=None)
                 for n, t in [("null-1", None), ("a", dict(effect="x")), ("b", dict(effect="y"))]]
    values = {"null-1": (0.040, 0.040), "a": (0.050, 0.042), "b": (0.060, 0.045)}
    ran = []

    def fake_run(sc, overrides, out, fail_on=None):
        ran.append(sc["name"])
        if sc["name"] == fail_on:
            raise KeyboardInterrupt
        folder = out / sc["name"]
        windows = pd.DataFrame(dict(counter=["c"], window=[0], measured_g=[0.1], predicted_before_g=[0.09]))
        write_table(windows, folder / "windows", bench.scenario_config(sc, overrides))
        row = _row(sc["name"], *values[sc["name"]]) | dict(hidden=sc["truth"]["effect"] if sc["truth"] else "none",
                                                           named="", operator="", seconds=1.0, generate_s=0.5,
                                                           correct_first=True)
        return row, bench._scored(_baseline(values[sc["name"]][0]).before, False, folder), None

    monkeypatch.setattr(bench, "identifiability", lambda res, null: dict(truth_gain=res.before["rms_g"]))
    monkeypatch.setattr(bench, "run_scenario", fake_run)
    whole = bench.run_all(scenarios, overrides, tmp_path / "whole")
    monkeypatch.setattr(bench, "run_scenario", lambda *a: fake_run(*a, fail_on="b"))
    with pytest.raises(KeyboardInterrupt):
        bench.run_all(scenarios, overrides, tmp_path / "cut")
    ran.clear()
    monkeypatch.setattr(bench, "run_scenario", fake_run)
    again = bench.run_all(scenarios, overrides, tmp_path / "cut", resume=True)
    assert ran == ["b"]  # null-1 and a read back from partial.csv and their folders
    pd.testing.assert_frame_equal(again, whole, check_dtype=False)
    assert again.set_index("scenario").loc["a", "attributable_shrink"] == pytest.approx(0.8)  # against null-1
    # only a run of the same settings goes on
    with pytest.raises(SystemExit, match="other settings"):
        bench.run_all(scenarios, dict(lag_test=dict(enabled=True)), tmp_path / "cut", resume=True)


def test_a_saved_reference_baseline_reads_back_as_the_scoring_needs_it(bench, tmp_path, monkeypatch):
    from pvvjax.io import write_table

    windows = pd.DataFrame(dict(counter=["c"], window=[0], measured_g=[0.1], predicted_before_g=[0.09]))
    lag = pd.DataFrame(dict(role=["baseline"], chosen=[False], rms_g=[0.05]))
    before = dict(rms_g=np.float64(0.05), peak_error_g=0.03, phase_error_s=4.0, ensemble_rms_g=0.045,
                  rms_by_seed=np.array([0.05, 0.051]))  # as discover's metrics hold it
    ref = SimpleNamespace(before=before, baseline=SimpleNamespace(through_lag=np.bool_(False)), lag_test=lag,
                          windows=windows)

    def write(res, folder):  # the files write_discovery writes that the scoring reads
        write_table(res.windows, folder / "windows")
        res.lag_test.to_csv(folder / "lag_test.csv", index=False)

    monkeypatch.setattr(bench, "write_discovery", write)
    bench._save_reference(ref, tmp_path / "reference")
    got = bench._load_reference(tmp_path / "reference")
    assert got.before == dict(rms_g=0.05, ensemble_rms_g=0.045, peak_error_g=0.03, phase_error_s=4.0)
    assert got.baseline.through_lag is False
    pd.testing.assert_frame_equal(got.windows, windows)
    pd.testing.assert_frame_equal(got.lag_test, lag)
    assert bench._load_reference(tmp_path / "none") is None


def test_by_scenario_counts_each_scenarios_worlds_over_the_seed_offsets(bench):
    def t(named_ok, attr, secs):
        return pd.DataFrame(dict(scenario=["null-1", "lag", "mode"], hidden=["none", "dynamic_lag", "rotor_resonance"],
                                 correct_first=named_ok, attributable_shrink=attr, seconds=secs))

    tables = {0: bench._blank(t([True, True, False], [np.nan, 0.8, 0.0], [100.0, 200.0, 300.0])),
              1: bench._blank(t([False, True, True], [np.nan, np.nan, 0.4], [110.0, 220.0, 330.0])),
              2: bench._blank(t([True, True, True], [np.nan, 0.6, 0.7], [120.0, 240.0, 360.0]))}
    got = bench.by_scenario(tables).set_index("scenario")
    assert list(got.index) == ["null-1", "lag", "mode"]  # the config's order
    assert got.loc["null-1", "right_first"] == "2 / 3" and got.loc["null-1", "attributable_at_least_half"] == ""
    assert got.loc["lag", "right_first"] == "3 / 3" and got.loc["lag", "attributable_at_least_half"] == "2 / 3"
    assert got.loc["lag", "gap_measured"] == "2 / 3"  # a world without a gap counts below 0.5
    assert got.loc["lag", "median_attributable"] == pytest.approx(0.7)
    assert got.loc["mode", "right_first"] == "2 / 3" and got.loc["mode", "attributable_at_least_half"] == "1 / 3"
    assert got.loc["mode", "median_attributable"] == pytest.approx(0.4)
    assert got.loc["mode", "median_seconds"] == 330 and np.isnan(got.loc["null-1", "median_attributable"])


def test_find_scenario_shifts_the_seed_and_names_the_scenarios_of_an_unknown_one(bench):
    config = ROOT / "research" / "configs" / "benchmark.toml"
    base, _ = bench.find_scenario(config, 0, "long-lag")
    shifted, overrides = bench.find_scenario(config, 3, "long-lag")
    assert shifted["seed"] == base["seed"] + 3 and overrides == bench.scenario_configs(config, 3)[1]
    with pytest.raises(SystemExit, match="unknown scenario 'nope'; one of null-31, .*long-lag"):
        bench.find_scenario(config, 0, "nope")


def test_remeasured_worlds_are_counted_beside_the_tables_own(bench, tmp_path):
    def rows(new, old):
        return pd.DataFrame(dict(scenario=["lag", "mode"], attributable=new, table_attributable=old))

    (tmp_path / "seed+2").mkdir()
    rows([0.9, 0.6], [np.nan, 0.4]).to_csv(tmp_path / "attributable_nets16.csv", index=False)
    rows([np.nan, 0.0], [0.8, 0.0]).to_csv(tmp_path / "seed+2" / "attributable_nets16.csv", index=False)
    rows([0.7, 0.7], [0.8, 0.0]).to_csv(tmp_path / "attributable_nets4_draws4.csv", index=False)  # another measure
    found = bench.remeasured(tmp_path, [0, 1, 2])
    assert list(found) == [16] and list(found[16]) == [0, 2]  # no file for offset 1
    got = bench.remeasured_by_scenario(found[16]).set_index("scenario")
    assert list(got.index) == ["lag", "mode", "all"]
    assert got.loc["lag", "at_least_half"] == "1 / 1" and got.loc["lag", "gap_measured"] == "1 / 1"
    assert got.loc["mode", "at_least_half"] == "0 / 1" and got.loc["mode", "median"] == "0.20 / 0.30"
    assert got.loc["all", "worlds"] == 4 and got.loc["all", "at_least_half"] == "1 / 2"
    text = bench._remeasured_section({16: {off: f.assign(seed=1, named="x", gap_metric="g", before=0.05, after=0.04,
                                                         null=0.03, seconds=100.0) for off, f in found[16].items()}})
    assert "## The attributable shrink with 16 nets per fold" in text
    assert "Worlds on the other side of 0.5 (3)" in text  # lag: no gap -> 0.9 and 0.8 -> no gap; mode 0.4 -> 0.6
