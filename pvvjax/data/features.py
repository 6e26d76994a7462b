"""Derived flight features: pure `jax.numpy` functions of canonical channels.

All arguments broadcast; all are differentiable. Units are those of the data contract
(kt, rpm, deg, deg/s, lb); the `Aircraft` PyTree supplies rotor constants.
"""

from __future__ import annotations

from typing import Mapping

import jax
import jax.numpy as jnp

from .constants import DEG_TO_RAD, KT_TO_FT_S, RPM_TO_RAD_S, UH60A, Aircraft

__all__ = [
    "DERIVED_FEATURES",
    "advance_ratio",
    "blade_loading",
    "derive_features",
    "maneuver_load_factor",
    "thrust_coefficient",
    "tip_speed_ft_s",
]

DERIVED_FEATURES = ("advance_ratio", "mlf", "thrust_coefficient", "blade_loading")


def tip_speed_ft_s(rotor_rpm, aircraft: Aircraft = UH60A):
    """Rotor tip speed ΩR, ft/s."""
    return rotor_rpm * RPM_TO_RAD_S * aircraft.rotor_radius_ft


def advance_ratio(airspeed_kt, rotor_rpm, aircraft: Aircraft = UH60A):
    """Advance ratio μ = V / (ΩR), V the true airspeed."""
    return airspeed_kt * KT_TO_FT_S / tip_speed_ft_s(rotor_rpm, aircraft)


def maneuver_load_factor(roll_angle_deg, pitch_rate_dps, airspeed_kt, aircraft: Aircraft = UH60A):
    """The paper's maneuver load factor, MLF = [1 / cos(roll)] · [1 + q·V / g].

    q is the pitch rate in rad/s and V the airspeed in ft/s. The seed text prints the
    product as a quotient (an extraction loss); the product reproduces the paper's worked
    example (q = 9.6 deg/s, V ≈ 193 ft/s, no roll → MLF 2.0).
    """
    q = pitch_rate_dps * DEG_TO_RAD
    v = airspeed_kt * KT_TO_FT_S
    return (1.0 + q * v / aircraft.g_ft_s2) / jnp.cos(roll_angle_deg * DEG_TO_RAD)


def thrust_coefficient(gross_weight_lb, density_ratio, rotor_rpm, load_factor=1.0, aircraft: Aircraft = UH60A):
    """Weight (thrust) coefficient C_W = n·W / (ρ A (ΩR)²), with load factor n."""
    rho = aircraft.rho0_slug_ft3 * density_ratio
    vt = tip_speed_ft_s(rotor_rpm, aircraft)
    return load_factor * gross_weight_lb / (rho * aircraft.disk_area_ft2 * vt**2)


def blade_loading(gross_weight_lb, density_ratio, rotor_rpm, load_factor=1.0, aircraft: Aircraft = UH60A):
    """Blade loading C_W/σ · n (dynamic stall sets in near 0.12-0.13)."""
    return thrust_coefficient(gross_weight_lb, density_ratio, rotor_rpm, load_factor, aircraft) / aircraft.solidity


def derive_features(ch: Mapping[str, jnp.ndarray], aircraft: Aircraft = UH60A) -> dict[str, jnp.ndarray]:
    """All derived features from a mapping of canonical channels (arrays of one shape).

    Returns:
        `advance_ratio`, `mlf`, `thrust_coefficient` and `blade_loading` (both with the
        MLF as load factor).
    """
    out = _derive({k: ch[k] for k in _SOURCES}, aircraft)
    return {k: out[k] for k in DERIVED_FEATURES}  # in this order (a program returns its dict's keys sorted)


# The channels the derived features are computed from.
_SOURCES = ("roll_angle_deg", "pitch_rate_dps", "airspeed_kt", "gross_weight_lb", "density_ratio", "rotor_rpm")


@jax.jit  # one program per shape (eagerly, each operation would compile one)
def _derive(ch: dict, aircraft: Aircraft) -> dict:
    mlf = maneuver_load_factor(ch["roll_angle_deg"], ch["pitch_rate_dps"], ch["airspeed_kt"], aircraft)
    args = (ch["gross_weight_lb"], ch["density_ratio"], ch["rotor_rpm"], mlf, aircraft)
    return {
        "advance_ratio": advance_ratio(ch["airspeed_kt"], ch["rotor_rpm"], aircraft),
        "mlf": mlf,
        "thrust_coefficient": thrust_coefficient(*args),
        "blade_loading": blade_loading(*args),
    }
