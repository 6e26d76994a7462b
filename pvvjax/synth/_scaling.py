"""UH-60A-like physics on another rotor, by similarity.

The generator's flight model and vibration effects are the UH-60A's. For another aircraft the
campaign keeps the same non-dimensional flight: the same advance ratio μ = V/ΩR, inflow ratio
ḣ/ΩR, blade loading C_W/σ and load factor, and so the same vibration levels, at the aircraft's
own rotor speed, weight and speeds, and at its own blade-passage harmonic N/rev. A stand-in for
measured data of that aircraft, not a model of its rotor.
"""

from __future__ import annotations

from ..data.constants import UH60A, Aircraft


def similarity(aircraft: Aircraft) -> dict[str, float]:
    """Factors from the UH-60A's dimensional values to the aircraft's: rotor speed, speeds
    (tip-speed ratio), weight (the same C_W/σ at the same density) and power (weight × speed)."""
    tip = aircraft.nominal_omega_rad_s * aircraft.rotor_radius_ft / (UH60A.nominal_omega_rad_s * UH60A.rotor_radius_ft)
    weight = (aircraft.solidity * aircraft.disk_area_ft2 / (UH60A.solidity * UH60A.disk_area_ft2)) * tip**2
    return dict(rpm=aircraft.nominal_rpm / UH60A.nominal_rpm, speed=tip, weight=weight, power=weight * tip)


# The simulated states each factor applies to.
_SCALED = dict(rotor_rpm="rpm", airspeed_kt="speed", climb_rate_fpm="speed", gross_weight_lb="weight",
               shaft_power_hp="power")


def scale_states(states: dict, aircraft: Aircraft) -> dict:
    """The flight model's (K, N) states in the aircraft's units (the UH-60A's unchanged)."""
    if aircraft == UH60A:
        return states
    f = similarity(aircraft)
    return {k: v * f[_SCALED[k]] if k in _SCALED else v for k, v in states.items()}
