"""The oracle beside each drawn world (research/world_oracle.py): told the answer, it finds a
planted effect that a baseline lacks and nothing where the baseline holds it; the scores
count a named effect against the whole truth, base terms included."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import research

from pvvjax.analysis import DB_INPUTS
from pvvjax.data.campaign import campaign_from_frames
from pvvjax.discovery import window_table
from pvvjax.synth import CampaignDraw, Planted, Span, draw_campaign, generate, law_amplitudes

ROOT = Path(__file__).parents[1]


@pytest.fixture(scope="module")
def wo():
    return research("world_oracle")


def _windows(wo, cfg, records):
    """A baseline's window table as the runner keeps it, with two baselines' predictions: the
    law without the planted yaw-rate term (it lacks the effect) and the whole law (it lacks
    nothing the oracle is asked about)."""
    win = wo.wt.windows(records, 4)
    law = law_amplitudes(cfg, {"law": cfg, "lacking": wo.wt._off(cfg, "yaw_rate")})
    rows = []
    for k, (i0, i1, measured) in win.items():
        t = records[k].time_s.to_numpy()
        rows.append(pd.DataFrame(dict(counter=k, t0=t[i0], t1=t[np.minimum(i1, len(t) - 1)], measured_g=measured,
                                      weight=1.0, whole=wo.wt._means(law[k].law.to_numpy(), i0, i1),
                                      lacking=wo.wt._means(law[k].lacking.to_numpy(), i0, i1))))
    return pd.concat(rows, ignore_index=True)


@pytest.mark.check  # a drawn world generated and tested whole (about 30 s)
def test_told_the_answer_the_oracle_finds_what_the_baseline_lacks(wo):
    world = dict(name="yaw", seed=21)
    cfg, drawn = draw_campaign(CampaignDraw(conditions=(60, 60), noise=Span(0.5, 0.5), scatter=Span(0.5, 0.5)), 21,
                               [Planted("yaw_rate", scale=Span(5.0, 5.0))])
    world["synth"] = cfg
    counters, records, _ = generate(cfg)
    truth = wo.wt.discrepancies(cfg, records, drawn)
    tab = _windows(wo, cfg, records)
    campaign = campaign_from_frames(counters, records, source="yaw")
    inputs = window_table(campaign, tab[["counter", "t0", "t1"]])
    for ch in DB_INPUTS["db1"]:
        tab[ch] = inputs[f"x:{ch}"].to_numpy()
    tab["condition"] = counters.set_index("counter").condition.loc[tab.counter].to_numpy()
    found = pd.DataFrame(wo.oracle(world, truth, tab.assign(predicted_before_g=tab.lacking), 0.0)).set_index("name")
    assert found.loc["yaw_rate", "detected"] and found.loc["yaw_rate", "p_value"] < 1e-3
    held = pd.DataFrame(wo.oracle(world, truth, tab.assign(predicted_before_g=tab.whole), 0.0)).set_index("name")
    assert held.loc["yaw_rate", "p_value"] > 0.05


def test_a_named_effect_counts_against_the_whole_truth(wo):
    plan = wo.bw.load_plan(ROOT / "research" / "configs" / "worlds.toml")
    fam = next(f for f in plan.family if f.name == "yaw-rate")
    worlds = [dict(name="null-1", seed=1, truth=None),
              dict(name="yaw-rate-1", seed=1, truth=dict(effect="yaw-rate", accept=list(fam.accept)))]
    named = [dict(operator="input", channels=["nz_g"]), dict(operator="input", channels=["yaw_rate_dps"]),
             dict(operator="threshold", channels=["shaft_power_hp"])]
    rows = pd.DataFrame([
        dict(world="null-1", family="none", aircraft="uh60a", conditions=90, named="load factor",
             effects=json.dumps(named[:1]), floor_g=0.01, ensemble_rms_g_before=0.03, ensemble_rms_g_after=0.028,
             seconds=30.0),
        dict(world="yaw-rate-1", family="yaw-rate", aircraft="uh60a", conditions=90, named="...",
             effects=json.dumps(named[2:] + named[1:2]), floor_g=0.01, ensemble_rms_g_before=0.04,
             ensemble_rms_g_after=0.03, seconds=30.0)])
    entries = [dict(name="measured load factor", source="base", kind="missing input", against_noise=3.0,
                    where_acts_g=0.03, rms_g=0.01)]
    truths = {"null-1": dict(entries=entries),
              "yaw-rate-1": dict(entries=entries + [dict(name="yaw_rate", source="planted", kind="missing input",
                                                         against_noise=1.5, where_acts_g=0.015, rms_g=0.005)])}
    orc = pd.DataFrame([dict(world="yaw-rate-1", name="yaw_rate", source="planted", detected=True, p_value=0.001,
                             against_noise=1.5, rms_g=0.005),
                        dict(world="null-1", name="capacity", source="baseline", detected=False, p_value=0.4,
                             against_noise=np.nan, rms_g=np.nan)])
    df = wo.judged(rows, orc, worlds, truths, plan).set_index("world")
    assert df.loc["null-1", "false_named"] == 0 and df.loc["null-1", "base_named"] == 1  # nz_g: a base term
    yaw = df.loc["yaw-rate-1"]
    assert yaw.discovered and not yaw.first and yaw.false_named == 1 and yaw.oracle and yaw["bin"] == "1-2"
    assert yaw.largest_first is False and np.isnan(df.loc["null-1", "largest_first"])  # the oracle's largest: yaw
    t = wo.tables(df.reset_index(), orc)
    assert t["by_bin"].set_index("").loc["1-2", "oracle detects"].startswith("1 / 1")
    assert t["nulls"].iloc[0]["name something not in the truth"].startswith("0 / 1")
    assert t["overall"].iloc[0]["precision (named effects in the truth)"].startswith("2 / 3")


def test_a_tied_set_that_holds_the_truth_is_right_and_a_misfit_is_right_where_the_capacity_test_sees_one(wo):
    plan = wo.bw.load_plan(ROOT / "research" / "configs" / "worlds.toml")
    fam = next(f for f in plan.family if f.name == "yaw-rate")
    worlds = [dict(name="yaw-rate-1", seed=1, truth=dict(effect="yaw-rate", accept=list(fam.accept))),
              dict(name="null-1", seed=1, truth=None)]
    tied = dict(operator="rate", channels=["roll_rate_dps"], kind="missing", tied=["input:yaw_rate_dps"])
    misfit = dict(operator="threshold", channels=["airspeed_kt"], kind="misfit", tied=[])
    rows = pd.DataFrame([
        dict(world="yaw-rate-1", family="yaw-rate", aircraft="uh60a", conditions=90, named="roll acceleration",
             effects=json.dumps([tied]), floor_g=0.01, ensemble_rms_g_before=0.04, ensemble_rms_g_after=0.03,
             seconds=30.0),
        dict(world="null-1", family="none", aircraft="uh60a", conditions=90, named="airspeed knee",
             effects=json.dumps([misfit]), floor_g=0.01, ensemble_rms_g_before=0.03, ensemble_rms_g_after=0.03,
             seconds=30.0)])
    truths = {"yaw-rate-1": dict(entries=[dict(name="yaw_rate", source="planted", kind="missing input",
                                               against_noise=2.5, where_acts_g=0.02, rms_g=0.01)]),
              "null-1": dict(entries=[])}
    for seen in (True, False):
        orc = pd.DataFrame([dict(world="yaw-rate-1", name="yaw_rate", source="planted", detected=True, p_value=0.001,
                                 against_noise=2.5, rms_g=0.01),
                            dict(world="null-1", name="capacity", source="baseline", detected=seen,
                                 p_value=0.01 if seen else 0.4, against_noise=np.nan, rms_g=np.nan)])
        df = wo.judged(rows, orc, worlds, truths, plan).set_index("world")
        assert df.loc["yaw-rate-1", "first"] and df.loc["yaw-rate-1", "false_named"] == 0
        assert df.loc["null-1", "false_named"] == (0 if seen else 1)
        assert json.loads(df.loc["yaw-rate-1", "set_sizes"]) == [2]
