"""The 4/rev pilot-floor vibration of the synthetic campaign, built from named effects.

The quasi-static 4P amplitude is a sum of additive effects, each a function of the flight
state (see `EFFECTS` for every formula), multiplied by the airframe's response at 4Ω
(`rotor_resonance`, `rotor_band`), and then passed through first-order lags (`dynamic_lag`,
`slow_lag`) and, where switched on, a second-order response (`second_order`): the vibratory
response follows a change of flight state with a delay, and may overshoot.

    A4_static = Σ_additive scale_e · f_e(state)
    A4        = mode_ωn,ζ( slow_lag( lag_τ( Π_gain G_e · A4_static · (1 + scatter) ) ) )

Each effect has an on/off switch, a scale and named parameters, all set from the
generator config. Symbols: μ advance ratio, L = C_W/σ·n_z blade loading, ḣ climb rate
(ft/min), q pitch rate (deg/s), q̇ pitch acceleration (deg/s²), p roll rate (deg/s), r yaw
rate (deg/s), β sideslip (deg), θ₀ collective (%), δ_lon longitudinal stick (%), f₄ = 4Ω/2π
(Hz), Ω% rotor speed (% of nominal), s(x) = w·softplus(x/w) a smooth ramp.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np


def _ramp(x, w):
    """Smooth max(x, 0) with corner width w."""
    return w * np.logaddexp(0.0, x / w)


@dataclass(frozen=True)
class Effect:
    """A named physical effect on the 4P amplitude."""

    name: str
    kind: str  # "additive", "gain", "lag" or "once_per_rev"
    formula: str
    physics: str
    params: dict
    channels: tuple[str, ...]
    default_on: bool = True
    fn: Callable | None = None
    axis: str = "z"  # the pilot-floor axis whose N/rev it shapes: "z" vertical, "y" lateral, "x" longitudinal


def _baseline(s, a0):
    return np.full_like(s["mu"], a0)


def _transition(s, a, mu0, width):
    return a * np.exp(-(((s["mu"] - mu0) / width) ** 2))


def _high_speed(s, a, mu0):
    return a * _ramp(s["mu"] - mu0, 0.01) ** 2


def _blade_loading(s, a, l0):
    return a * _ramp(s["loading"] - l0, 0.005)


def _dynamic_stall(s, a, knee, saturation):
    return a * saturation * np.tanh(_ramp(s["loading"] - knee, 0.004) / saturation)


def _descent_bvi(s, a, mu0, mu_width, climb0, climb_width, l_ref):
    return (a * (s["loading"] / l_ref) ** 2 * np.exp(-(((s["mu"] - mu0) / mu_width) ** 2))
            * np.exp(-(((s["climb_fpm"] - climb0) / climb_width) ** 2)))


def _pitch_rate(s, a):
    return a * np.abs(s["q"])


def _roll_rate(s, a):
    return a * np.abs(s["p"])


def _pitch_acceleration(s, a):
    return a * np.abs(s["qdot"])


def _sideslip(s, a):
    return a * np.abs(s["beta"])


def _collective_stall(s, a, knee):
    return a * _ramp(s["collective"] - knee, 1.0)


def _yaw_rate(s, a):
    return a * np.abs(s["r"])


def _stick_knee(s, a, knee):
    return a * _ramp(s["lon"] - knee, 1.0)


def _rotor_band(s, gain, center_pct, width_pct):
    return 1.0 + gain / (1.0 + ((s["rpm_pct"] - center_pct) / width_pct) ** 2)


def _lateral_tail_rotor(s, a, mu0, width, q_ref):
    return a * np.exp(-(((s["mu"] - mu0) / width) ** 2)) * (1.0 + np.abs(s["q"]) / q_ref)


def _bank(s, a):
    return a * np.abs(np.sin(np.deg2rad(s["phi"])))


def _longitudinal_trend(s, ratio):
    return ratio * sum(EFFECTS[name].fn(s, **EFFECTS[name].params) for name in _TREND)


def _rotor_resonance(s, gain, f_mode, bandwidth, f_ref):
    h = lambda f: 1.0 + gain / (1.0 + ((f - f_mode) / bandwidth) ** 2)  # noqa: E731
    return h(s["f4"]) / h(f_ref)


EFFECTS: dict[str, Effect] = {e.name: e for e in [
    Effect("baseline", "additive", "a0",
           "steady 4P of the rotor in any flight condition (hub loads at 4Ω)",
           dict(a0=0.040), (), fn=_baseline),
    Effect("transition", "additive", "a·exp(−((μ − μ0)/width)²)",
           "rotor wake close to the disk at low speed (transition, μ ≈ 0.05–0.12): blade-vortex interaction",
           dict(a=0.09, mu0=0.08, width=0.06), ("advance_ratio",), fn=_transition),
    Effect("high_speed", "additive", "a·s(μ − μ0)²",
           "advancing-blade compressibility and negative lift at high speed (μ ≳ 0.3)",
           dict(a=14.2, mu0=0.26), ("advance_ratio",), fn=_high_speed),
    Effect("blade_loading", "additive", "a·s(L − l0)",
           "4P hub loads grow with blade loading C_W/σ·n (weight, density, rotor speed, load factor)",
           dict(a=0.7, l0=0.055), ("blade_loading",), fn=_blade_loading),
    Effect("dynamic_stall", "additive", "a·sat·tanh(s(L − knee)/sat)",
           "retreating-blade dynamic stall above a blade-loading knee (pull-ups, tight turns, high weight/altitude)",
           dict(a=5.5, knee=0.12, saturation=0.05), ("blade_loading",), fn=_dynamic_stall),
    Effect("descent_bvi", "additive",
           "a·(L/l_ref)²·exp(−((μ − mu0)/mu_width)²)·exp(−((ḣ − climb0)/climb_width)²)",
           "descent at low to moderate speed puts the wake of a loaded rotor into the disk: blade-vortex "
           "interaction (strongest in powered descent and recovery from autorotation)",
           dict(a=0.15, mu0=0.15, mu_width=0.07, climb0=-900.0, climb_width=550.0, l_ref=0.07),
           ("advance_ratio", "climb_rate_fpm", "blade_loading"), fn=_descent_bvi),
    Effect("pitch_rate", "additive", "a·|q|",
           "maneuver transient: rotor flapping and inflow change with body pitch rate",
           dict(a=0.003), ("pitch_rate_dps",), fn=_pitch_rate),
    Effect("roll_rate", "additive", "a·|p|",
           "maneuver transient: asymmetric inflow and flapping with roll rate",
           dict(a=0.0015), ("roll_rate_dps",), fn=_roll_rate),
    Effect("pitch_acceleration", "additive", "a·|q̇|",
           "maneuver transient: hub moment demand during pitch acceleration",
           dict(a=0.004), ("pitch_rate_dps",), default_on=False, fn=_pitch_acceleration),
    Effect("sideslip", "additive", "a·|β|",
           "tail-rotor and fuselage interference with the main-rotor wake in sideslip (pedal)",
           dict(a=0.005), ("sideslip_deg", "pedal_pct"), default_on=False, fn=_sideslip),
    Effect("collective_stall", "additive", "a·s(θ₀ − knee)",
           "retreating-blade stall at high collective pitch θ₀ (%), beyond a knee the steady data rarely reach",
           dict(a=0.006, knee=62.0), ("collective_pct",), default_on=False, fn=_collective_stall),
    Effect("rotor_resonance", "gain", "H(f4)/H(f_ref), H(f) = 1 + gain/(1 + ((f − f_mode)/bandwidth)²)",
           "airframe response at 4Ω near a fuselage mode (H-60 pilot-station peak at 17–17.5 Hz)",
           dict(gain=0.5, f_mode=17.4, bandwidth=0.6, f_ref=17.19), ("rotor_rpm",), fn=_rotor_resonance),
    Effect("yaw_rate", "additive", "a·|r|",
           "maneuver transient: tail-rotor thrust changes and the main-rotor wake swept sideways with yaw rate",
           dict(a=0.002), ("yaw_rate_dps",), default_on=False, fn=_yaw_rate),
    Effect("stick_knee", "additive", "a·s(δ_lon − knee)",
           "hub moments grow once the longitudinal cyclic passes a knee (aft c.g., high-speed or pull-up "
           "trim): the blades fly at large cyclic pitch", dict(a=0.006, knee=64.0), ("longitudinal_pct",),
           default_on=False, fn=_stick_knee),
    Effect("rotor_band", "gain", "1 + gain/(1 + ((Ω% − center_pct)/width_pct)²)",
           "a second airframe or drive-train mode met in a narrow band of rotor speed (Ω% of nominal): "
           "the whole N/rev is magnified there", dict(gain=1.0, center_pct=103.0, width_pct=1.0),
           ("rotor_rpm",), default_on=False, fn=_rotor_band),
    Effect("lateral_baseline", "additive", "a0",
           "steady lateral N/rev at the pilot floor: in-plane hub shears reach the seat (lateral axis)",
           dict(a0=0.025), (), fn=_baseline, axis="y"),
    Effect("lateral_sideslip", "additive", "a·|β|",
           "sideslip puts the tail rotor and fin into the main-rotor wake off-axis: lateral N/rev grows "
           "with |β| (flares, uncoordinated turns)", dict(a=0.02), ("sideslip_deg",), fn=_sideslip, axis="y"),
    Effect("lateral_roll_rate", "additive", "a·|p|",
           "roll rate tilts the disk and loads the blades asymmetrically: lateral N/rev in turn entries "
           "and rolls", dict(a=0.004), ("roll_rate_dps",), fn=_roll_rate, axis="y"),
    Effect("lateral_tail_rotor", "additive", "a·exp(−((μ − μ0)/width)²)·(1 + |q|/q_ref)",
           "at low speed the main-rotor wake sweeps over the tail rotor; a pitch-up (flare) moves it through "
           "the tail-rotor disk", dict(a=0.05, mu0=0.12, width=0.07, q_ref=2.0),
           ("advance_ratio", "pitch_rate_dps"), fn=_lateral_tail_rotor, axis="y"),
    Effect("lateral_bank", "additive", "a·|sin φ|",
           "in a banked turn the tail-rotor thrust and the rotor's lateral shears grow with the load it "
           "carries sideways", dict(a=0.25), ("roll_angle_deg",), fn=_bank, axis="y"),
    Effect("longitudinal_trend", "additive", "ratio·(baseline + transition + high_speed + blade_loading + "
           "dynamic_stall)", "the longitudinal N/rev follows the vertical's advance-ratio and blade-loading "
           "trends at a lower level (the same hub loads, a stiffer path to the seat)",
           dict(ratio=0.45), ("advance_ratio", "blade_loading"), fn=_longitudinal_trend, axis="x"),
    Effect("track_balance", "once_per_rev", "a_x·cos(ψ + φ_x), a_y·cos(ψ + φ_y)",
           "rotor track and balance: a 1/rev at the pilot floor, constant in amplitude with a set phase "
           "to the reference blade (longitudinal and lateral)",
           dict(a_x=0.02, phase_x=0.6, a_y=0.035, phase_y=2.2), (), fn=None, axis="xy"),
    Effect("dynamic_lag", "lag", "τ·dA/dt = A_static − A",
           "rotor inflow and wake settle after a change of flight state: the vibration lags the state",
           dict(tau_s=0.6), (), fn=None),
    Effect("slow_lag", "lag", "τ·dA/dt = A_in − A, in series with dynamic_lag",
           "a slower settling of the whole response after a change of flight state (e.g. a wake that "
           "convects over seconds), beside the fast inflow lag", dict(tau_s=2.0), (), default_on=False, fn=None),
    Effect("second_order", "lag", "d²A/dt² + 2ζω_n·dA/dt + ω_n²·A = ω_n²·A_in, ω_n = 2π·f_n_hz",
           "the vibratory response to a change of flight state as a damped mode: it overshoots and rings "
           "before it settles (unit steady-state gain)",
           dict(f_n_hz=0.5, zeta=0.4), (), default_on=False, fn=None),
]}


# The vertical effects the longitudinal trend follows (their default parameters).
_TREND = ("baseline", "transition", "high_speed", "blade_loading", "dynamic_stall")
AXES = ("z", "y", "x")


def vibration_state(states: dict, aircraft) -> dict:
    """The quantities effects use, from simulated (K, N) state arrays. The blade-passage
    frequency `f4` is expressed at the UH-60A's scale (N/rev over the aircraft's nominal N/rev,
    times the UH-60A's 4/rev at its nominal rpm), so that the airframe resonance sits at the
    same place relative to the rotor on every aircraft."""
    from ..data.constants import KT_TO_FT_S, RPM_TO_RAD_S, UH60A

    vt = states["rotor_rpm"] * RPM_TO_RAD_S * aircraft.rotor_radius_ft
    mu = states["airspeed_kt"] * KT_TO_FT_S / vt
    rho = aircraft.rho0_slug_ft3 * states["density_ratio"]
    cw = states["gross_weight_lb"] / (rho * aircraft.disk_area_ft2 * vt**2)
    return dict(
        mu=mu, loading=cw / aircraft.solidity * states["nz_g"], climb_fpm=states["climb_rate_fpm"],
        q=states["pitch_rate_dps"], p=states["roll_rate_dps"], qdot=states["pitch_accel_dps2"],
        beta=states["sideslip_deg"], collective=states["collective_pct"], phi=states["roll_angle_deg"],
        r=states["yaw_rate_dps"], lon=states["longitudinal_pct"],
        rpm_pct=100.0 * states["rotor_rpm"] / aircraft.nominal_rpm,
        f4=aircraft.blades * states["rotor_rpm"] / 60.0 * (UH60A.nominal_np_hz() / aircraft.nominal_np_hz()),
    )


def first_order_lag(x: np.ndarray, tau: float, dt: float) -> np.ndarray:
    """y' = (x − y)/τ along the last axis, exact for piecewise-constant input; y(0) = x(0)."""
    if tau <= 0:
        return x
    a = 1.0 - np.exp(-dt / tau)
    y = np.empty_like(x)
    y[..., 0] = x[..., 0]
    for i in range(1, x.shape[-1]):
        y[..., i] = y[..., i - 1] + a * (x[..., i] - y[..., i - 1])
    return y


def second_order_response(u: np.ndarray, dt, omega_n: float, zeta: float) -> np.ndarray:
    """y'' + 2ζω_n y' + ω_n² y = ω_n² u along the last axis, from rest at u's first value
    (y = u[0], y' = 0), integrated by the trapezoidal rule (Tustin), which keeps the steady
    gain exactly 1.

    Args:
        u: (..., N) input.
        dt: step(s) between samples, s: a scalar, or (..., N − 1); a step of 0 holds the state.
        omega_n: natural frequency, rad/s. zeta: damping ratio.

    Returns:
        (..., N) response.
    """
    u = np.asarray(u, float)
    dt = np.broadcast_to(np.asarray(dt, float), u.shape[:-1] + (u.shape[-1] - 1,))
    w2, c = omega_n**2, 2.0 * zeta * omega_n
    y, v = u[..., 0].copy(), np.zeros(u.shape[:-1])
    out = np.empty_like(u)
    out[..., 0] = y
    for i in range(1, u.shape[-1]):
        a = 0.5 * dt[..., i - 1]
        r0 = y + a * v
        r1 = v - a * w2 * y - a * c * v + a * w2 * (u[..., i - 1] + u[..., i])
        det = 1.0 + a * c + a * a * w2
        y, v = ((1.0 + a * c) * r0 + a * r1) / det, (-a * w2 * r0 + r1) / det
        out[..., i] = y
    return out


def amplitude_4p(state: dict, settings: dict, dt: float) -> tuple[np.ndarray, dict]:
    """4P amplitude (g) from the vibration state.

    Args:
        state: from `vibration_state`, (K, N) arrays.
        settings: effect name -> (enabled, scale, params).
        dt: sample step of the state arrays, s.

    Returns:
        (A4 after gain and lag, per-effect additive contributions before the lag).
    """
    total, parts = _additive(state, settings, "z")
    for name, eff in EFFECTS.items():  # the airframe's gains: a mode magnifies the whole N/rev
        on, scale, params = settings[name]
        if eff.kind == "gain" and on:
            total = total * (1.0 + scale * (eff.fn(state, **params) - 1.0))
    return _settle(total, settings, dt), parts


def amplitude_axis(state: dict, settings: dict, dt: float, axis: str) -> np.ndarray:
    """N/rev amplitude (g) of the lateral ("y") or longitudinal ("x") axis: the sum of that
    axis's switched-on additive effects, through the same lag and mode as the vertical (the
    rotor's inflow and wake settle the same way; the airframe's 4Ω resonance is the
    vertical's own and is left out)."""
    return _settle(_additive(state, settings, axis)[0], settings, dt)


def _additive(state: dict, settings: dict, axis: str) -> tuple[np.ndarray, dict]:
    """The sum of one axis's switched-on additive effects, and each one's contribution."""
    parts = {}
    total = np.zeros_like(state["mu"])
    for name, eff in EFFECTS.items():
        on, scale, params = settings[name]
        if eff.kind == "additive" and eff.axis == axis and on:
            parts[name] = scale * eff.fn(state, **params)
            total = total + parts[name]
    return total, parts


def _settle(total: np.ndarray, settings: dict, dt: float) -> np.ndarray:
    """An amplitude through the switched-on `dynamic_lag`, `slow_lag` and `second_order` response."""
    for name in ("dynamic_lag", "slow_lag"):
        lag_on, lag_scale, lag_params = settings[name]
        if lag_on:
            total = first_order_lag(total, lag_scale * lag_params["tau_s"], dt)
    mode_on, _, mode = settings["second_order"]
    if mode_on:
        total = second_order_response(total, dt, 2.0 * np.pi * mode["f_n_hz"], mode["zeta"])
    return total
