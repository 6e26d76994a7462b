"""The resonance probe (experiments/resonance_modes_probe.py): the world's own mode it tells
the `truth` mode, and the null world it measures a gap against."""

import numpy as np
from conftest import experiment


def test_the_truth_mode_magnifies_as_the_generator_does_and_a_null_world_not_at_all():
    """The 4P amplitude of the rotor-resonance world over its null world's, same flight
    state at each rotor speed, is the probe's `magnification` (through the generator's own
    amplitude model: the effect's scale, 4/rev from rotor speed, applied to every load)."""
    from pvvjax.synth._vibration import amplitude_4p

    probe = experiment("resonance_modes_probe")
    res, _ = probe.world_config("0:rotor-resonance")
    null, _ = probe.world_config("0:null-31")
    rpm = np.linspace(240.0, 280.0, 81)
    one = np.ones_like(rpm)[:, None]  # one condition per rotor speed, one sample each (the lag acts along time)
    state = dict(mu=0.2 * one, loading=0.08 * one, climb_fpm=0.0 * one, q=2.0 * one, p=3.0 * one, qdot=1.0 * one,
                 beta=1.0 * one, collective=50.0 * one, f4=4.0 * rpm[:, None] / 60.0)
    a_res = amplitude_4p(state, res["synth"].effect_settings(), 0.02)[0][:, 0]
    a_null = amplitude_4p(state, null["synth"].effect_settings(), 0.02)[0][:, 0]
    m = probe.magnification(res["synth"], rpm)
    np.testing.assert_allclose(a_res / a_null, m, rtol=1e-6)
    np.testing.assert_allclose(probe.magnification(null["synth"], rpm), 1.0)
    # The benchmark's mode: 273 rpm (18.2 Hz at 4/rev), 2.2x at the campaign's top rotor speed.
    at = lambda r: m[np.argmin(np.abs(rpm - r))]  # noqa: E731
    assert 272.5 < rpm[np.argmax(m)] < 273.5 and 2.1 < at(270.7) / at(257.8) < 2.4


def test_a_world_is_measured_against_the_null_world_of_its_seed():
    probe = experiment("resonance_modes_probe")
    assert probe._null_job("16:rotor-resonance") == "16:null-31"
    assert probe._null_job("3:roll-rate") == "3:null-41"
    assert probe._null_job("0:null-51") == "0:null-51"
