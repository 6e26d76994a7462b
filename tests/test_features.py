import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pvvjax.data.constants import UH60A, Aircraft
from pvvjax.data.features import advance_ratio, blade_loading, derive_features, maneuver_load_factor, thrust_coefficient

# The paper's worked example: pull-up 11022 at 255 rpm, mu 0.27, pitch rate 9.6 deg/s, no roll.
V_PULLUP_KT = 0.27 * 255 * 2 * math.pi / 60 * 26.83 / (6076.12 / 3600)


def test_paper_pullup_mlf_is_2():
    assert advance_ratio(V_PULLUP_KT, 255.0) == pytest.approx(0.27, rel=1e-6)
    assert V_PULLUP_KT * 6076.12 / 3600 == pytest.approx(193.4, abs=0.2)  # physics.md: V ≈ 193 ft/s
    assert float(maneuver_load_factor(0.0, 9.6, V_PULLUP_KT)) == pytest.approx(2.0, abs=0.02)


def test_level_45_degree_turn_mlf_is_root_2():
    assert float(maneuver_load_factor(45.0, 0.0, 145.0)) == pytest.approx(math.sqrt(2.0), rel=1e-6)
    assert float(maneuver_load_factor(0.0, 0.0, 145.0)) == 1.0


def test_thrust_coefficient_hand_calculation():
    # C_W = W / (rho A (Omega R)^2), computed by hand for 16 000 lb at sea level, 257.8 rpm
    omega_r = 257.8 * 2 * math.pi / 60 * 26.83
    cw = 16000 / (0.002377 * math.pi * 26.83**2 * omega_r**2)
    assert float(thrust_coefficient(16000.0, 1.0, 257.8)) == pytest.approx(cw, rel=1e-6)
    assert float(blade_loading(16000.0, 1.0, 257.8)) == pytest.approx(cw / 0.0826, rel=1e-6)
    assert float(blade_loading(16000.0, 0.8, 257.8, 2.0)) == pytest.approx(2.5 * cw / 0.0826, rel=1e-6)
    assert 0.06 < cw / 0.0826 < 0.08  # typical UH-60A blade loading


def test_aircraft_constants_override():
    small = Aircraft(rotor_radius_ft=20.0)
    assert float(advance_ratio(100.0, 257.8, small)) == pytest.approx(
        float(advance_ratio(100.0, 257.8)) * 26.83 / 20.0, rel=1e-6)
    assert UH60A.nominal_np_hz() == pytest.approx(17.19, abs=0.01)


def test_features_are_differentiable_and_jittable():
    f = jax.jit(lambda q: maneuver_load_factor(30.0, q, 120.0))
    g = jax.grad(f)(5.0)
    fd = (f(5.0 + 1e-2) - f(5.0 - 1e-2)) / 2e-2
    assert float(g) == pytest.approx(float(fd), rel=1e-3)
    ch = {k: jnp.ones(3) * v for k, v in dict(roll_angle_deg=0.0, pitch_rate_dps=9.6, airspeed_kt=V_PULLUP_KT,
                                                gross_weight_lb=16055.0, density_ratio=1.0, rotor_rpm=255.0).items()}
    out = jax.jit(derive_features)(ch)
    np.testing.assert_allclose(out["mlf"], 2.0, atol=0.02)
    np.testing.assert_allclose(out["advance_ratio"], 0.27, rtol=1e-5)
