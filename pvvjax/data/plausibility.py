"""Physical plausibility of a record beyond its ranges: values no flying helicopter of the
campaign's aircraft can have, unit mistakes that pass the range checks, and sampling too
slow for the analysed harmonic.

An *error* (refused) is a value no aircraft of the campaign can have; a *warning* is a value
that is suspicious but possible (a record is kept). Each names the file, the column and,
for per-sample rules, the first bad row. The limits are aircraft-relative where the physics
is (rotor speed against nominal, airspeed as advance ratio, weight as blade loading).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .checks import Problem, _first_bad, _numeric
from .constants import KT_TO_FT_S, Aircraft

__all__ = ["LIMITS", "MIN_SAMPLES_PER_CYCLE", "STICKS", "plausibility"]

STICKS = ("collective_pct", "lateral_pct", "longitudinal_pct")

# Samples per cycle of the analysed harmonic, at the record's highest rotor speed: Nyquist's
# 2 with a 50 % margin (the harmonic's projection over whole revolutions is then unaliased).
MIN_SAMPLES_PER_CYCLE = 3.0

# name -> (error bounds, warning bounds, what it measures); None = no bound.
LIMITS: dict[str, tuple[tuple, tuple, str]] = {
    "az_g": ((-10.0, 10.0), (None, None), "each sample, g"),
    "az_g median": ((0.25, 3.0), (None, None), "the record's median, g (total acceleration: 1 g in level flight)"),
    "az_g median, level": ((None, None), (0.8, 1.2), "the median of a level-flight record, g"),
    "rotor_rpm / nominal": ((0.5, 1.3), (0.9, 1.1), "each sample, against the aircraft's nominal_rpm"),
    "advance ratio": ((None, 0.6), (None, None), "airspeed / rotor tip speed, each sample"),
    "climb_rate_fpm": ((-10000.0, 10000.0), (None, None), "each sample, ft/min"),
    "pitch_rate_dps": ((-200.0, 200.0), (None, None), "each sample, deg/s"),
    "blade loading": ((0.01, 0.3), (0.04, 0.16), "C_T/σ = W / (ρ₀ σ_ρ A (ΩR)² solidity), first sample"),
}


def _outside(vals, bounds):
    lo, hi = bounds
    bad = np.zeros(np.shape(vals), bool)
    if lo is not None:
        bad |= vals < lo
    if hi is not None:
        bad |= vals > hi
    return bad


def _span(bounds) -> str:
    lo, hi = bounds
    return f"[{'' if lo is None else f'{lo:g}'}, {'' if hi is None else f'{hi:g}'}]"


def _sample_rule(key, vals, file, column, problems, hint=""):
    """Per-sample error and warning bounds of `LIMITS[key]` on `vals`."""
    err, warn, _ = LIMITS[key]
    for bounds, warning in ((err, False), (warn, True)):
        row = _first_bad(_outside(vals, bounds))
        if row is not None:
            what = "outside the plausible" if warning else "impossible for this aircraft: outside"
            problems.append(Problem(file, column, row, f"{key} {vals[row - 1]:.4g} {what} {_span(bounds)}{hint}",
                                    warning=warning))
            return


def plausibility(df: pd.DataFrame, file: str, aircraft: Aircraft, harmonic: int, maneuver: str = "") -> list[Problem]:
    """Plausibility problems of one record whose values passed the range checks.

    Args:
        df: the record in canonical columns (constants broadcast), numeric and finite.
        file: its file name in messages.
        aircraft: the campaign's rotor constants.
        harmonic: harmonic order analysed (per revolution).
        maneuver: the counter's maneuver kind (level flight has a 1 g check).

    Returns:
        Problems (errors and warnings), in the order of the rules.
    """
    problems: list[Problem] = []
    t, az, rpm = _numeric(df["time_s"]), _numeric(df["az_g"]), _numeric(df["rotor_rpm"])

    fs = 1.0 / float(np.median(np.diff(t)))
    per_cycle = fs * 60.0 / float(rpm.max()) / harmonic
    if per_cycle < MIN_SAMPLES_PER_CYCLE:
        problems.append(Problem(
            file, "time_s", None,
            f"sampled at {fs:.4g} Hz: {per_cycle:.3g} samples per cycle of the {harmonic}/rev harmonic at "
            f"{rpm.max():.4g} rpm; at least {MIN_SAMPLES_PER_CYCLE:g} are needed (Nyquist's 2 with a 50 % "
            "margin); time in milliseconds?"))

    med = float(np.median(az))
    err, warn, _ = LIMITS["az_g median"]
    if _outside(med, err):  # one line for a record in another unit, not one per rule
        hint = "acceleration in m/s²?" if med > err[1] else "the vibration without the 1 g mean? (offset = 1)"
        problems.append(Problem(file, "az_g", None, f"median {med:.4g} g outside {_span(err)} g: {hint}"))
    else:
        _sample_rule("az_g", az, file, "az_g", problems)
    if maneuver == "level" and not _outside(med, err):
        _, warn, _ = LIMITS["az_g median, level"]
        if _outside(med, warn):
            problems.append(Problem(file, "az_g", None, f"median {med:.4g} g in level flight, outside "
                                    f"{_span(warn)} g", warning=True))

    n = len(problems)
    _sample_rule("rotor_rpm / nominal", rpm / aircraft.nominal_rpm, file, "rotor_rpm", problems,
                 f" (nominal {aircraft.nominal_rpm:g} rpm); rad/s or rev/s?")
    if all(p.warning for p in problems[n:]):  # the advance ratio needs a rotor speed in rpm
        tip_ft_s = rpm * np.pi / 30.0 * aircraft.rotor_radius_ft
        _sample_rule("advance ratio", _numeric(df["airspeed_kt"]) * KT_TO_FT_S / tip_ft_s, file, "airspeed_kt",
                     problems, "; airspeed in km/h or ft/s?")
    _sample_rule("climb_rate_fpm", _numeric(df["climb_rate_fpm"]), file, "climb_rate_fpm", problems)
    _sample_rule("pitch_rate_dps", _numeric(df["pitch_rate_dps"]), file, "pitch_rate_dps", problems)

    if all(float(_numeric(df[s]).max()) <= 1.0 for s in STICKS):
        for s in STICKS:
            problems.append(Problem(file, s, None, "every stick within 0–1 throughout the record: fractions, not % "
                                    "(map it with unit = \"fraction\")"))

    w, sigma = float(_numeric(df["gross_weight_lb"])[0]), float(_numeric(df["density_ratio"])[0])
    rho = aircraft.rho0_slug_ft3 * sigma
    ct_sigma = w / (rho * aircraft.disk_area_ft2 * (aircraft.nominal_omega_rad_s * aircraft.rotor_radius_ft) ** 2
                    ) / aircraft.solidity
    err, warn, _ = LIMITS["blade loading"]
    for bounds, warning in ((err, False), (warn, True)):
        if _outside(ct_sigma, bounds):
            problems.append(Problem(file, "gross_weight_lb", None,
                                    f"blade loading C_T/σ {ct_sigma:.3g} at {w:g} lb outside {_span(bounds)}: "
                                    "weight in kg or N?", warning=warning))
            break
    return problems
