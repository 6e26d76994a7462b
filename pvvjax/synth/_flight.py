"""A simple UH-60A flight-dynamics model driven by a pilot model.

Everything is vectorised over conditions (arrays of shape (K,)) and stepped at a fixed
dynamics rate, so the whole campaign is simulated in one loop.

Trim (momentum theory plus profile and parasite power):
    P_req = [κ·nW·v_i + ρA(ΩR)³σC_d0/8·(1 + 4.65μ²) + ½ρfV³ + W·ḣ] / (550·η)
    v_i = sqrt(-V²/2 + sqrt(V⁴/4 + v_h⁴)),  v_h² = nW / (2ρA)       (Glauert)
    collective = c0 + c1·P_req·(Ω₀/Ω)        longitudinal = 40 + 0.17·V + weight/climb terms
    lateral    = 55 + 0.035·V − weight term   pedal = 30 + 0.012·P_req − 0.04·V
so that trim sticks vary with speed and weight (the collective carries weight only through
power, mixed with speed, climb, density and rotor speed).

Dynamics (first-order lags, time constants in `FLIGHT`):
    q̇ = [K_q·(δe_trim(V) − δe) − q] / τ_q            pitch rate, flight-path axes
    γ̇ = q − γ/τ_γ;  V̇ = −g·sin γ + (V₀ − V)/τ_V        flight-path angle, speed
    ṗ = [K_p·(δa − δa_trim) − p] / τ_p;  φ̇ = p          roll
    ḣ_c → (P_cmd − P_level)·550η·60/W  (τ_h);  ḣ = ḣ_c + V·sin γ
    n_z = (1 + qV/g)/cos φ + ḧ_c/g                    load factor (the MLF plus climb acceleration)
    Ω → Ω_set (power on) or Ω_set·(1.04 − 0.0035·(δc − 8)) (power off)  (τ_Ω)
    P_shaft → P_cmd (power on) or ~0 (power off)       (τ_P)
    β → K_β·(δp − δp_trim)                            sideslip (τ_β)

The pitch rate is the flight-path-axes pitch rate (as in the paper's MLF), so a steady
level turn has no pitch rate and MLF = 1/cos φ; the turn rate appears as yaw rate.
"""

from __future__ import annotations

import numpy as np

from ..data.constants import KT_TO_FT_S, UH60A

RHO0 = UH60A.rho0_slug_ft3
AREA = UH60A.disk_area_ft2
RADIUS = UH60A.rotor_radius_ft
NOMINAL_RPM = UH60A.nominal_rpm
G = UH60A.g_ft_s2

FLIGHT = dict(
    kappa=1.15, cd0=0.0095, flat_plate_ft2=26.0, eta=0.95,
    coll0=2.0, coll1=0.031,
    K_q=2.0, tau_q=0.4, tau_gamma=10.0, tau_V=25.0,
    K_p=3.0, tau_p=0.3, tau_h=1.8, tau_omega_on=0.6, tau_omega_off=1.2, tau_P=0.6,
    K_beta=0.8, tau_beta=0.8,
    pilot_K_phi=0.25, pilot_K_p=0.05, pilot_K_gamma=0.08,
)


def power_required_hp(v_kt, w_lb, sigma, rpm, climb_fpm=0.0, n=1.0):
    """Main-rotor power required, hp (negative climb power can make it < 0: autorotation)."""
    rho = RHO0 * sigma
    vt = rpm * 2 * np.pi / 60 * RADIUS
    v = np.maximum(v_kt, 0.0) * KT_TO_FT_S
    wn = w_lb * n
    vh2 = wn / (2 * rho * AREA)
    vi = np.sqrt(-(v**2) / 2 + np.sqrt(v**4 / 4 + vh2**2))
    mu = v / vt
    p_ind = FLIGHT["kappa"] * wn * vi
    p_0 = rho * AREA * vt**3 * UH60A.solidity * FLIGHT["cd0"] / 8 * (1 + 4.65 * mu**2)
    p_par = 0.5 * rho * FLIGHT["flat_plate_ft2"] * v**3
    p_climb = w_lb * climb_fpm / 60.0
    return (p_ind + p_0 + p_par + p_climb) / (550.0 * FLIGHT["eta"])


def collective_for_power(p_hp, rpm):
    return np.clip(FLIGHT["coll0"] + FLIGHT["coll1"] * p_hp * NOMINAL_RPM / rpm, 0.0, 100.0)


def power_for_collective(coll, rpm):
    return (coll - FLIGHT["coll0"]) / FLIGHT["coll1"] * rpm / NOMINAL_RPM


def trim_sticks(v_kt, w_lb, sigma, rpm, climb_fpm=0.0, n=1.0):
    """Trim stick positions (%): collective, lateral, longitudinal, pedal."""
    p = power_required_hp(v_kt, w_lb, sigma, rpm, climb_fpm, n)
    coll = collective_for_power(p, rpm)
    lon = 40.0 + 0.17 * v_kt + 0.0004 * (w_lb - 16000.0) - 0.001 * climb_fpm
    lat = 55.0 + 0.035 * v_kt - 0.0003 * (w_lb - 16000.0)
    ped = 30.0 + 0.012 * np.maximum(p, 0.0) - 0.04 * v_kt
    return coll, np.clip(lat, 0, 100), np.clip(lon, 0, 100), np.clip(ped, 0, 100)


def _alpha(dt, tau):
    return 1.0 - np.exp(-dt / tau)


# The states and sticks `simulate` returns, in the order its step computes them.
_OUTPUTS = ("airspeed_kt", "pitch_rate_dps", "roll_angle_deg", "roll_rate_dps", "yaw_rate_dps", "climb_rate_fpm",
            "pitch_angle_deg", "nz_g", "rotor_rpm", "shaft_power_hp", "altitude_ft", "sideslip_deg",
            "collective_pct", "lateral_pct", "longitudinal_pct", "pedal_pct", "pitch_accel_dps2")


def simulate(init: dict, sched: dict, dt: float) -> dict:
    """Step the flight model for K conditions over N steps.

    Args:
        init: (K,) arrays: v_kt, w_lb, sigma, rpm_set, climb_fpm, phi_deg.
        sched: (K, N) arrays of the pilot's plan: dcoll, dlon, dped (stick offsets from
            trim, %), phi_cmd (bank command, deg), power_on (0/1), v_hold (speed the pilot
            holds, kt), plus noise_lat, noise_lon, noise_coll (pilot noise, %).
        dt: step, s.

    Returns:
        (K, N) arrays of every state and stick.
    """
    F = FLIGHT
    K, N = sched["dcoll"].shape
    w, sig, rpm_set = init["w_lb"], init["sigma"], init["rpm_set"]
    v = init["v_kt"].astype(float).copy()
    climb0 = init["climb_fpm"]
    phi = init["phi_deg"].astype(float).copy()
    n0 = 1.0 / np.cos(np.deg2rad(phi))
    coll_trim0 = collective_for_power(power_required_hp(v, w, sig, rpm_set, climb0, n0), rpm_set)
    q, gam, p, beta = np.zeros(K), np.zeros(K), np.zeros(K), np.zeros(K)
    hc, omega = climb0.astype(float).copy(), rpm_set.astype(float).copy()
    pw = np.maximum(power_required_hp(v, w, sig, rpm_set, climb0, n0), 0.0)
    alt = np.full(K, 1000.0)
    out = {k: np.zeros((K, N)) for k in _OUTPUTS}
    a = {k: _alpha(dt, F[k]) for k in ("tau_q", "tau_p", "tau_h", "tau_P", "tau_beta", "tau_omega_on", "tau_omega_off")}
    n_prev = n0
    for i in range(N):
        on = sched["power_on"][:, i] > 0.5
        _, lat_t, lon_t, ped_t = trim_sticks(v, w, sig, omega, 0.0)
        # pilot: open-loop plan plus attitude-hold feedback and noise
        coll = np.clip(coll_trim0 + sched["dcoll"][:, i] + sched["noise_coll"][:, i], 0, 100)
        lon = np.clip(lon_t + sched["dlon"][:, i] + F["pilot_K_gamma"] * gam + sched["noise_lon"][:, i], 0, 100)
        lat = np.clip(lat_t + F["pilot_K_phi"] * (sched["phi_cmd"][:, i] - phi) - F["pilot_K_p"] * p
                      + sched["noise_lat"][:, i], 0, 100)
        ped = np.clip(ped_t + sched["dped"][:, i], 0, 100)
        # pitch and flight path
        q_new = q + (F["K_q"] * (lon_t - lon) - q) * a["tau_q"]
        qdot = (q_new - q) / dt
        q = q_new
        gam = gam + (q - gam / F["tau_gamma"]) * dt
        v_fts = np.maximum(v, 1.0) * KT_TO_FT_S
        v = v + (-G * np.sin(np.deg2rad(gam)) / KT_TO_FT_S + (sched["v_hold"][:, i] - v) / F["tau_V"]) * dt
        v = np.maximum(v, 0.0)
        # roll
        p = p + (F["K_p"] * (lat - lat_t) - p) * a["tau_p"]
        phi = np.clip(phi + p * dt, -80.0, 80.0)
        # climb from collective (power) and rotor speed
        p_level = power_required_hp(v, w, sig, omega, 0.0, n_prev)
        p_cmd = np.where(on, power_for_collective(coll, omega), 0.0)
        hc_target = (p_cmd - p_level) * 550.0 * F["eta"] * 60.0 / w
        hc_new = hc + (hc_target - hc) * a["tau_h"]
        hdd = (hc_new - hc) / dt / 60.0  # ft/s²
        hc = hc_new
        om_target = np.where(on, rpm_set, rpm_set * np.clip(1.04 - 0.0035 * (coll - 8.0), 0.85, 1.08))
        omega = omega + (om_target - omega) * np.where(on, a["tau_omega_on"], a["tau_omega_off"])
        pw = pw + (np.where(on, np.maximum(p_cmd, 0.0), 10.0) - pw) * a["tau_P"]
        beta = beta + (F["K_beta"] * (ped - ped_t) - beta) * a["tau_beta"]
        hdot = hc + 60.0 * v_fts * np.sin(np.deg2rad(gam))
        alt = alt + hdot / 60.0 * dt
        n_kin = (1.0 + np.deg2rad(q) * v_fts / G) / np.cos(np.deg2rad(phi))
        nz = n_kin + hdd / G
        # Power follows the kinematic load factor only: feeding the climb acceleration back
        # into power required would close an algebraic loop that diverges at low speed.
        n_prev = np.maximum(n_kin, 0.1)
        r = np.rad2deg(G * np.tan(np.deg2rad(phi)) / v_fts)
        theta = 4.0 - 0.055 * v + gam
        for k, val in zip(_OUTPUTS, (v, q, phi, p, r, hdot, theta, nz, omega, pw, alt, beta, coll, lat, lon, ped,
                                     qdot)):
            out[k][:, i] = val
    return out
