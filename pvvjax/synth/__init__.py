"""Synthetic UH-60A flight-test campaigns with named, switchable physical effects.

The generator writes campaigns in the data-contract format; nothing in the pipeline
imports it. A scenario config switches effects on or off, rescales them or changes their
parameters; `draw_campaign` draws a whole campaign (law, noise, scatter, size, aircraft and
planted effects) over declared ranges. The ground truth is written beside the campaign
folder, never inside it.
"""

from ._conditions import NAMED, Condition, catalogue
from ._draw import CampaignDraw, Planted, Span, draw_campaign, law_effects
from ._generate import (
    GENERATOR_VERSION,
    EffectConfig,
    SynthConfig,
    cached_campaign,
    default_cache_dir,
    describe_effects,
    generate,
    ground_truth,
    load_synth_config,
    write_synthetic,
)
from ._law import law_amplitudes, simulation_config
from ._vibration import EFFECTS, Effect

__all__ = [
    "EFFECTS", "GENERATOR_VERSION", "NAMED", "Condition", "Effect", "EffectConfig", "Planted", "Span",
    "SynthConfig", "CampaignDraw", "cached_campaign", "catalogue", "default_cache_dir", "describe_effects",
    "draw_campaign", "generate", "ground_truth", "law_amplitudes", "law_effects", "load_synth_config",
    "simulation_config", "write_synthetic",
]
