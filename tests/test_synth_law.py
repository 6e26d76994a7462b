"""The vibration law alone (`law_amplitudes`), its variants and the drawn-wrong simulation
(`simulation_config`), checked against the campaign's own accelerations and against worlds
generated separately."""

from dataclasses import replace

import numpy as np
import pytest

from pvvjax.synth import (
    CampaignDraw,
    EffectConfig,
    Planted,
    Span,
    SynthConfig,
    draw_campaign,
    generate,
    law_amplitudes,
    law_effects,
    simulation_config,
)

CONDS = ("11022", "T1-turn45-145", "T1-level-135")  # a pull-up, a steady turn, level flight


def _demodulated(r, blades=4, revs=1):
    """The N/rev amplitude of `az_g` over consecutive whole-revolution windows, and the
    window's sample indices (an FFT-free reference: the complex mean over whole revolutions of
    the acceleration less its load factor, whose 1 g would leak through the windows' edges)."""
    psi = np.unwrap(np.deg2rad(r.azimuth_deg.to_numpy()))
    rev = (psi - psi[0]) / (2 * np.pi)
    out = []
    for start in np.arange(0, rev[-1] - revs, revs):
        m = (rev >= start) & (rev < start + revs)
        z = (r.az_g - r.nz_g).to_numpy()[m]
        out.append((2 * abs(np.mean(z * np.exp(-1j * blades * psi[m]))), m))
    return out


@pytest.mark.parametrize("condition", CONDS)
def test_the_law_is_what_the_campaign_carries_at_n_per_rev(condition):
    cfg = SynthConfig(conditions=(condition,), noise_g=0.0)
    records = generate(cfg)[1]
    law = law_amplitudes(cfg, scatter=True)
    assert set(law) == set(records)
    for counter, r in records.items():
        a = law[counter]
        np.testing.assert_array_equal(a.time_s.to_numpy(), r.time_s.to_numpy())
        for measured, m in _demodulated(r):
            assert measured == pytest.approx(a.law.to_numpy()[m].mean(), rel=0.03, abs=2e-3)


def test_a_switched_off_effect_is_the_world_without_it():
    # The world with a planted effect, minus its switch-off, is the world minus the null of its seed
    # (two campaigns generated apart): the switch-off measures the planted effect and nothing else.
    draw = CampaignDraw(conditions=(50, 50))
    plant = Planted("yaw_rate", scale=Span(3.0, 3.0))
    hidden, _ = draw_campaign(draw, 3, [plant])
    null, _ = draw_campaign(draw, 3)
    off = replace(hidden, effects={**hidden.effects, "yaw_rate": EffectConfig(enabled=False)})
    both = law_amplitudes(hidden, {"on": hidden, "off": off})
    alone = law_amplitudes(null)
    gap = np.concatenate([both[k].on - both[k].off for k in both])
    np.testing.assert_allclose(np.concatenate([both[k].off for k in both]),
                               np.concatenate([alone[k].law for k in both]), rtol=1e-12)
    assert np.sqrt(np.mean(gap**2)) > 1e-3  # the planted yaw-rate term is there
    # An effect that is off already changes nothing.
    again = replace(hidden, effects={**hidden.effects, "sideslip": EffectConfig(enabled=False)})
    same = law_amplitudes(hidden, {"on": hidden, "again": again})
    for k in same:
        np.testing.assert_array_equal(same[k].on, same[k].again)


def test_the_kinematic_load_factor_differs_only_where_the_climb_accelerates():
    cfg = SynthConfig(conditions=("T1-level-135", "11022"), noise_g=0.0)
    law = law_amplitudes(cfg, {"measured": cfg, "kinematic": replace(cfg, load_factor="kinematic")})
    level, pull = law["T1-level-135"], law["11022"]
    np.testing.assert_allclose(level.kinematic, level.measured, rtol=0.02)  # steady level: nz = MLF = 1
    assert np.abs(pull.kinematic - pull.measured).max() > 0.005


def test_a_variant_may_not_change_the_flight():
    cfg = SynthConfig(conditions=("11022",))
    with pytest.raises(ValueError, match=r"variants\.other: changes seed"):
        law_amplitudes(cfg, {"other": replace(cfg, seed=1)})
    with pytest.raises(ValueError, match="spread"):
        simulation_config(cfg, spread=1.0)


def test_the_simulation_is_the_base_law_drawn_wrong_and_the_same_for_every_world_of_a_seed():
    draw = CampaignDraw(conditions=(50, 50))
    null, _ = draw_campaign(draw, 5)
    hidden, _ = draw_campaign(draw, 5, [Planted("rotor_band", scale=Span(2.0, 2.0)),
                                        Planted("slow_lag", params={"tau_s": Span(3.0, 3.0)})])
    s_null, s_hidden = simulation_config(null), simulation_config(hidden)
    # Nothing planted reaches the simulation, and both worlds of the seed get the same one.
    assert not s_hidden.effect_settings()["rotor_band"][0] and not s_hidden.effect_settings()["slow_lag"][0]
    a = law_amplitudes(null, {"sim": s_null})
    b = law_amplitudes(hidden, {"sim": s_hidden})
    for k in a:
        np.testing.assert_array_equal(a[k].sim, b[k].sim)
    # Each coefficient of the law within the spread of the world's, and drawn, not copied.
    world, sim = null.effect_settings(), s_null.effect_settings()
    ratios = np.array([sim[e][2][p] / v for e in (*law_effects(), "pitch_rate", "roll_rate")
                       for p, v in world[e][2].items()])
    assert ratios.min() >= 0.7 and ratios.max() <= 1.3 and ratios.std() > 0.05
    assert sim["rotor_resonance"][2]["f_mode"] == world["rotor_resonance"][2]["f_mode"]
    assert sim["dynamic_lag"] == world["dynamic_lag"]
    # Drawn exactly right, the simulation of a null world is its law.
    exact = law_amplitudes(null, {"law": null, "sim": simulation_config(null, spread=0.0)})
    for k in exact:
        np.testing.assert_allclose(exact[k].sim, exact[k].law, rtol=1e-12)
