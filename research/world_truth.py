"""Every way a drawn world departs from what a baseline's inputs express, each sized by
switching it off in the generator; the world's floor; the simulation lane's prediction.

A world's discrepancies (`discrepancies`) against the db1 baseline are its planted effects
and the base's own terms that db1's inputs cannot carry: the measured load factor in the
blade loading (db1 has the kinematic MLF), the 0.6 s lag, the pitch- and roll-rate terms,
and the airframe's rotor-speed resonance (a function of rotor speed, which db1 has: a
possible misfit, not a missing input). Against the simulation lane's baseline (the world's
base law drawn wrong, `pvvjax.synth.simulation_config`) only the planted effects are
missing; the drawn-wrong coefficients are misfits of the simulation's own inputs.

Each entry's size is measured on the scored target, the N/rev level per analysis window
(8 revolutions, a hop of one), as the RMS over all windows and over the windows where it
acts (where it is at least a tenth of its largest) of the noise-free law minus the same law
with the entry switched off (`pvvjax.synth.law_amplitudes`: one flight, so the difference is
the entry's own). The floor is the generator's noise-free, scatter-free law scored as a
model: the RMS over windows of the measured level (the demodulated N/rev of the vertical
acceleration) minus the law; no model goes below it, and it is the noise plus scatter that
each size is set against.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from pvvjax.synth import EFFECTS, EffectConfig, SynthConfig, generate, law_amplitudes, simulation_config

WINDOW_REVS, HOP_REVS = 8.0, 1.0  # the analysis's default window and the replay's hop
ACTS = 0.1  # "where it acts": windows where the entry is at least this share of its largest

# The base's own terms that db1's inputs cannot carry, and the variant that switches each off.
BASE_TERMS = {
    "measured load factor": dict(kind="missing input", channels=["nz_g"], switch=dict(load_factor="kinematic")),
    "0.6 s lag": dict(kind="response", channels=[], switch=dict(effect="dynamic_lag")),
    "pitch rate": dict(kind="missing input", channels=["pitch_rate_dps"], switch=dict(effect="pitch_rate")),
    "roll rate": dict(kind="missing input", channels=["roll_rate_dps"], switch=dict(effect="roll_rate")),
    "rotor-speed resonance": dict(kind="misfit", channels=["rotor_rpm"], switch=dict(effect="rotor_resonance")),
}
_RESPONSES = ("slow_lag", "second_order")  # planted responses (a lag, a mode) rather than inputs
_MISFITS = ("rotor_band",)  # planted functions of db1's own inputs (rotor speed)


def _off(cfg: SynthConfig, effect: str) -> SynthConfig:
    return replace(cfg, effects={**cfg.effects, effect: EffectConfig(enabled=False)})


def _switched(cfg: SynthConfig, switch: dict) -> SynthConfig:
    return _off(cfg, switch["effect"]) if "effect" in switch else replace(cfg, **switch)


def planted_effects(cfg: SynthConfig) -> list[str]:
    """The generator effects a world plants: on, and off by default."""
    return [n for n, (on, _, _) in cfg.effect_settings().items() if on and not EFFECTS[n].default_on]


def windows(records: dict, blades: int) -> dict:
    """Per counter: the analysis windows (sample start and end, `WINDOW_REVS` revolutions
    every `HOP_REVS`) and the measured N/rev level in each (g: twice the magnitude of the
    complex mean of `az_g − nz_g` times exp(−iNψ), the load factor taken out so that its
    1 g does not leak through the windows' edges)."""
    out = {}
    for k, r in records.items():
        psi = np.unwrap(np.deg2rad(r.azimuth_deg.to_numpy(np.float64)))
        rev = (psi - psi[0]) / (2 * np.pi)
        starts = np.arange(0.0, rev[-1] - WINDOW_REVS, HOP_REVS)
        i0, i1 = np.searchsorted(rev, starts), np.searchsorted(rev, starts + WINDOW_REVS)
        z = (r.az_g.to_numpy(np.float64) - r.nz_g.to_numpy(np.float64)) * np.exp(-1j * blades * psi)
        out[k] = (i0, i1, 2 * np.abs(_means(z, i0, i1)))
    return out


def _means(x, i0, i1):
    c = np.concatenate([[0], np.cumsum(x)])
    return (c[i1] - c[i0]) / np.maximum(i1 - i0, 1)


def _windowed(law: dict, win: dict, column: str) -> np.ndarray:
    return np.concatenate([_means(law[k][column].to_numpy(), *win[k][:2]) for k in win])


def _size(d: np.ndarray) -> dict:
    acts = np.abs(d) >= ACTS * np.abs(d).max() if np.abs(d).max() > 0 else np.zeros(d.shape, bool)
    return dict(rms_g=float(np.sqrt(np.mean(d**2))),
                where_acts_g=float(np.sqrt(np.mean(d[acts] ** 2))) if acts.any() else 0.0,
                acts_share=float(acts.mean()))


def discrepancies(cfg: SynthConfig, records: dict, drawn: dict | None = None, lane: str = "db1") -> dict:
    """A world's discrepancies against a lane's baseline, each sized, and its floor.

    Args:
        cfg: the world's generator config. records: its campaign's records (`generate`).
        drawn: what was drawn (`draw_campaign`), for the planted parameters.
        lane: "db1" (the paper's map: the base terms above and the planted effects) or
            "simulation" (the drawn-wrong base law: the planted effects, and the law's
            coefficients as a misfit).

    Returns:
        dict of `floor_g` (the law scored as a model), `windows`, and `entries`: each with
        name, kind (missing input, response or misfit), channels, parameters, `rms_g`,
        `where_acts_g`, `acts_share` and `against_noise` (`where_acts_g` over the floor),
        largest first.
    """
    if lane not in ("db1", "simulation"):
        raise ValueError(f"lane {lane!r}: db1 or simulation")
    drawn = drawn or {}
    specs = {}
    if lane == "db1":
        for name, s in BASE_TERMS.items():
            specs[name] = dict(kind=s["kind"], channels=s["channels"], variant=_switched(cfg, s["switch"]),
                               source="base", parameters={})
        everything = cfg
        for s in BASE_TERMS.values():
            everything = _switched(everything, s["switch"])
        specs["the base's terms together"] = dict(kind="all", channels=[], variant=everything, source="base",
                                                  parameters={})
    else:
        specs["the simulation's coefficients"] = dict(kind="misfit", channels=[], source="simulation",
                                                     variant=simulation_config(cfg, planted=()), parameters={})
    for eff in planted_effects(cfg):
        kind = "response" if eff in _RESPONSES else "misfit" if eff in _MISFITS else "missing input"
        params = {k.split(".")[-1]: v for k, v in drawn.items() if k.startswith(f"planted.{eff}.")}
        specs[eff] = dict(kind=kind, channels=list(EFFECTS[eff].channels), variant=_off(cfg, eff), source="planted",
                          parameters=params)
    law = law_amplitudes(cfg, {"law": cfg, **{n: s["variant"] for n, s in specs.items()}})
    blades = cfg.aircraft_constants().blades
    win = windows(records, blades)
    clean = _windowed(law, win, "law")
    floor = floor_g(cfg, records, win)
    entries = []
    for name, s in specs.items():
        size = _size(clean - _windowed(law, win, name))
        entries.append(dict(name=name, source=s["source"], kind=s["kind"], channels=s["channels"],
                            parameters=s["parameters"], **size, against_noise=size["where_acts_g"] / floor))
    entries.sort(key=lambda e: (e["kind"] == "all", -e["rms_g"]))
    return dict(lane=lane, floor_g=floor, windows=int(clean.size), entries=entries)


def floor_g(cfg: SynthConfig, records: dict, win: dict | None = None) -> float:
    """The world's floor, g: the RMS over windows of the measured level minus the level of
    the same campaign generated without noise and scatter (the same flight, phases and
    windows: the law as a model, scored as the measured level is analysed)."""
    blades = cfg.aircraft_constants().blades
    win = win or windows(records, blades)
    truth = windows(generate(replace(cfg, noise_g=0.0, scatter=0.0))[1], blades)
    return float(np.sqrt(np.mean(np.concatenate([win[k][2] - truth[k][2] for k in win]) ** 2)))


SIMULATION_COLUMN = "simulated_pvv_g"
# The channels the generator's base law takes (its default effects' inputs, the measured load
# factor among them): the simulation lane's inputs.
SIMULATION_INPUTS = ("airspeed_kt", "rotor_rpm", "gross_weight_lb", "density_ratio", "nz_g", "climb_rate_fpm",
                     "pitch_rate_dps", "roll_rate_dps")


def with_simulation(cfg: SynthConfig, records: dict, spread: float = 0.3) -> dict:
    """The world's records with the simulation lane's baseline as a column: the predicted
    vertical N/rev (g) of the world's base law drawn wrong (`simulation_config`) at every
    sample, `SIMULATION_COLUMN`, which a campaign keeps and passes through (data contract:
    other columns) as a user's physics code's prediction would be."""
    sim = law_amplitudes(cfg, {"simulation": simulation_config(cfg, spread)})
    return {k: r.assign(**{SIMULATION_COLUMN: sim[k].simulation.to_numpy(np.float32)}) for k, r in records.items()}


def table(truth: dict) -> pd.DataFrame:
    """A truth's entries as a table (mg), for a report."""
    rows = [dict(name=e["name"], source=e["source"], kind=e["kind"], rms_mg=1e3 * e["rms_g"],
                 where_acts_mg=1e3 * e["where_acts_g"], acts=e["acts_share"], against_noise=e["against_noise"])
            for e in truth["entries"]]
    return pd.DataFrame(rows)
