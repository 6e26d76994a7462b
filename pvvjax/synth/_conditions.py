"""The flight conditions of the synthetic campaign and the pilot's plan for each.

The paper's named conditions are always present with fixed parameters; the rest are drawn
from the seed. Every condition has its own random stream (seeded by the campaign seed and
the condition id), so any subset of conditions is generated identically to the full
campaign, and switching an effect on or off changes nothing but the vibration.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from ..data.constants import UH60A


@dataclass(frozen=True)
class Condition:
    """One flight condition (one or two counters)."""

    id: str
    maneuver: str
    airspeed_kt: float
    gross_weight_lb: float
    density_ratio: float = 1.0
    rpm: float = UH60A.nominal_rpm
    climb_fpm: float = 0.0
    duration_s: float = 30.0
    intensity: float = 0.0  # bank (deg) for turns/rolls, stick (%) for pulls/pushovers/flares
    t_event_s: float = 10.0
    counters: tuple[str, ...] = ()
    description: str = ""

    @property
    def counter_names(self) -> tuple[str, ...]:
        return self.counters or (self.id,)


NAMED = (
    Condition("T1-level-135", "level", 135.0, 16000.0, 1.0, UH60A.nominal_rpm, 0.0, 30.0,
              description="Table 1: level flight, 135 kt"),
    Condition("T1-descent-160", "descent", 160.0, 18000.0, 1.0, 0.97 * UH60A.nominal_rpm, -1500.0, 30.0,
              description="Table 1: descent, 160 kt"),
    Condition("T1-climb-62", "climb", 62.0, 21000.0, 0.8, UH60A.nominal_rpm, 1200.0, 30.0,
              description="Table 1: climb, 62 kt"),
    Condition("T1-turn45-145", "turn", 145.0, 16000.0, 1.0, 1.03 * UH60A.nominal_rpm, 0.0, 30.0, 45.0,
              description="Table 1: steady 45 deg turn, 145 kt"),
    Condition("11022", "pullup", 121.0, 16055.0, 1.0, 255.0, 0.0, 37.0, 5.7, 12.0,
              description="paper counter 11022: pull-up at ~120 kt"),
    Condition("AR60", "autorotation", 60.0, 15910.0, 1.0, 256.0, 0.0, 54.0, 0.0, 9.8,
              counters=("11539", "11540"),
              description="paper counters 11539/11540: autorotation at ~60 kt, two segments"),
)

DEFAULT_COUNTS = dict(level=86, climb=21, descent=27, turn=15, roll=12, pushover=8, pullup=11,
                      autorotation=5, flare=7)
SWEEP_SPEEDS = (10, 20, 30, 40, 50, 60, 70, 80, 90, 100, 110, 120, 130, 140, 150, 160, 165)
SWEEP_WEIGHTS = (15000.0, 20000.0)


def condition_rng(seed: int, cid: str) -> np.random.Generator:
    return np.random.default_rng([seed, zlib.crc32(cid.encode())])


def catalogue(seed: int, counts: dict[str, int] | None = None) -> list[Condition]:
    """All conditions of a campaign: the named ones, a level-flight speed sweep at two
    weights (sea level, 100 % rpm), and `counts` random conditions per maneuver kind."""
    counts = {**DEFAULT_COUNTS, **(counts or {})}
    out = list(NAMED)
    for w in SWEEP_WEIGHTS:
        for v in SWEEP_SPEEDS:
            out.append(Condition(f"LS{int(w / 1000)}k-{v:03d}", "level", float(v), w, 1.0, UH60A.nominal_rpm,
                                 0.0, 24.0, description=f"level sweep, {w:.0f} lb"))
    prefix = dict(level="L", climb="C", descent="D", turn="T", roll="R", pushover="PO", pullup="PU",
                  autorotation="AR", flare="F")
    for kind, n in counts.items():
        for i in range(n):
            cid = f"{prefix[kind]}{i + 1:03d}"
            r = condition_rng(seed, "catalogue:" + cid)
            w = float(r.uniform(14000, 22000))
            sig = float(r.uniform(0.75, 1.0))
            rpm = float(UH60A.nominal_rpm * r.choice([0.95, 0.975, 1.0, 1.0, 1.0, 1.025, 1.05]))
            dur = float(np.round(r.uniform(20, 40), 1))
            te = float(np.round(r.uniform(0.3, 0.45) * dur, 1))
            if kind == "level":
                c = Condition(cid, kind, float(r.uniform(10, 165)), w, sig, rpm, 0.0, dur)
            elif kind == "climb":
                c = Condition(cid, kind, float(r.uniform(40, 120)), w, sig, rpm, float(r.uniform(400, 2000)), dur)
            elif kind == "descent":
                if i % 3 == 2:  # high-speed dives
                    c = Condition(cid, kind, float(r.uniform(130, 165)), w, sig, rpm, float(r.uniform(-2500, -800)),
                                  dur)
                else:
                    c = Condition(cid, kind, float(r.uniform(30, 95)), w, sig, rpm, float(r.uniform(-1600, -300)), dur)
            elif kind == "turn":
                c = Condition(cid, kind, float(r.uniform(60, 150)), w, sig, rpm, 0.0, dur, float(r.uniform(15, 55)))
            elif kind == "roll":
                c = Condition(cid, kind, float(r.uniform(60, 140)), w, sig, rpm, 0.0, dur, float(r.uniform(20, 45)), te)
            elif kind == "pushover":
                c = Condition(cid, kind, float(r.uniform(80, 150)), w, sig, rpm, 0.0, dur, float(r.uniform(1.5, 3.0)),
                              te)
            elif kind == "pullup":
                c = Condition(cid, kind, float(r.uniform(80, 150)), w, sig, rpm, 0.0, dur, float(r.uniform(2.0, 5.0)),
                              te)
            elif kind == "autorotation":
                c = Condition(cid, kind, float(r.uniform(50, 90)), w, sig, rpm, 0.0, 54.0, 0.0,
                              float(np.round(r.uniform(8, 12), 1)), counters=(f"{cid}-1", f"{cid}-2"))
            elif kind == "flare":
                c = Condition(cid, kind, float(r.uniform(55, 85)), w, sig, rpm, float(r.uniform(-900, -400)),
                              dur, float(r.uniform(3.0, 5.0)), te)
            else:  # pragma: no cover
                raise ValueError(kind)
            out.append(c)
    return out


def _ramp_between(t, t0, t1):
    return np.clip((t - t0) / max(t1 - t0, 1e-9), 0.0, 1.0)


def _trapezoid(t, t0, rise, hold, fall):
    return _ramp_between(t, t0, t0 + rise) - _ramp_between(t, t0 + rise + hold, t0 + rise + hold + fall)


def _band_noise(rng, n, dt, sigma, tau=1.0):
    """Band-limited pilot noise: white noise through a first-order filter, std ≈ sigma."""
    a = 1.0 - np.exp(-dt / tau)
    w = rng.standard_normal(n) * sigma * np.sqrt((2 - a) / a)
    y = np.empty(n)
    acc = 0.0
    for i in range(n):
        acc += a * (w[i] - acc)
        y[i] = acc
    return y


def pilot_plan(c: Condition, t: np.ndarray, seed: int, coll_trim: float) -> dict:
    """The pilot's open-loop plan for one condition on the dynamics time grid.

    Random draws come from streams named after the condition and their purpose, and cover
    the condition's own duration, so a plan does not depend on the other conditions.

    Returns:
        dcoll, dlon, dped (% offsets from trim), phi_cmd (deg), power_on, v_hold (kt),
        and the pilot noise on the three cyclic/collective sticks.
    """
    n = t.size
    dt = float(t[1] - t[0])
    n_own = min(n, int(np.ceil(c.duration_s / dt)) + 2)
    z = np.zeros(n)
    plan = dict(dcoll=z.copy(), dlon=z.copy(), dped=z.copy(), phi_cmd=z.copy(), power_on=np.ones(n),
                v_hold=np.full(n, c.airspeed_kt))
    for stick, sigma, tau in (("lat", 0.35, 1.0), ("lon", 0.20, 1.0), ("coll", 0.25, 2.0)):
        noise = _band_noise(condition_rng(seed, f"pilot-{stick}:{c.id}"), n_own, dt, sigma, tau)
        plan[f"noise_{stick}"] = np.concatenate([noise, np.full(n - n_own, noise[-1])])
    rng = condition_rng(seed, f"pilot-plan:{c.id}")
    # occasional pedal inputs (uncoordinated flight gives sideslip)
    for _ in range(rng.integers(0, 3)):
        t0 = rng.uniform(0.1, 0.8) * c.duration_s
        plan["dped"] += rng.uniform(-6, 6) * _trapezoid(t, t0, 0.8, rng.uniform(1, 4), 0.8)
    te, k = c.t_event_s, c.intensity
    if c.maneuver == "turn":
        plan["phi_cmd"][:] = k
    elif c.maneuver == "roll":
        hold = rng.uniform(2.5, 4.0)
        plan["phi_cmd"] = k * (_trapezoid(t, te, 0.3, hold, 0.3) - _trapezoid(t, te + hold + 2.0, 0.3, hold, 0.3))
        plan["dped"] += rng.uniform(2, 6) * np.sign(rng.uniform(-1, 1)) * _trapezoid(t, te, 0.5, hold, 0.5)
    elif c.maneuver == "pushover":
        plan["dlon"] = k * _trapezoid(t, te, 0.6, 1.5, 0.6) - 0.5 * k * _trapezoid(t, te + 2.7, 0.6, 1.5, 0.6)
        plan["dcoll"] = -4.0 * _trapezoid(t, te, 0.6, 2.0, 1.5)
    elif c.maneuver == "pullup":
        plan["dlon"] = -k * _trapezoid(t, te, 1.0, 2.2, 1.0) + 0.6 * k * _trapezoid(t, te + 4.2, 0.8, 2.0, 1.0)
        plan["dcoll"] = (6.0 * k) * _trapezoid(t, te - 0.5, 1.5, 2.5, 2.0)
    elif c.maneuver == "flare":
        plan["dlon"] = -k * _trapezoid(t, te, 1.0, 3.0, 1.5)
        plan["dcoll"] = 16.0 * _trapezoid(t, te + 2.0, 1.5, 5.0, 3.0)
        plan["v_hold"] = c.airspeed_kt - (c.airspeed_kt - 20.0) * _ramp_between(t, te, te + 6.0)
    elif c.maneuver == "autorotation":
        t_cut, t_rec = te, 27.0 + 10.3 if c.id == "AR60" else te + rng.uniform(22, 30)
        plan["power_on"] = np.where((t >= t_cut) & (t < t_rec), 0.0, 1.0)
        down = (8.0 - coll_trim) * _ramp_between(t, t_cut, t_cut + 1.5)
        up = (70.0 - 8.0) * _ramp_between(t, t_rec - 0.3, t_rec + 1.7)
        plan["dcoll"] = down + up - (70.0 - coll_trim) * _ramp_between(t, t_rec + 6.0, t_rec + 12.0)
        plan["dlon"] = -2.5 * _trapezoid(t, t_rec, 0.8, 2.5, 1.5)
        plan["noise_coll"] *= 0.5
    return plan
