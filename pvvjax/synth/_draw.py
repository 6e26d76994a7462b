"""Campaigns drawn at random: the full default physics with its law, noise, scatter, size
and aircraft drawn per campaign over declared ranges, and hidden effects planted with drawn
parameters, so that a rule judged on such campaigns is judged on what real campaigns vary,
not on one campaign's fixed values.

A drawn campaign is a pure function of (ranges, seed): the base draws come from the seed's
own stream and each planted effect from a stream of its own, so the campaign without
planted effects and one with them share their base (conditions, pilot inputs, law, noise)
exactly, and a planted effect's gap is measured against the one without."""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ._conditions import DEFAULT_COUNTS, NAMED, SWEEP_SPEEDS, SWEEP_WEIGHTS
from ._generate import EffectConfig, SynthConfig, _min_sample_rate_hz
from ._vibration import EFFECTS

__all__ = ["Planted", "Span", "CampaignDraw", "draw_campaign", "law_effects"]


@dataclass(frozen=True)
class Span:
    """A number drawn per campaign: uniform on [lo, hi], or log-uniform with `log` (for a scale
    over decades). lo = hi fixes it."""

    lo: float
    hi: float
    log: bool = False

    def __post_init__(self):
        if not self.lo <= self.hi:
            raise ValueError(f"a span needs lo <= hi, got [{self.lo:g}, {self.hi:g}]")
        if self.log and not self.lo > 0:
            raise ValueError(f"a log-uniform span needs lo > 0, got {self.lo:g}")

    def sample(self, rng: np.random.Generator) -> float:
        u = rng.uniform()
        if self.log:
            return float(math.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo))))
        return float(self.lo + u * (self.hi - self.lo))


@dataclass(frozen=True)
class Planted:
    """A hidden effect planted in a drawn campaign: a generator effect (`pvvjax.synth.EFFECTS`)
    switched on, its scale and named parameters drawn per campaign (a parameter not listed
    keeps its default; no scale: 1)."""

    effect: str
    scale: Span | None = None
    params: dict[str, Span] = field(default_factory=dict)

    def __post_init__(self):
        if self.effect not in EFFECTS:
            raise ValueError(f"effect {self.effect!r}: unknown; known: {', '.join(EFFECTS)}")
        unknown = sorted(set(self.params) - set(EFFECTS[self.effect].params))
        if unknown:
            raise ValueError(f"effect {self.effect!r}: unknown parameter(s) {unknown}; known: "
                             f"{', '.join(EFFECTS[self.effect].params)}")


@dataclass(frozen=True)
class CampaignDraw:
    """How a campaign drawn at random departs from the default one, whose every default
    effect (transients, the rotor-speed resonance, autorotations) stays on.

    Attributes:
        law: relative half-width of the draw of every parameter of the quasi-static vertical
            law (`law_effects`): each is its default × U(1 − law, 1 + law).
        noise: factor on the measurement noise (`SynthConfig.noise_g`).
        scatter: factor on the condition-to-condition scatter (`SynthConfig.scatter`).
        conditions: (fewest, most) conditions of the campaign, drawn uniformly; the random
            conditions of every maneuver kind scale together (at least one of each kind).
        aircraft: name -> rotor constants (`SynthConfig.aircraft`; empty: the UH-60A), one
            drawn per campaign with equal odds.
    """

    law: float = 0.3
    noise: Span = Span(0.5, 2.0, log=True)
    scatter: Span = Span(0.5, 2.0, log=True)
    conditions: tuple[int, int] = (80, 300)
    aircraft: dict[str, dict[str, float]] = field(default_factory=lambda: {"uh60a": {}})

    def __post_init__(self):
        if not 0 <= self.law < 1:
            raise ValueError(f"law = {self.law:g}: a relative half-width within 0 (included) to 1")
        lo, hi = self.conditions
        if not _FIXED < lo <= hi:
            raise ValueError(f"conditions = {list(self.conditions)}: need {_FIXED} < fewest <= most (the named "
                             f"conditions and the level sweep are {_FIXED})")
        if not self.aircraft:
            raise ValueError("aircraft: give at least one (an empty table is the UH-60A)")


# Every campaign holds the paper's named conditions and the level sweep at two weights.
_FIXED = len(NAMED) + len(SWEEP_SPEEDS) * len(SWEEP_WEIGHTS)


def law_effects() -> tuple[str, ...]:
    """The effects of the quasi-static vertical law a drawn campaign redraws: the default-on additive
    effects of the vertical axis that depend on the steady state (not the maneuver
    transients of body rates, which the hidden-effect families plant)."""
    return tuple(n for n, e in EFFECTS.items()
                 if e.kind == "additive" and e.axis == "z" and e.default_on and n not in _TRANSIENTS)


_TRANSIENTS = ("pitch_rate", "roll_rate")


def _stream(seed: int, what: str) -> np.random.Generator:
    return np.random.default_rng([seed, zlib.crc32(what.encode())])


def _counts(n: int) -> dict[str, int]:
    """Random conditions per maneuver kind for a campaign of `n` conditions: every kind in
    its default share (at least one), level flight taking up the rounding."""
    share = (n - _FIXED) / sum(DEFAULT_COUNTS.values())
    counts = {k: max(1, int(round(v * share))) for k, v in DEFAULT_COUNTS.items()}
    counts["level"] += n - _FIXED - sum(counts.values())
    return counts


def draw_campaign(draw: CampaignDraw, seed: int, planted: Sequence[Planted] = (), base: SynthConfig = SynthConfig(),
               name: str = "") -> tuple[SynthConfig, dict]:
    """A campaign drawn at random (pure: the same arguments give the same campaign).

    Args:
        draw: the ranges of its base. seed: its seed (also the generator's).
        planted: hidden effects, each switched on with its drawn scale and parameters.
        base: the config the draws start from: its rates, format, maneuvers and effects'
            overrides are kept (the drawn law parameters replace its own); its size
            (`counts`, `conditions`), noise, scatter and aircraft are drawn.
        name: the campaign's name (default "drawn-<seed>").

    Returns:
        (its `SynthConfig`, what was drawn: key -> value, e.g. "law.blade_loading.a",
        "noise_g", "scatter", "conditions", "aircraft", "planted.slow_lag.tau_s"; the
        record its truth file carries beside `ground_truth`).
    """
    rng = _stream(seed, "base")
    effects = dict(base.effects)
    drawn: dict = {}
    for eff in law_effects():
        old = effects.get(eff, EffectConfig())
        params = {**EFFECTS[eff].params, **old.params}
        new = {}
        for p, v in params.items():
            new[p] = float(v * rng.uniform(1.0 - draw.law, 1.0 + draw.law))
            drawn[f"law.{eff}.{p}"] = new[p]
        effects[eff] = EffectConfig(enabled=old.enabled, scale=old.scale, params=new)
    noise = base.noise_g * draw.noise.sample(rng)
    scatter = base.scatter * draw.scatter.sample(rng)
    counts = _counts(int(rng.integers(draw.conditions[0], draw.conditions[1] + 1)))
    names = sorted(draw.aircraft)
    aircraft_name = names[int(rng.integers(len(names)))]
    aircraft = dict(draw.aircraft[aircraft_name])
    drawn.update(noise_g=noise, scatter=scatter, conditions=_FIXED + sum(counts.values()), aircraft=aircraft_name)
    for plant in planted:
        prng = _stream(seed, "planted:" + plant.effect)
        old = effects.get(plant.effect, EffectConfig())
        scale = plant.scale.sample(prng) if plant.scale is not None else old.scale
        params = dict(old.params)
        for p in sorted(plant.params):
            params[p] = plant.params[p].sample(prng)
            drawn[f"planted.{plant.effect}.{p}"] = params[p]
        if plant.scale is not None:
            drawn[f"planted.{plant.effect}.scale"] = scale
        effects[plant.effect] = EffectConfig(enabled=True, scale=scale, params=params)
    rpm = aircraft.get("nominal_rpm", SynthConfig().aircraft_constants().nominal_rpm)
    rate = max(base.sample_rate_hz, 10.0 * math.ceil(_min_sample_rate_hz(rpm) / 10.0))
    cfg = SynthConfig(name=name or f"drawn-{seed}", seed=seed, sample_rate_hz=rate,
                      dynamics_rate_hz=base.dynamics_rate_hz, noise_g=noise, scatter=scatter, format=base.format,
                      maneuvers=base.maneuvers, counts=counts, effects=effects,
                      vibration_weight_lb=base.vibration_weight_lb, aircraft=aircraft)
    return cfg, drawn
