"""Generate, write and cache synthetic flight-test campaigns (the UH-60A, or UH-60A-like physics
scaled to another rotor)."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from .._cache import cache_dir

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib
from .._strict import to_dict
from ..config import config_hash, load_config
from ..data.campaign import write_campaign
from ..data.constants import KT_TO_FT_S, UH60A, Aircraft
from ..io import refuse_in_campaign
from . import _flight
from ._conditions import DEFAULT_COUNTS, NAMED, Condition, catalogue, condition_rng, pilot_plan
from ._scaling import scale_states, similarity
from ._vibration import EFFECTS, amplitude_4p, amplitude_axis, vibration_state

GENERATOR_VERSION = "3"
MAX_RATE_HZ = 20000.0  # the highest sample or dynamics rate a generator config may ask for


def _min_sample_rate_hz(rpm: float) -> float:
    """The lowest sample rate a campaign of a rotor at `rpm` nominal may have: 64 samples a
    revolution at 115 % of it (the analysis's harmonics up to 2N/rev, in overspeed)."""
    return 64 * 1.15 * rpm / 60


@dataclass(frozen=True)
class EffectConfig:
    """Switch, scale and parameter overrides of one named effect (`None`: its default)."""

    enabled: bool | None = None
    scale: float = 1.0
    params: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class SynthConfig:
    """A synthetic campaign.

    Attributes:
        name: campaign name (recorded in campaign.toml).
        seed: random seed; same config and seed give the same campaign.
        sample_rate_hz: time-series sample rate (≥ 64 samples per revolution up to 115 % rpm).
        dynamics_rate_hz: rate of the flight-dynamics model (states are interpolated).
        noise_g: broadband measurement noise on each acceleration channel, g (standard deviation).
        scatter: condition-to-condition scatter of the 4P level (relative std).
        format: time-series file format.
        conditions: generate only these condition ids (empty: all).
        maneuvers: generate only conditions of these maneuver kinds (empty: all).
        counts: random conditions per maneuver kind, beyond the named ones and the sweep.
        effects: per-effect overrides by name (see `pvvjax.synth.EFFECTS`).
        vibration_weight_lb: the gross weight the vibration sees, lb. `None`: each condition's
            own. A number holds it fixed in the blade loading of every effect, while the flight
            (trim, controls, the `gross_weight_lb` column) keeps each condition's own: the same
            campaign with a 4P level that does not depend on weight (a reference for a study
            of weight missing from a database).
        aircraft: constants of another aircraft (`pvvjax.data.Aircraft` fields: blades,
            rotor_radius_ft, nominal_rpm, chord_ft, solidity, ...; empty: the UH-60A). The
            campaign is then UH-60A-like physics scaled to that rotor (same advance ratio,
            blade loading and load factor; its rotor speed, weights and speeds; its N/rev and
            2N/rev content), written into campaign.toml: a stand-in until measured data exist.
        load_factor: the load factor in the blade loading the vibration sees: "measured", the
            `nz_g` the airframe feels (turns, pull-ups and the climb's own acceleration), or
            "kinematic", the turn-and-pull-up MLF of bank, pitch rate and airspeed that the
            paper's databases carry (a campaign whose blade loading db1's inputs express exactly).
    """

    name: str = "uh60a-synthetic"
    seed: int = 0
    sample_rate_hz: float = 320.0
    dynamics_rate_hz: float = 50.0
    noise_g: float = 0.02
    scatter: float = 0.04
    format: Literal["parquet", "csv"] = "parquet"
    conditions: tuple[str, ...] = ()
    maneuvers: tuple[str, ...] = ()
    counts: dict[str, int] = field(default_factory=dict)
    effects: dict[str, EffectConfig] = field(default_factory=dict)
    vibration_weight_lb: float | None = None
    aircraft: dict[str, float] = field(default_factory=dict)
    load_factor: Literal["measured", "kinematic"] = "measured"

    def aircraft_constants(self) -> Aircraft:
        """The aircraft the campaign is flown on."""
        return UH60A._replace(**{k: int(v) if k == "blades" else float(v) for k, v in self.aircraft.items()})

    def __post_init__(self):
        if self.vibration_weight_lb is not None and not self.vibration_weight_lb > 0:
            raise ValueError(f"vibration_weight_lb: must be > 0 lb, got {self.vibration_weight_lb}")
        for name, e in self.effects.items():
            if name not in EFFECTS:
                raise ValueError(f"effects.{name}: unknown effect; known: {', '.join(EFFECTS)}")
            unknown = set(e.params) - set(EFFECTS[name].params)
            if unknown:
                raise ValueError(f"effects.{name}.params: unknown {sorted(unknown)}; "
                                 f"known: {', '.join(EFFECTS[name].params)}")
        bad = sorted(set(self.maneuvers) - set(DEFAULT_COUNTS))
        if bad:
            raise ValueError(f"maneuvers: unknown {bad}; known: {', '.join(DEFAULT_COUNTS)}")
        for kind, n in self.counts.items():
            if kind not in DEFAULT_COUNTS:
                raise ValueError(f"counts.{kind}: unknown maneuver; known: {', '.join(DEFAULT_COUNTS)}")
            if n < 0:
                raise ValueError(f"counts.{kind}: must be >= 0, got {n}")
        for key, value in self.aircraft.items():
            if key not in Aircraft._fields:
                raise ValueError(f"aircraft.{key}: unknown constant; known: {', '.join(Aircraft._fields)}")
            if not value > 0 or (key == "blades" and value != int(value)):
                raise ValueError(f"aircraft.{key}: must be {'a whole number ' if key == 'blades' else ''}> 0, "
                                 f"got {value}")
        rpm = self.aircraft_constants().nominal_rpm
        if self.sample_rate_hz < _min_sample_rate_hz(rpm):
            raise ValueError(f"sample_rate_hz {self.sample_rate_hz} gives fewer than 64 samples per revolution at "
                             f"115 % of {rpm:g} rpm (at least {_min_sample_rate_hz(rpm):.0f} Hz)")
        # Flight-test acquisition runs at 100 Hz to a few kHz; beyond, only the data grows (GBs).
        for name, hi in (("sample_rate_hz", MAX_RATE_HZ), ("dynamics_rate_hz", MAX_RATE_HZ)):
            if not getattr(self, name) <= hi:
                raise ValueError(f"{name} {getattr(self, name):g}: at most {hi:g} Hz")
        for name in ("noise_g", "scatter"):  # standard deviations
            if getattr(self, name) < 0:
                raise ValueError(f"{name} is a standard deviation: must be >= 0, got {getattr(self, name):g}")
        if not self.dynamics_rate_hz > 0:
            raise ValueError(f"dynamics_rate_hz must be > 0 Hz, got {self.dynamics_rate_hz:g}")

    def effect_settings(self) -> dict[str, tuple[bool, float, dict]]:
        """name -> (enabled, scale, params) with defaults filled in."""
        out = {}
        for name, eff in EFFECTS.items():
            o = self.effects.get(name, EffectConfig())
            on = eff.default_on if o.enabled is None else o.enabled
            out[name] = (on, o.scale, {**eff.params, **o.params})
        return out


def load_synth_config(path) -> SynthConfig:
    """A generator config from TOML (strict: unknown keys and effects are errors)."""
    return load_config(path, SynthConfig)


def ground_truth(cfg: SynthConfig) -> dict:
    """What the generator put into the data: every effect's setting, and which differ from
    the defaults (the 'hidden' effects of a scenario)."""
    effects = []
    default = SynthConfig().effect_settings()
    for name, (on, scale, params) in cfg.effect_settings().items():
        eff = EFFECTS[name]
        effects.append(dict(
            name=name, enabled=on, scale=scale, params=params, kind=eff.kind, formula=eff.formula,
            physics=eff.physics, channels=list(eff.channels),
            default=dict(enabled=default[name][0], params=default[name][2]),
            changed=(on, scale, params) != default[name],
        ))
    return dict(generator_version=GENERATOR_VERSION, config=to_dict(cfg), effects=effects,
                hidden=[e["name"] for e in effects if e["changed"]])


def _simulate(conds: list[Condition], cfg: SynthConfig):
    dt = 1.0 / cfg.dynamics_rate_hz
    t_max = max(c.duration_s for c in conds)
    t = np.arange(0.0, t_max + dt, dt)
    init = {k: np.array([getattr(c, a) for c in conds], float) for k, a in (
        ("v_kt", "airspeed_kt"), ("w_lb", "gross_weight_lb"), ("sigma", "density_ratio"),
        ("rpm_set", "rpm"), ("climb_fpm", "climb_fpm"))}
    init["phi_deg"] = np.array([c.intensity if c.maneuver == "turn" else 0.0 for c in conds])
    n0 = 1.0 / np.cos(np.deg2rad(init["phi_deg"]))
    coll_trim = _flight.collective_for_power(
        _flight.power_required_hp(init["v_kt"], init["w_lb"], init["sigma"], init["rpm_set"], init["climb_fpm"], n0),
        init["rpm_set"])
    plans = [pilot_plan(c, t, cfg.seed, ct) for c, ct in zip(conds, coll_trim)]
    sched = {k: np.stack([p[k] for p in plans]) for k in plans[0]}
    states = _flight.simulate(init, sched, dt)
    states["gross_weight_lb"] = np.broadcast_to(init["w_lb"][:, None], states["nz_g"].shape)
    states["density_ratio"] = np.broadcast_to(init["sigma"][:, None], states["nz_g"].shape)
    return t, states


def campaign_conditions(cfg: SynthConfig) -> list[Condition]:
    """The conditions a campaign of `cfg` flies (its catalogue, filtered by `conditions` and
    `maneuvers`)."""
    conds = catalogue(cfg.seed, cfg.counts)
    if cfg.conditions:
        known = {c.id for c in conds}
        missing = sorted(set(cfg.conditions) - known)
        if missing:
            raise ValueError(f"conditions: unknown condition ids {missing}")
        conds = [c for c in conds if c.id in set(cfg.conditions)]
    if cfg.maneuvers:
        conds = [c for c in conds if c.maneuver in set(cfg.maneuvers)]
    return conds


def flight(cfg: SynthConfig, conds: list[Condition]) -> tuple[np.ndarray, dict]:
    """The simulated flight of the conditions: the dynamics time grid (s) and the (K, N)
    states in the aircraft's units."""
    t, states = _simulate(conds, cfg)
    return t, scale_states(states, cfg.aircraft_constants())


def seen_state(cfg: SynthConfig, states: dict) -> dict:
    """The vibration state (`vibration_state`) of the flight as `cfg`'s vibration sees it:
    with its fixed vibration weight and its load factor (`SynthConfig.load_factor`)."""
    seen = dict(states)
    if cfg.vibration_weight_lb is not None:
        seen["gross_weight_lb"] = np.full_like(states["gross_weight_lb"], cfg.vibration_weight_lb)
    if cfg.load_factor == "kinematic":
        g = cfg.aircraft_constants().g_ft_s2
        q, v = np.deg2rad(states["pitch_rate_dps"]), states["airspeed_kt"] * KT_TO_FT_S
        seen["nz_g"] = (1.0 + q * v / g) / np.cos(np.deg2rad(states["roll_angle_deg"]))
    return vibration_state(seen, cfg.aircraft_constants())


def condition_scatter(cfg: SynthConfig, conds: list[Condition]) -> np.ndarray:
    """(K,) each condition's factor on its N/rev level: 1 + scatter · N(0, 1), at least 0.5;
    the paper's named conditions (the calibration anchors) carry none."""
    named = {c.id for c in NAMED}
    scat = np.array([1.0 + (0.0 if c.id in named else cfg.scatter)
                     * condition_rng(cfg.seed, "scatter:" + c.id).standard_normal() for c in conds])
    return np.maximum(scat, 0.5)


def record_parts(c: Condition, n: int) -> list[tuple[str, np.ndarray, int]]:
    """How a condition's `n` samples become records: (counter, sample indices, segment), one
    record, or a continuous flight cut into equal segments."""
    names = c.counter_names
    if len(names) == 1:
        return [(names[0], np.arange(n), 1)]
    return [(name, idx, seg) for seg, (name, idx) in enumerate(zip(names, np.array_split(np.arange(n), len(names))),
                                                                start=1)]


def generate(cfg: SynthConfig = SynthConfig()) -> tuple[pd.DataFrame, dict[str, pd.DataFrame], dict]:
    """Generate a campaign in memory.

    Returns:
        (counters table, counter -> time series, ground truth).
    """
    conds = campaign_conditions(cfg)
    ac = cfg.aircraft_constants()
    scale = similarity(ac)  # every factor exactly 1 for the UH-60A
    t, states = flight(cfg, conds)
    dt = float(t[1] - t[0])
    settings = cfg.effect_settings()
    vstate = seen_state(cfg, states)  # the flight and its channels keep each condition's weight
    # Condition-to-condition scatter (a per-condition constant, so its order with the lag is
    # immaterial).
    scat = condition_scatter(cfg, conds)
    a4, _ = amplitude_4p(vstate, settings, dt)
    a4 = a4 * scat[:, None]
    phi4 = 1.2 * vstate["mu"] + 3.0 * (vstate["loading"] - 0.07)
    a_xy = {axis: amplitude_axis(vstate, settings, dt, axis) * scat[:, None] for axis in "xy"}

    rows, records = [], {}
    for k, c in enumerate(conds):
        rng = condition_rng(cfg.seed, "signal:" + c.id)
        ts = np.arange(0.0, c.duration_s, 1.0 / cfg.sample_rate_hz)
        interp = lambda arr: np.interp(ts, t, arr[k])  # noqa: E731
        rpm = interp(states["rotor_rpm"])
        psi = np.concatenate([[0.0], np.cumsum(0.5 * (rpm[1:] + rpm[:-1]) * np.diff(ts))]) * 2 * np.pi / 60
        psi += rng.uniform(0, 2 * np.pi)
        amp4 = interp(a4)
        nz = interp(states["nz_g"])
        a1, a2 = rng.uniform(0.015, 0.04), 0.01 + 0.05 * np.abs(nz - 1.0)
        p1, p2, p4, p8 = rng.uniform(0, 2 * np.pi, 4)
        n = ac.blades  # the blade-passage harmonic N/rev and its 2N/rev
        az = (nz + rotor_harmonics(psi, n, (a1, a2), (p1, p2))
              + amp4 * np.cos(n * psi + p4 + interp(phi4))
              + 0.2 * amp4 * np.cos(2 * n * psi + p8)
              + cfg.noise_g * rng.standard_normal(ts.size))
        ch = {
            "time_s": ts, "az_g": az, "azimuth_deg": np.mod(np.rad2deg(psi), 360.0), "rotor_rpm": rpm,
            **_horizontal(psi, n, {axis: interp(a) for axis, a in a_xy.items()}, interp(phi4), settings, cfg.noise_g,
                          condition_rng(cfg.seed, "signal-xy:" + c.id)),
        }
        for name in ("airspeed_kt", "pitch_rate_dps", "roll_angle_deg", "climb_rate_fpm", "collective_pct",
                     "lateral_pct", "longitudinal_pct", "pedal_pct", "roll_rate_dps", "yaw_rate_dps",
                     "pitch_angle_deg", "nz_g", "altitude_ft", "shaft_power_hp", "sideslip_deg"):
            ch[name] = interp(states[name])
        for stick in ("collective_pct", "lateral_pct", "longitudinal_pct", "pedal_pct"):  # unfiltered sticks
            ch[stick] = np.clip(ch[stick] + 0.15 * rng.standard_normal(ts.size), 0.0, 100.0)
        df = pd.DataFrame(ch).astype(np.float32)
        df["time_s"] = ts  # keep time exact (float64)
        for name, idx, seg in record_parts(c, len(df)):
            part = df.iloc[idx].reset_index(drop=True)
            part["time_s"] = ts[idx] - ts[idx[0]]  # each segment's time from its start
            records[name] = part
            rows.append(_row(name, c, seg, scale))
    return pd.DataFrame(rows), records, ground_truth(cfg)


def rotor_harmonics(psi, blades: int, amplitudes, phases):
    """The 1/rev, 2/rev, ... of rotor track, balance and blade dissimilarity (`amplitudes[k - 1]`
    at k/rev, g; `phases` rad) on azimuth `psi` (rad): only those below the blade-passage
    harmonic, which is the vibration law's alone (on a two-bladed rotor 2/rev is N/rev, where a
    term of random phase per condition would be a second, lawless vibration source)."""
    out = np.zeros_like(psi)
    for k, (a, p) in enumerate(zip(amplitudes, phases), start=1):
        if k < blades:
            out = out + a * np.cos(k * psi + p)
    return out


def _horizontal(psi, n: int, amp: dict, phase_n, settings: dict, noise_g: float, rng) -> dict:
    """The longitudinal and lateral pilot-floor accelerations (`ax_g` forward, `ay_g` right,
    g): each axis's N/rev at its amplitude `amp[axis]` and the vertical's phase trend, a
    2N/rev at a fifth of it, the 1/rev of rotor track and balance (constant amplitude, set
    phase: effect `track_balance`) and measurement noise. Drawn from its own random stream,
    so that the vertical channel is the same whether or not these exist."""
    on, scale, tb = settings["track_balance"]
    out = {}
    for axis in "xy":
        pn, p2n = rng.uniform(0, 2 * np.pi, 2)
        once = scale * tb[f"a_{axis}"] * np.cos(psi + tb[f"phase_{axis}"]) if on else 0.0
        out[f"a{axis}_g"] = (once + amp[axis] * np.cos(n * psi + pn + phase_n)
                             + 0.2 * amp[axis] * np.cos(2 * n * psi + p2n) + noise_g * rng.standard_normal(psi.size))
    return out


def _row(counter: str, c: Condition, segment: int, f: dict) -> dict:
    """A counters-table row; `f`: the similarity factors of the aircraft (`similarity`)."""
    return dict(counter=counter, maneuver=c.maneuver, condition=c.id, segment=segment,
                gross_weight_lb=c.gross_weight_lb * f["weight"], density_ratio=round(c.density_ratio, 4),
                description=c.description or f"{c.maneuver}, {c.airspeed_kt * f['speed']:.0f} kt")


def _is_synthetic(folder: Path) -> bool:
    try:
        return tomllib.loads((folder / "campaign.toml").read_text())["provenance"]["generator"] == "pvvjax.synth"
    except (OSError, KeyError, TypeError, tomllib.TOMLDecodeError):
        return False


def write_synthetic(out, cfg: SynthConfig = SynthConfig(), truth_path=None, force: bool = False,
                    log=print, drawn: dict | None = None) -> tuple[Path, Path]:
    """Generate a campaign and write it to `out`; the ground truth goes to `truth_path`
    (default: `<out>.truth.json`, beside the folder, never inside it).

    Only files the generator wrote are ever replaced: a synthetic campaign written to `out`
    before loses its `counters.csv`, `campaign.toml` and records (said through `log`);
    any other file there is kept. A folder holding a campaign (or its files) that the
    generator did not write is refused, and so is a ground-truth file it did not write.

    Args:
        force: also write into a non-empty folder that is not a synthetic campaign, beside
            the files there (refused otherwise: it may be a user's own data).
        log: where replaced files are reported.
        drawn: what a random draw set (`draw_campaign`'s record), written into the truth as
            `drawn`.

    Returns:
        (campaign folder, ground-truth file).
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: is a file, not a folder; give a folder for the campaign")
    refuse_in_campaign(out, itself=False)
    synthetic = out.is_dir() and _is_synthetic(out)
    if out.is_dir() and any(out.iterdir()) and not synthetic:
        clash = [n for n in ("counters.csv", "campaign.toml", "timeseries") if (out / n).exists()]
        if clash:
            raise ValueError(f"{out}: holds {', '.join(clash)} that pvvjax.synth did not write (a campaign?); give a "
                             "new or empty folder")
        if not force:
            raise ValueError(f"{out}: is not empty and not a synthetic campaign (no campaign.toml of pvvjax.synth); "
                             "give an empty or new folder, or --force to write the campaign beside its files")
    truth_path = Path(truth_path) if truth_path else out.with_name(out.name + ".truth.json")
    if truth_path.resolve().is_relative_to(out.resolve()):
        raise ValueError(f"ground truth {truth_path} must not be inside the campaign folder {out}")
    refuse_in_campaign(truth_path)
    if truth_path.exists() and not _is_truth(truth_path):
        raise ValueError(f"{truth_path}: exists and is not a ground truth of pvvjax.synth; give a new file (--truth)")
    counters, records, truth = generate(cfg)
    if drawn:
        truth = {**truth, "drawn": dict(drawn)}
    if synthetic:
        _remove_synthetic(out, log)
    ac = cfg.aircraft_constants()
    write_campaign(out, counters, records, fmt=cfg.format, aircraft=None if ac == UH60A else ac,
                   provenance=dict(generator="pvvjax.synth", generator_version=GENERATOR_VERSION,
                                   name=cfg.name, seed=cfg.seed, config_hash=config_hash(cfg)))
    truth_path.parent.mkdir(parents=True, exist_ok=True)
    truth_path.write_text(json.dumps(truth, indent=2))
    return out, truth_path


def _is_truth(path: Path) -> bool:
    try:
        return {"generator_version", "effects", "hidden"} <= set(json.loads(path.read_text()))
    except (OSError, ValueError, TypeError):
        return False


def _remove_synthetic(folder: Path, log) -> None:
    """Delete the files a synthetic campaign of `folder` consists of (its counters' records,
    `counters.csv`, `campaign.toml`), keeping anything else there."""
    names = pd.read_csv(folder / "counters.csv", dtype=str).get("counter", pd.Series(dtype=str)).dropna()
    records = [p for n in names for p in (folder / "timeseries" / f"{n}.parquet", folder / "timeseries" / f"{n}.csv")
               if p.is_file()]
    others = [p for p in folder.rglob("*") if p.is_file()
              and p not in records and p.name not in ("counters.csv", "campaign.toml")]
    log(f"{folder}: replacing the synthetic campaign written there before ({len(records)} records, counters.csv, "
        f"campaign.toml)" + (f"; {len(others)} other file(s) kept" if others else ""))
    for p in records + [folder / "counters.csv", folder / "campaign.toml"]:
        p.unlink(missing_ok=True)
    if (folder / "timeseries").is_dir() and not any((folder / "timeseries").iterdir()):
        (folder / "timeseries").rmdir()


def default_cache_dir() -> Path:
    """`$PVVJAX_CACHE`, else `.cache/` of the source checkout, else `~/.cache/pvvjax`."""
    return cache_dir()


def cached_campaign(cfg: SynthConfig = SynthConfig(), cache_dir=None) -> Path:
    """The folder of a generated campaign, generating it once per config and generator
    version. Safe under concurrent callers (the folder appears atomically; where the OS
    has file locks, a second caller waits for the first instead of generating it again)."""
    cache_dir = Path(cache_dir) if cache_dir else default_cache_dir()
    key = f"{cfg.name}-{config_hash(cfg)}-v{GENERATOR_VERSION}"
    final = cache_dir / "campaigns" / key
    if (final / "counters.csv").exists():
        return final
    final.parent.mkdir(parents=True, exist_ok=True)
    with _locked(final.parent / f"{key}.lock"):
        if not (final / "counters.csv").exists():
            _generate_into(final, cfg, key)
    return final


@contextlib.contextmanager
def _locked(path: Path):
    """An exclusive lock on `path` (POSIX `flock`; elsewhere no lock: the atomic rename
    still keeps concurrent generations correct, only not single)."""
    try:
        import fcntl
    except ImportError:
        yield
        return
    with open(path, "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _generate_into(final: Path, cfg: SynthConfig, key: str):
    tmp = Path(tempfile.mkdtemp(dir=final.parent, prefix=".tmp-"))
    try:
        write_synthetic(tmp / "campaign", cfg, truth_path=tmp / "truth.json")
        shutil.move(str(tmp / "truth.json"), str(final.parent / f"{key}.truth.json"))
        try:
            os.rename(tmp / "campaign", final)
        except OSError:
            if not (final / "counters.csv").exists():
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def describe_effects() -> pd.DataFrame:
    """The effect library as a table (name, kind, default, formula, physics, parameters)."""
    return pd.DataFrame([dict(name=e.name, kind=e.kind, default_on=e.default_on, formula=e.formula,
                              parameters=", ".join(f"{k}={v:g}" for k, v in e.params.items()), physics=e.physics)
                         for e in EFFECTS.values()])


__all__ = ["EffectConfig", "SynthConfig", "cached_campaign", "default_cache_dir", "describe_effects", "generate",
           "ground_truth", "load_synth_config", "write_synthetic", "GENERATOR_VERSION"]
