"""A drawn world's discrepancies (research/world_truth.py): every term the baseline's inputs
cannot carry is listed and sized by switching it off, a planted effect's size is the world
minus the null of its seed (generated apart), and the floor is what noise and scatter leave."""

from dataclasses import replace

import numpy as np
import pytest
from conftest import research

from pvvjax.synth import CampaignDraw, Planted, Span, draw_campaign, generate, law_amplitudes


@pytest.fixture(scope="module")
def wt():
    return research("world_truth")


@pytest.fixture(scope="module")
def worlds():
    draw = CampaignDraw(conditions=(50, 50))
    hidden, drawn = draw_campaign(draw, 11, [Planted("yaw_rate", scale=Span(4.0, 4.0))])
    null, _ = draw_campaign(draw, 11)
    return hidden, drawn, null, generate(hidden)[1]


def test_every_discrepancy_is_listed_and_sized_by_switching_it_off(wt, worlds):
    hidden, drawn, null, records = worlds
    truth = wt.discrepancies(hidden, records, drawn)
    by = {e["name"]: e for e in truth["entries"]}
    assert set(wt.BASE_TERMS) | {"yaw_rate", "the base's terms together"} == set(by)
    assert by["yaw_rate"]["source"] == "planted" and by["yaw_rate"]["kind"] == "missing input"
    assert by["rotor-speed resonance"]["kind"] == "misfit" and by["0.6 s lag"]["kind"] == "response"
    assert by["yaw_rate"]["parameters"] == {"scale": 4.0}
    for e in truth["entries"]:
        assert e["rms_g"] > 1e-4 and e["where_acts_g"] >= e["rms_g"]
        assert e["against_noise"] == pytest.approx(e["where_acts_g"] / truth["floor_g"])
    # The planted effect's size, from the hidden world and its seed's null generated apart.
    win = wt.windows(records, 4)
    a, b = law_amplitudes(hidden), law_amplitudes(null)
    d = np.concatenate([wt._means((a[k].law - b[k].law).to_numpy(), *win[k][:2]) for k in win])
    assert by["yaw_rate"]["rms_g"] == pytest.approx(np.sqrt(np.mean(d**2)), rel=1e-9)
    # Together the base's terms are at least as large as the largest of them.
    assert by["the base's terms together"]["rms_g"] >= max(by[n]["rms_g"] for n in wt.BASE_TERMS) * 0.9


def test_the_floor_is_the_noise_and_scatter_and_the_simulation_lane_misses_only_what_was_planted(wt, worlds):
    hidden, drawn, null, records = worlds
    floor = wt.floor_g(hidden, records)
    assert 0 < floor < 0.05
    quiet = generate(replace(hidden, noise_g=0.0, scatter=0.0))[1]
    assert wt.floor_g(hidden, quiet) == pytest.approx(0.0, abs=1e-6)  # the truth scored as itself
    sim = wt.discrepancies(hidden, records, drawn, lane="simulation")
    rms = [e["rms_g"] for e in sim["entries"]]
    assert rms == sorted(rms, reverse=True)  # largest first
    assert {e["name"] for e in sim["entries"]} == {"yaw_rate", "the simulation's coefficients"}
    with pytest.raises(ValueError, match="lane"):
        wt.discrepancies(hidden, records, drawn, lane="db2")


def test_the_simulation_lane_carries_its_prediction_as_a_column_a_campaign_keeps(wt, worlds):
    from pvvjax.data.campaign import campaign_from_frames

    hidden, drawn, null, records = worlds
    counters = generate(hidden)[0]
    campaign = campaign_from_frames(counters, wt.with_simulation(hidden, records), source="with-simulation")
    k = next(iter(records))
    column = campaign.records[k][wt.SIMULATION_COLUMN].to_numpy()
    sim = law_amplitudes(null, {"s": wt.simulation_config(null)})[k].s.to_numpy()
    np.testing.assert_allclose(column, sim, rtol=1e-6)  # the null's simulation: nothing planted reaches it
    law = law_amplitudes(hidden)[k].law.to_numpy()
    assert 0 < np.sqrt(np.mean((column - law) ** 2)) < 0.5 * np.sqrt(np.mean(law**2))  # drawn wrong, not far off
