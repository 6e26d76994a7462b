"""Worlds drawn at random (`synth.draw_campaign`) and the effects the hidden-effect families
plant (`yaw_rate`, `stick_knee`, `rotor_band`, `slow_lag`): draws within their declared
ranges, recorded, pure in the seed; a null and a hidden world of one seed share their base;
each new effect changes the vibration as its formula says and nothing else."""

import json

import numpy as np
import pandas as pd
import pytest

from pvvjax.config import ConfigError, from_dict
from pvvjax.synth import (
    EFFECTS,
    NAMED,
    CampaignDraw,
    EffectConfig,
    Planted,
    Span,
    SynthConfig,
    catalogue,
    draw_campaign,
    generate,
    law_effects,
    write_synthetic,
)

AH1S = dict(rotor_radius_ft=22.0, blades=2, nominal_rpm=324.0, chord_ft=2.25, solidity=0.06511)
DRAW = CampaignDraw(aircraft={"uh60a": {}, "ah1s": AH1S})
LAG = Planted("slow_lag", params={"tau_s": Span(0.5, 4.0)})
YAW = Planted("yaw_rate", scale=Span(0.6, 6.0, log=True))


def test_a_world_is_a_pure_function_of_its_ranges_and_seed():
    a, b = draw_campaign(DRAW, 3, [LAG]), draw_campaign(DRAW, 3, [LAG])
    assert a == b
    other, _ = draw_campaign(DRAW, 4, [LAG])
    assert other.effects != a[0].effects and other.seed == 4


def test_a_null_and_a_hidden_world_of_one_seed_share_their_base():
    null, drawn_null = draw_campaign(DRAW, 11)
    hidden, drawn = draw_campaign(DRAW, 11, [LAG, YAW])
    assert {k: v for k, v in drawn.items() if not k.startswith("planted.")} == drawn_null
    assert {k: v for k, v in hidden.effects.items() if k not in ("slow_lag", "yaw_rate")} == null.effects
    for field in ("noise_g", "scatter", "counts", "aircraft", "sample_rate_hz", "seed"):
        assert getattr(hidden, field) == getattr(null, field)
    assert hidden.effects["slow_lag"].enabled and 0.5 <= hidden.effects["slow_lag"].params["tau_s"] <= 4.0
    assert drawn["planted.slow_lag.tau_s"] == hidden.effects["slow_lag"].params["tau_s"]
    assert 0.6 <= drawn["planted.yaw_rate.scale"] == hidden.effects["yaw_rate"].scale <= 6.0


@pytest.mark.parametrize("seed", range(12))
def test_every_draw_lies_within_its_declared_range(seed):
    cfg, drawn = draw_campaign(DRAW, seed, [LAG, YAW])
    default = SynthConfig()
    for eff in law_effects():
        for p, v in EFFECTS[eff].params.items():
            got = cfg.effects[eff].params[p]
            assert drawn[f"law.{eff}.{p}"] == got
            assert min(0.7 * v, 1.3 * v) <= got <= max(0.7 * v, 1.3 * v)
    assert 0.5 * default.noise_g <= cfg.noise_g == drawn["noise_g"] <= 2.0 * default.noise_g
    assert 0.5 * default.scatter <= cfg.scatter == drawn["scatter"] <= 2.0 * default.scatter
    assert 80 <= drawn["conditions"] <= 300 and len(catalogue(seed, cfg.counts)) == drawn["conditions"]
    assert min(cfg.counts.values()) >= 1
    assert cfg.aircraft == ({} if drawn["aircraft"] == "uh60a" else AH1S)
    rpm = cfg.aircraft_constants().nominal_rpm
    assert cfg.sample_rate_hz >= 64 * 1.15 * rpm / 60  # SynthConfig would refuse fewer samples a revolution


def test_the_draws_cover_their_ranges():
    worlds = [draw_campaign(DRAW, s, [YAW])[1] for s in range(60)]
    assert {w["aircraft"] for w in worlds} == {"uh60a", "ah1s"}
    scales = np.log10([w["planted.yaw_rate.scale"] for w in worlds])
    assert scales.min() < np.log10(1.2) and scales.max() > np.log10(3.0)  # log-uniform over the decade
    sizes = [w["conditions"] for w in worlds]
    assert min(sizes) < 120 and max(sizes) > 260
    law = [w["law.blade_loading.a"] / EFFECTS["blade_loading"].params["a"] for w in worlds]
    assert min(law) < 0.8 and max(law) > 1.2


def test_the_law_redrawn_is_the_steady_vertical_law_and_every_default_effect_stays_on():
    assert set(law_effects()) == {"baseline", "transition", "high_speed", "blade_loading", "dynamic_stall",
                                  "descent_bvi"}
    cfg, _ = draw_campaign(DRAW, 5)
    on = {n for n, (enabled, _, _) in cfg.effect_settings().items() if enabled}
    assert {n for n, e in EFFECTS.items() if e.default_on} <= on
    assert not cfg.maneuvers and not cfg.conditions  # every maneuver kind, autorotations included


@pytest.mark.parametrize("table, needle", [
    (dict(law=1.5), "law"),
    (dict(conditions=[300, 80]), "conditions"),
    (dict(conditions=[10, 80]), "conditions"),
    (dict(noise=dict(lo=2.0, hi=1.0)), "noise"),
    (dict(scatter=dict(lo=0.0, hi=1.0, log=True)), "scatter"),
    (dict(aircraft={}), "aircraft"),
    (dict(nosie=dict(lo=1.0, hi=2.0)), "nosie"),
])
def test_bad_ranges_are_errors_naming_the_key(table, needle):
    with pytest.raises(ConfigError, match=needle):
        from_dict(CampaignDraw, table)


def test_a_planted_effect_must_be_a_known_effect_and_parameter():
    with pytest.raises(ValueError, match="unknown"):
        Planted("slow_lags")
    with pytest.raises(ValueError, match="tau"):
        Planted("slow_lag", params={"tau": Span(1.0, 2.0)})


def test_the_truth_file_records_what_was_drawn(tmp_path):
    cfg = SynthConfig(name="tiny", conditions=("11022",))
    _, truth = write_synthetic(tmp_path / "c", cfg, drawn={"planted.slow_lag.tau_s": 1.5, "aircraft": "uh60a"},
                               log=lambda m: None)
    assert json.loads(truth.read_text())["drawn"] == {"planted.slow_lag.tau_s": 1.5, "aircraft": "uh60a"}


def _pair(cid: str, **effects):
    """One condition without noise, with and without `effects`: (plain, with)."""
    cfg = lambda e: SynthConfig(conditions=(cid,), noise_g=0.0, effects=e)  # noqa: E731
    return generate(cfg({}))[1][cid], generate(cfg(effects))[1][cid]


def _harmonic(r, k, rows=slice(None)):
    """Amplitude of the vertical's harmonic k over the chosen samples, g."""
    return 2 * abs(np.mean((r.az_g * np.exp(-1j * k * np.deg2rad(r.azimuth_deg)))[rows]))


def test_new_effects_change_the_vibration_only():
    """The additive effects shape the vertical alone; a lag of the whole response settles
    every axis the same way (`synth.EFFECTS`: the rotor's inflow and wake)."""
    for cid, effects, changed in (
            ("R003", dict(yaw_rate=EffectConfig(enabled=True, scale=5.0)), ["az_g"]),
            ("11022", dict(stick_knee=EffectConfig(enabled=True, params=dict(knee=40.0))), ["az_g"]),
            ("11022", dict(slow_lag=EffectConfig(enabled=True)), ["az_g", "ax_g", "ay_g"])):
        plain, new = _pair(cid, **effects)
        pd.testing.assert_frame_equal(plain.drop(columns=changed), new.drop(columns=changed))
        assert (plain.az_g - new.az_g).abs().max() > 1e-3, effects


def test_a_knee_beyond_the_stick_travel_does_nothing():
    plain, new = _pair("11022", stick_knee=EffectConfig(enabled=True, params=dict(knee=150.0)))
    assert (plain.az_g - new.az_g).abs().max() < 1e-6


def test_a_rotor_band_magnifies_the_n_per_rev_by_its_gain_at_its_centre():
    cid = NAMED[0].id  # level flight at the nominal rotor speed
    plain, new = _pair(cid, rotor_band=EffectConfig(enabled=True, params=dict(gain=1.0, center_pct=100.0)))
    assert _harmonic(new, 4) / _harmonic(plain, 4) == pytest.approx(2.0, rel=0.02)
    _, far = _pair(cid, rotor_band=EffectConfig(enabled=True, params=dict(center_pct=90.0, width_pct=0.5)))
    assert _harmonic(far, 4) / _harmonic(plain, 4) == pytest.approx(1.0, abs=0.01)


def test_a_slow_lag_starts_settled_and_smooths_the_maneuver():
    """The pull-up 11022 (a 0.29 g peak): a lag of 3 s starts at the input's value and cuts
    the peak by about a third."""
    plain, lagged = _pair("11022", slow_lag=EffectConfig(enabled=True, params=dict(tau_s=3.0)))
    assert (plain.az_g - lagged.az_g)[plain.time_s < 0.5].abs().max() < 5e-4
    rev = 60 / 257.8
    peaks = [max(_harmonic(r, 4, (r.time_s >= t) & (r.time_s < t + 2 * rev)) for t in np.arange(0, 28, rev))
             for r in (plain, lagged)]
    assert 0.5 * peaks[0] < peaks[1] < 0.8 * peaks[0]
