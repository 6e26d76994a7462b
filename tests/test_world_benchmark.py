"""Scoring of the discovery benchmark on drawn worlds (research/world_benchmark.py): right
first, both named and the larger first on a two-effect world, clean nulls, spurious extras,
the attributable shrink against the null of the seed and the parameter's error."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import research

from pvvjax.synth import EffectConfig, SynthConfig, generate

ROOT = Path(__file__).parents[1]


@pytest.fixture(scope="module")
def wb():
    return research("world_benchmark")


def _effect(operator, channels, **parameters):
    return dict(operator=operator, channels=list(channels), parameters=parameters)


def _row(world, seed, family, effects, before, after, also="", peak=(0.1, 0.1)):
    return dict(world=world, seed=seed, family=family, also=also, effects=json.dumps(effects), seconds=30.0,
                ensemble_rms_g_before=before, ensemble_rms_g_after=after, peak_error_g_before=peak[0],
                peak_error_g_after=peak[1], rms_g_before=before, rms_g_after=after)


KNEE = dict(effect="collective-knee", accept=["threshold:collective_pct"], gap_metric="ensemble_rms_g",
            parameter="knee", value=60.0)
YAW = dict(effect="yaw-rate", accept=["input:yaw_rate_dps"], gap_metric="ensemble_rms_g")


def test_a_world_is_scored_against_its_truth_and_the_null_of_its_seed(wb):
    worlds = [dict(name="null-1", seed=1, truth=None), dict(name="knee-1", seed=1, truth=KNEE),
              dict(name="yaw-1", seed=1, truth=YAW), dict(name="null-2", seed=2, truth=None)]
    rows = pd.DataFrame([
        _row("null-1", 1, "none", [], 0.030, 0.030),
        _row("knee-1", 1, "collective-knee", [_effect("threshold", ["collective_pct"], knee=63.0),
                                              _effect("input", ["pitch_rate_dps"])], 0.040, 0.032),
        _row("yaw-1", 1, "yaw-rate", [_effect("input", ["roll_rate_dps"])], 0.036, 0.034),
        _row("null-2", 2, "none", [_effect("threshold", ["shaft_power_hp"])], 0.03, 0.028)])
    s = wb.score(rows, worlds).set_index("world")
    assert s.loc["null-1", "clean"] and not s.loc["null-2", "clean"]
    knee = s.loc["knee-1"]
    assert knee.right_first and knee.spurious  # the truth first, then an effect nothing planted
    assert knee.attributable == pytest.approx((0.040 - 0.032) / (0.040 - 0.030))
    assert knee.parameter_error == pytest.approx(3 / 60)
    yaw = s.loc["yaw-1"]
    assert not yaw.right_first and yaw.spurious and np.isnan(yaw.parameter_error)
    t = wb.table(s.reset_index()).set_index("family")
    assert t.loc["all", "right first"] == "1 / 2" and t.loc["none", "nulls clean"] == "1 / 2"
    assert t.loc["all", "spurious extra"] == "2 / 2" and t.loc["collective-knee", "median parameter error"] == "5.0%"


@pytest.mark.check
def test_of_two_effects_the_larger_must_come_first_and_both_be_named(wb):
    base = SynthConfig(conditions=("11022",), noise_g=0.0)
    big = {**base.effects, "collective_stall": EffectConfig(enabled=True, scale=3.0, params=dict(knee=40.0))}
    small = {**base.effects, "yaw_rate": EffectConfig(enabled=True, scale=0.5)}
    both = SynthConfig(conditions=("11022",), noise_g=0.0, effects={**big, **small})
    world = dict(name="yaw-rate+collective-knee-1", seed=1, synth=both, truth={**YAW, "also": {**KNEE, "value": 40.0}},
                 alone={"yaw-rate": SynthConfig(conditions=("11022",), noise_g=0.0, effects=small),
                        "collective-knee": SynthConfig(conditions=("11022",), noise_g=0.0, effects=big)})
    worlds = [dict(name="null-1", seed=1, truth=None, synth=base), world]
    null = generate(base)[1]
    assert wb.effect_size(world, "collective-knee", null) > wb.effect_size(world, "yaw-rate", null) > 0
    knee, yaw = _effect("threshold", ["collective_pct"], knee=41.0), _effect("input", ["yaw_rate_dps"])
    for effects, right, both_named in (([knee, yaw], True, True), ([yaw, knee], False, True), ([knee], True, False)):
        rows = pd.DataFrame([_row("null-1", 1, "none", [], 0.03, 0.03),
                             _row(world["name"], 1, "yaw-rate", effects, 0.05, 0.035, also="collective-knee")])
        s = wb.score(rows, worlds).set_index("world").loc[world["name"]]
        assert (s.right_first, s.both_named, s.spurious) == (right, both_named, False)
        if right:  # the larger effect's parameter
            assert s.parameter_error == pytest.approx(1 / 40)


@pytest.mark.check
@pytest.mark.parametrize("lane", ["db1", "simulation"])
def test_a_micro_world_runs_end_to_end_and_writes_its_truth(wb, tmp_path, lane):
    """The runner's path on a few conditions with short trainings (the table runs the
    defaults on 80-300 conditions), in each lane."""
    from conftest import discovery_config

    from pvvjax.config import ExperimentConfig, TrainConfig

    cids = ("11022", "T1-level-135", "T1-descent-160", "T1-climb-62", "T1-turn45-145", "LS15k-060", "LS15k-120",
            "LS20k-080", "LS20k-140")
    synth = SynthConfig(name="micro", conditions=cids)
    world = dict(name="micro", seed=0, database="db1", truth=None, synth=synth, alone={},
                 drawn={"aircraft": "uh60a", "conditions": len(cids)})
    sim = dict(simulation=wb.wt.SIMULATION_COLUMN, simulation_inputs=wb.wt.SIMULATION_INPUTS) if lane != "db1" else {}
    cfg = ExperimentConfig(train=TrainConfig(max_steps=50),
                           discovery=discovery_config(seeds=1, folds=3, max_effects=1, offset_step_s=0.5, **sim))
    row = wb.run_world(world, tmp_path, cfg, lane=lane)
    truth = json.loads((tmp_path / "truth" / "micro.truth.json").read_text())
    assert truth["drawn"] == world["drawn"] and truth["judged"] is None
    names = {e["name"] for e in truth["discrepancies"]["entries"]}
    if lane == "db1":
        assert {"measured load factor", "0.6 s lag", "pitch rate"} <= names
    else:
        assert names == {"the simulation's coefficients"} and row["database"] == "simulation"
    assert row["family"] == "none" and row["ensemble_rms_g_before"] > 0 and row["seconds"] > 0
    assert row["floor_g"] == truth["discrepancies"]["floor_g"] > 0
    windows = pd.read_parquet(tmp_path / "windows" / "micro.parquet")  # what the oracle tests
    assert {"counter", "condition", "t0", "t1", "measured_g", "weight", "predicted_before_g"} <= set(windows.columns)
    s = wb.score(pd.DataFrame([row]), [world]).iloc[0]
    assert s.clean == (row["named"] == "none")
