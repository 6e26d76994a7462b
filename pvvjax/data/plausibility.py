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

from .checks import Problem, _first_bad, _integrate_azimuth, _numeric
from .constants import KT_TO_FT_S, Aircraft

__all__ = ["HORIZONTAL_AXES", "LIMITS", "MIN_SAMPLES_PER_CYCLE", "STICKS", "TIME_PRECISION_SHARE",
           "condition_consistency", "plausibility", "rebase_time"]

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
    "density_ratio": ((None, None), (None, 1.15), "ρ/ρ₀, first sample: above 1.15 is air colder than -15 °C at "
                                                  "sea level (1.225 is the sea-level density in kg/m³)"),
    "blade loading": ((0.01, 0.3), (0.04, 0.16), "C_T/σ = W / (ρ₀ σ_ρ A (ΩR)² solidity), first sample"),
    "azimuth advance / rotor speed": ((0.8, 1.25), (0.95, 1.05),
                                      "median over samples of azimuth_deg's advance (wrapped to ±180°) over "
                                      "rotor_rpm × 6 × the step: degrees, forwards, at the rotor's rate"),
    "az_g vibration": ((1e-3, None), (None, None), "standard deviation of az_g (and of ax_g, ay_g where given) "
                                                   "about its one-revolution moving mean, g: a vibration channel "
                                                   "carries vibration"),
    "ax_g, ay_g median": ((-0.5, 0.5), (None, None), "the record's median, g (about 0: the 1 g is the vertical's)"),
    "ax_g, ay_g vibration / az_g's": ((None, 6.0), (None, 4.0),
                                      "its standard deviation about its one-revolution moving mean over az_g's: "
                                      "a horizontal axis seldom shakes 4x the vertical (a steep banked turn of a "
                                      "rotor with a quiet vertical N/rev), never 6x (m/s² give 9.81x)"),
}
# The optional horizontal axes at the pilot floor, beside az_g: name -> (axis, sign).
# Each step of `azimuth_deg` within this span × the record's typical step: a rotor's speed
# moves by a few per cent from one sample to the next, never by half (autorotation and
# overspeed span 90-115 % of nominal over seconds).
AZIMUTH_STEP_SPAN = (0.5, 1.5)
# Another order this many times stronger than the analysed harmonic means the analysis would
# measure noise: a blade-passage vibration stands far above its neighbouring orders.
HARMONIC_DOMINANCE = 4.0
# The analysed harmonic within this factor of the median amplitude of the half orders between
# harmonics (broadband noise only) over a whole record carries no vibration: for noise alone, the
# harmonic passes 3x that median in about 2 records in 1000 (Rayleigh amplitudes), and a blade-
# passage vibration stands orders of magnitude above it.
NOISE_MARGIN = 3.0
HORIZONTAL_AXES = {"ax_g": ("longitudinal", "positive forward"), "ay_g": ("lateral", "positive right")}
# Time stamps are analysed in single precision: a record whose times float32 would round by
# more than this share of its sample step is rebased to start at 0 s (refused where even that
# is not enough).
TIME_PRECISION_SHARE = 0.1


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


def unit_hint(seen: float, typical: float, units: dict[str, float], what: str = "", otherwise: str = "") -> str:
    """The likely unit of a value outside its plausible range, ranked by the value itself:
    the units (name -> factor to the canonical unit) whose conversion brings `seen` within a
    factor 1.5 of `typical`, nearest first ("in % of the nominal rotor speed?"); all of them
    as a question where none does, followed by `otherwise` (another likely cause)."""
    fits = sorted((abs(np.log(seen * f / typical)), name) for name, f in units.items()
                  if seen > 0 and abs(np.log(seen * f / typical)) < np.log(1.5))
    prefix = f"{what} in " if what else "in "
    if fits:
        return prefix + " or ".join(name for _, name in fits) + "? (the values seen fit it)"
    return prefix + " or ".join(units) + "?" + (f" {otherwise}" if otherwise else "")


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
            "margin); time in milliseconds?" + ("" if harmonic == aircraft.blades else
                                                f" Or analysis.harmonic = {harmonic} beyond this sampling?")))

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

    _vibration_rule(t, az, rpm, file, problems)
    for axis in HORIZONTAL_AXES:
        if axis in df:
            _horizontal_rule(axis, t, _numeric(df[axis]), az, rpm, file, problems)
    n = len(problems)
    nominal = aircraft.nominal_rpm
    _sample_rule("rotor_rpm / nominal", rpm / nominal, file, "rotor_rpm", problems,
                 f" (nominal {nominal:g} rpm); " + unit_hint(float(np.median(rpm)), nominal, {
                     "% of the nominal rotor speed": nominal / 100.0, "rad/s": 30.0 / np.pi, "rev/s or Hz": 60.0},
                     otherwise=f"Or is campaign.toml's nominal_rpm ({nominal:g}) another rotor's?"))
    if all(p.warning for p in problems[n:]) and "azimuth_deg" in df:  # against a rotor speed in rpm
        _azimuth_rule(t, _numeric(df["azimuth_deg"]), rpm, file, problems)
    if all(p.warning for p in problems):  # the azimuth given, or the one its rotor speed integrates to
        azimuth = _numeric(df["azimuth_deg"]) if "azimuth_deg" in df else _integrate_azimuth(t, rpm)
        _harmonic_rule(az, azimuth, harmonic, file, problems)
    if all(p.warning for p in problems[n:]):  # the advance ratio needs a rotor speed in rpm
        tip_ft_s = rpm * np.pi / 30.0 * aircraft.rotor_radius_ft
        _sample_rule("advance ratio", _numeric(df["airspeed_kt"]) * KT_TO_FT_S / tip_ft_s, file, "airspeed_kt",
                     problems, "; airspeed in km/h or ft/s?")
    _sample_rule("climb_rate_fpm", _numeric(df["climb_rate_fpm"]), file, "climb_rate_fpm", problems)
    _sample_rule("pitch_rate_dps", _numeric(df["pitch_rate_dps"]), file, "pitch_rate_dps", problems)

    within_one = [s for s in STICKS if float(np.nanmax(np.abs(_numeric(df[s])))) <= 1.0]
    if len(within_one) == len(STICKS):
        for s in STICKS:
            problems.append(Problem(file, s, None, "every stick within 0–1 throughout the record: fractions, not % "
                                    "(map it with unit = \"fraction\")"))
    for s in within_one if len(within_one) < len(STICKS) else ():  # one stick a fraction, the others in %?
        problems.append(Problem(file, s, None, "within 0–1 throughout the record while the other sticks are not: a "
                                "fraction, not %? (map it with unit = \"fraction\")", warning=True))

    _sample_rule("density_ratio", _numeric(df["density_ratio"])[:1], file, "density_ratio", problems,
                 " (air colder than -15 °C at sea level): a density in kg/m³ (1.225 at sea level) rather than the "
                 "ratio?")
    if not any(p.column == "rotor_rpm" for p in problems[n:]):  # at nominal speed: that speed must be the rotor's
        _blade_loading_rule(df, aircraft, file, problems)
    return problems


def _spread(t, x, rpm) -> float | None:
    """Standard deviation of `x` about its one-revolution moving mean, g (None where a
    revolution holds fewer than 3 samples: the sampling rule says so)."""
    spr = max(1, int(round(60.0 / float(np.median(rpm)) / float(np.median(np.diff(t))))))
    if spr < 3 or len(x) <= spr:
        return None
    c = np.concatenate([[0.0], np.cumsum(x - x.mean())])
    moving = (c[spr:] - c[:-spr]) / spr
    centred = (x - x.mean())[spr // 2: spr // 2 + len(moving)]
    return float(np.std(centred - moving))


def _horizontal_rule(axis, t, x, az, rpm, file, problems):
    """`ax_g`/`ay_g`: about 0 g in the mean (an axis carrying 1 g is the vertical: swapped
    axes), and no more vibration than 6x the vertical's (9.81x: m/s², not g); above 4x, a
    warning."""
    name, sign = HORIZONTAL_AXES[axis]
    med = float(np.median(x))
    err, _, _ = LIMITS["ax_g, ay_g median"]
    if _outside(med, err):
        problems.append(Problem(file, axis, None, f"median {med:.4g} g on the {name} axis ({sign}), outside "
                                f"{_span(err)} g: the vertical's 1 g? axes swapped (az_g is the vertical)?"))
        return
    if _vibration_rule(t, x, rpm, file, problems, axis):
        return
    own, vertical = _spread(t, x, rpm), _spread(t, az, rpm)
    (_, hi), (_, warn), _ = LIMITS["ax_g, ay_g vibration / az_g's"]
    if own is not None and vertical and own / vertical > warn:
        bad = own / vertical > hi
        problems.append(Problem(file, axis, None, f"vibration {own:.3g} about its one-revolution mean, "
                                f"{own / vertical:.3g}x az_g's (above {hi if bad else warn:g}x): in m/s² (9.81x g)?",
                                warning=not bad))


def _vibration_rule(t, x, rpm, file, problems, column: str = "az_g") -> bool:
    """A pilot-floor axis (`az_g`, and `ax_g`/`ay_g` where given) must vary within a
    revolution: a constant, or a smooth channel (the load factor in the vibration's place),
    carries no N/rev vibration to analyse. True when it does not."""
    spread = _spread(t, x, rpm)
    if spread is None:
        return False
    lo = LIMITS["az_g vibration"][0][0]
    if spread < lo:
        hint = "the load factor in its place" if column == "az_g" else "an accelerometer that was not recording"
        text = (f"carries no vibration: {spread:.2g} g about its one-revolution mean, below {lo:g} g (a constant, or "
                f"{hint}?)")
        if column != "az_g":
            text += "; leave the column out where the axis was not measured"
        problems.append(Problem(file, column, None, text))
        return True
    return False


def _blade_loading_rule(df, aircraft: Aircraft, file, problems):
    """The record's blade loading C_T/σ at its weight and density, at nominal rotor speed,
    within the plausible span: outside it, the weight is likely in another unit."""
    w, sigma = float(_numeric(df["gross_weight_lb"])[0]), float(_numeric(df["density_ratio"])[0])
    rho = aircraft.rho0_slug_ft3 * sigma
    ct_sigma = w / (rho * aircraft.disk_area_ft2 * (aircraft.nominal_omega_rad_s * aircraft.rotor_radius_ft) ** 2
                    ) / aircraft.solidity
    err, warn, _ = LIMITS["blade loading"]
    for bounds, warning in ((err, False), (warn, True)):
        if _outside(ct_sigma, bounds):
            problems.append(Problem(file, "gross_weight_lb", None,
                                    f"blade loading C_T/σ {ct_sigma:.3g} at {w:g} lb outside {_span(bounds)}: " +
                                    unit_hint(ct_sigma, 0.08, {"kg": 2.20462, "N": 0.224809,
                                                               "tonnes": 2204.62}, "weight"), warning=warning))
            break


def _harmonic_rule(az, azimuth, harmonic: int, file, problems):
    """The analysed harmonic must carry the record's vibration, and stand above its noise.

    Where another order from 2/rev up (1/rev is track and balance) is `HARMONIC_DOMINANCE`
    times stronger over the whole record, the analysis would measure noise (a wrong `blades`
    in campaign.toml, or `analysis.harmonic`). Where the analysed order is no more than
    `NOISE_MARGIN` times the median amplitude of the half orders between the harmonics
    (2.5/rev, 3.5/rev, …, where only broadband noise lives), the record carries no N/rev at
    all: its peaks would be noise. Both are warnings without numbers, so that a cause shared by
    every record is reported once (`_collapsed`)."""
    psi = np.unwrap(np.deg2rad(azimuth))
    per_rev = len(psi) / max((psi[-1] - psi[0]) / (2 * np.pi), 1e-9)
    top = 2 * harmonic + 2
    if harmonic >= per_rev / 2:
        return
    x = az - az.mean()
    half, z = np.exp(-0.5j * psi), np.exp(-1.5j * psi)
    amp = {}
    for m in range(4, 2 * top + 2):  # e^(−i m ψ / 2) by repeated products: one complex exponential per record
        z = z * half
        if m / 2 < per_rev / 2:
            amp[m / 2] = 2.0 * abs(np.mean(x * z))
    whole = {int(k): a for k, a in amp.items() if k == int(k)}
    between = [a for k, a in amp.items() if k != int(k)]
    strongest = max(whole, key=whole.get)
    if strongest != harmonic and whole[strongest] > HARMONIC_DOMINANCE * whole[harmonic]:
        problems.append(Problem(file, "az_g", None,
                                f"vibrates at {strongest}/rev, far more than at the analysed {harmonic}/rev (the blade "
                                f"passage of campaign.toml's blades, or analysis.harmonic): is blades right? The "
                                f"analysis would measure noise", warning=True))
    elif between and whole[harmonic] <= NOISE_MARGIN * float(np.median(between)):
        problems.append(Problem(file, "az_g", None,
                                f"carries no {harmonic}/rev above its noise (the analysed harmonic is within "
                                f"{NOISE_MARGIN:g}x of the noise between the harmonics): its peaks would be noise, "
                                f"and a model or a discovery from them means nothing", warning=True))


def _azimuth_rule(t, azimuth, rpm, file, problems):
    """`azimuth_deg` must advance at the rate `rotor_rpm` gives, in degrees, forwards: the
    harmonic analysis counts revolutions on it."""
    step = (np.diff(azimuth) + 180.0) % 360.0 - 180.0
    expected = rpm[:-1] * 6.0 * np.diff(t)  # degrees per step
    ok = expected > 0
    if not ok.any():
        return
    ratio = float(np.median(step[ok] / expected[ok]))
    err, warn, _ = LIMITS["azimuth advance / rotor speed"]
    for bounds, warning in ((err, False), (warn, True)):
        if _outside(ratio, bounds):
            if -1.25 < ratio < -0.8:
                hint = "it runs backwards: the rotor's other sense of rotation? (azimuth = 360 − azimuth)"
            elif 0.8 * np.pi / 180 < ratio < 1.25 * np.pi / 180:
                hint = "azimuth in radians? (unit = \"rad\")"
            else:
                hint = "another rotor's or a wrong channel?"
            problems.append(Problem(file, "azimuth_deg", None,
                                    f"advances {ratio:.3g} × the rate rotor_rpm gives (in degrees, forwards), "
                                    f"outside {_span(bounds)}: {hint}", warning=warning))
            return
    _azimuth_steps(np.diff(azimuth), file, problems)


def _azimuth_steps(d, file, problems):
    """Every step of `azimuth_deg` must advance by about the record's typical step: the
    analysis counts revolutions on each one (window edges, the sizes of its window plan), so
    one sample that stands still, runs back or jumps (a logger glitch reading 0, a repeated
    or skipped value) would move the windows. Refused at the first such sample's row."""
    step = (d + 180.0) % 360.0 - 180.0
    forward = step[step > 0]
    if not forward.size:
        return
    typical = float(np.median(forward))
    lo, hi = AZIMUTH_STEP_SPAN
    bad = (step < lo * typical) | (step > hi * typical)
    if bad.any():
        i = int(np.argmax(bad))
        problems.append(Problem(file, "azimuth_deg", i + 2,
                                f"steps {step[i]:+.3g}° from the sample before, where the record's typical step is "
                                f"{typical:.3g}° (allowed {lo:g}-{hi:g} × that): a glitch in the azimuth signal"
                                + (f"; {int(bad.sum())} such steps in the record" if bad.sum() > 1 else "")))


def rebase_time(df: pd.DataFrame, file: str) -> tuple[pd.DataFrame, list[Problem]]:
    """A record whose time stamps single precision would round by more than
    `TIME_PRECISION_SHARE` of its sample step (large absolute times: seconds of the day, GPS
    time) is rebased to start at 0 s, with a warning naming the file; one that stays too
    coarse even so (an extremely long record) is an error. Never rounded silently.

    Returns:
        (the record, rebased or as it was; its problems).
    """
    t = _numeric(df["time_s"])
    step = float(np.median(np.diff(t)))
    coarse = lambda v: float(np.spacing(np.float32(np.max(np.abs(v))))) > TIME_PRECISION_SHARE * step  # noqa: E731
    if not coarse(t):
        return df, []
    if coarse(t - t[0]):
        return df, [Problem(file, "time_s", None, f"{t[-1] - t[0]:.6g} s long at {step:.3g} s steps: too long for "
                            "single-precision times; split the record")]
    rounding = float(np.spacing(np.float32(np.max(np.abs(t)))))
    return df.assign(time_s=t - t[0]), [Problem(
        file, "time_s", None, f"starts at {t[0]:.10g} s: rebased to start at 0 s (single precision would round its "
        f"times by {rounding:.3g} s, {rounding / step:.2g} of a step); its results give times from the record's start",
        warning=True)]


def condition_consistency(counters: pd.DataFrame) -> list[Problem]:
    """Problems between the rows of `counters.csv` (canonical columns): the counters of one
    condition share its maneuver kind, and each segment of a condition is one counter."""
    problems = []
    first = counters.groupby("condition", sort=False).maneuver.transform("first")
    row = next((i + 1 for i, bad in enumerate((counters.maneuver != first).to_numpy()) if bad), None)
    if row is not None:
        r = counters.iloc[row - 1]
        problems.append(Problem("counters.csv", "maneuver", row, f"condition {r.condition!r} is a "
                                f"{first.iloc[row - 1]} in an earlier row and a {r.maneuver} here: one condition, one "
                                "maneuver kind"))
    dup = counters.duplicated(["condition", "segment"]).to_numpy()
    row = next((i + 1 for i, bad in enumerate(dup) if bad), None)
    if row is not None:
        r = counters.iloc[row - 1]
        problems.append(Problem("counters.csv", "segment", row, f"condition {r.condition!r} has segment {r.segment} "
                                "twice: number a condition's segments 1, 2, ... in flight order"))
    return problems
