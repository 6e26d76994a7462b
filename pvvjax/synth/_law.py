"""What the vibration law alone puts into a campaign: the noise-free N/rev amplitude of each
record under the campaign's own settings and under variants of them (an effect switched off,
a law drawn wrong), all on one simulated flight, so that their differences are the effects'
own contributions and nothing else."""

from __future__ import annotations

import zlib
from dataclasses import replace
from typing import Mapping

import numpy as np
import pandas as pd

from ._generate import (
    EffectConfig,
    SynthConfig,
    campaign_conditions,
    condition_scatter,
    flight,
    record_parts,
    seen_state,
)
from ._vibration import EFFECTS, amplitude_4p

__all__ = ["law_amplitudes", "simulation_config"]

# What a variant may change: what the vibration law sees, never the flight or the records.
_LAW_FIELDS = ("effects", "load_factor", "vibration_weight_lb", "noise_g", "name")


def law_amplitudes(cfg: SynthConfig, variants: Mapping[str, SynthConfig] | None = None,
                   scatter: bool = False) -> dict[str, pd.DataFrame]:
    """The vertical N/rev amplitude each record of the campaign `cfg` carries, without the
    measurement noise: the vibration law through its lags and modes, at the record's samples.

    Every variant is evaluated on the flight of `cfg` (simulated once), so a variant with one
    effect switched off differs from `cfg` by exactly that effect's contribution, and a variant
    whose law is drawn wrong (`simulation_config`) is a simulation of the same flight.

    Args:
        cfg: the campaign (`generate(cfg)` writes the same records).
        variants: column name -> a config that differs from `cfg` only in what the vibration
            law sees (`effects`, `load_factor`, `vibration_weight_lb`); default: one column
            "law", `cfg` itself. A variant that changes the flight, the conditions or the
            scatter draws is refused, naming the field.
        scatter: multiply by each condition's scatter factor (`cfg`'s draws), as the campaign
            does before the noise; without it, the law's own level.

    Returns:
        counter -> DataFrame of `time_s` (s, from the record's start, as the campaign's) and
        one column per variant, g.
    """
    variants = {"law": cfg} if variants is None else dict(variants)
    for name, v in variants.items():
        _same_flight(cfg, v, name)
    conds = campaign_conditions(cfg)
    t, states = flight(cfg, conds)
    dt = float(t[1] - t[0])
    factor = condition_scatter(cfg, conds)[:, None] if scatter else 1.0
    a4 = {name: amplitude_4p(seen_state(v, states), v.effect_settings(), dt)[0] * factor
          for name, v in variants.items()}
    out = {}
    for k, c in enumerate(conds):
        ts = np.arange(0.0, c.duration_s, 1.0 / cfg.sample_rate_hz)
        cols = {name: np.interp(ts, t, a[k]) for name, a in a4.items()}
        for counter, idx, _ in record_parts(c, ts.size):
            out[counter] = pd.DataFrame({"time_s": ts[idx] - ts[idx[0]], **{n: col[idx] for n, col in cols.items()}})
    return out


def _same_flight(cfg: SynthConfig, v: SynthConfig, name: str) -> None:
    keep = {f: getattr(cfg, f) for f in cfg.__dataclass_fields__ if f not in _LAW_FIELDS}
    for field_name, value in keep.items():
        if getattr(v, field_name) != value:
            raise ValueError(f"variants.{name}: changes {field_name} ({getattr(v, field_name)!r}, the campaign's "
                             f"{value!r}); a variant may change only what the vibration law sees "
                             f"({', '.join(f for f in _LAW_FIELDS if f not in ('name', 'noise_g'))})")


def simulation_config(cfg: SynthConfig, spread: float = 0.3, planted: tuple[str, ...] | None = None) -> SynthConfig:
    """A simulation of the campaign `cfg`: its vibration law with every coefficient of its
    default effects drawn wrong, and its planted effects left out.

    This stands for a user's physics code (a comprehensive rotorcraft analysis) whose
    predicted vibration is compared with the measurement: it knows the campaign's base physics
    (the steady law, the maneuver transients, the airframe resonance, the lags, the measured
    load factor), each coefficient of the vertical law and the resonance's gain off by a
    factor U(1 − spread, 1 + spread) (the resonance's frequency and the lags as the campaign's),
    and nothing of what was planted. Against it, a campaign without planted effects has nothing missing, and
    one with them misses exactly those. The draws come from the seed's own stream, so every
    campaign of one seed (with or without planted effects) gets the same simulation.

    Args:
        cfg: the campaign.
        spread: the relative half-width of each coefficient's error, within 0 to 1.
        planted: the effects to leave out (default: every effect that is off by default and
            on in `cfg`, the generator's hidden effects).

    Returns:
        a config of the same flight (`law_amplitudes` takes it as a variant).
    """
    if not 0 <= spread < 1:
        raise ValueError(f"spread = {spread:g}: a relative half-width within 0 (included) to 1")
    settings = cfg.effect_settings()
    planted = tuple(n for n, e in EFFECTS.items() if not e.default_on and settings[n][0]) if planted is None \
        else planted
    rng = np.random.default_rng([cfg.seed, zlib.crc32(b"simulation")])
    effects = {}
    for name, eff in EFFECTS.items():  # a fixed order, so the draws do not depend on what is planted
        on, scale, params = settings[name]
        wrong = {p: float(v * rng.uniform(1.0 - spread, 1.0 + spread)) for p, v in params.items()}
        if name in planted:
            effects[name] = EffectConfig(enabled=False)
        elif eff.default_on and eff.axis == "z" and eff.kind == "additive":
            effects[name] = EffectConfig(enabled=on, scale=scale, params=wrong)
        elif eff.default_on and eff.kind == "gain":  # the mode's strength, not where it sits
            effects[name] = EffectConfig(enabled=on, scale=scale, params={**params, "gain": wrong["gain"]})
        elif name in cfg.effects:
            effects[name] = cfg.effects[name]
    return replace(cfg, name=f"{cfg.name}-simulation", effects=effects)
