"""The sections of an experiment config other than discovery's: campaign, analysis, training,
sweep, replay, calibration and the main job."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from ..data.campaign import MANEUVERS
from ..data.units import CANONICAL_UNITS, ColumnMap

# What a trainer can hold and a flight test can show: a setting beyond these is a mistake
# (a seed count of 2**40 allocates that many nets; an offset of a minute leaves no window).
MAX_SEEDS, MAX_FOLDS = 64, 50
MAX_LAYERS, MAX_WIDTH = 8, 1024
MAX_STEPS = 10_000_000
MAX_OFFSET_S = 60.0
MAX_WINDOW_REVS = 64.0


def _within(key: str, value, lo, hi, unit: str = "") -> None:
    """Refuse `value` outside [lo, hi], naming `key`."""
    if not lo <= value <= hi:
        raise ValueError(f"{key} = {value!r}: must lie within {lo:g} to {hi:g}{unit}")


def _widths(key: str, hidden) -> None:
    """Hidden-layer widths: 1 to `MAX_LAYERS` layers of 1 to `MAX_WIDTH` units."""
    if not hidden or len(hidden) > MAX_LAYERS or min(hidden) < 1 or max(hidden) > MAX_WIDTH:
        raise ValueError(f"{key} = {list(hidden)}: give 1 to {MAX_LAYERS} layers of 1 to {MAX_WIDTH} units")


def _counts(section: str, seeds: int, folds: int) -> None:
    """Seeds per fold (1 to `MAX_SEEDS`) and the k of a k-fold split (3 to `MAX_FOLDS`)."""
    _within(f"{section}.seeds", seeds, 1, MAX_SEEDS)
    _within(f"{section}.folds", folds, 3, MAX_FOLDS)


def _offsets(key: str, bounds) -> None:
    """[lo, hi] offsets, s, lo < hi, within ±`MAX_OFFSET_S`."""
    _bounds(key, bounds)
    if max(abs(bounds[0]), abs(bounds[1])) > MAX_OFFSET_S:
        raise ValueError(f"{key} = {list(bounds)}: an input-to-vibration offset lies within ±{MAX_OFFSET_S:g} s")


def _grid(key: str, bounds, step_key: str, step: float) -> None:
    """A grid from `bounds` in steps of `step` holds at least two points."""
    if step > bounds[1] - bounds[0] + 1e-12:
        raise ValueError(f"{step_key} = {step:g} leaves one point of {key} {list(bounds)}: a grid needs at least two "
                         f"(a step of at most {bounds[1] - bounds[0]:g})")


def _advance_ratio_band(key: str, band) -> None:
    _bounds(key, band)
    if band[0] < 0 or band[1] > 1:
        raise ValueError(f"{key} = {list(band)}: an advance ratio lies within 0 to 1")


def _maneuver_kinds(key: str, kinds, allow_empty: bool = False) -> None:
    """Maneuver kinds the data contract knows (a typo would select nothing)."""
    bad = [k for k in kinds if k not in MANEUVERS]
    if bad or (not kinds and not allow_empty):
        raise ValueError(f"{key}: unknown maneuver kind(s) {bad}; the data contract's: {', '.join(MANEUVERS)}"
                         if bad else f"{key} is empty: name at least one maneuver kind ({', '.join(MANEUVERS)})")


@dataclass(frozen=True)
class CampaignConfig:
    """Where the flight-test campaign comes from.

    Attributes:
        path: campaign folder (data-contract §1). Empty: the embedded synthetic campaign.
        synthetic: generator config (TOML) for the embedded campaign; empty: the default
            campaign with the experiment's seed.
        columns: foreign column name -> `ColumnMap`, applied to counters.csv and time series.
    """

    path: str = ""
    synthetic: str = ""
    columns: dict[str, ColumnMap] = field(default_factory=dict)

    def __post_init__(self):
        targets = [m.to for m in self.columns.values()]
        dup = {t for t in targets if targets.count(t) > 1}
        if dup:
            raise ValueError(f"columns: several columns map to {sorted(dup)}")
        for src, m in self.columns.items():
            if m.to not in CANONICAL_UNITS and m.unit is not None:
                raise ValueError(f"columns.{src}: {m.to!r} is not a canonical channel")


@dataclass(frozen=True)
class AnalysisConfig:
    """Windowed harmonic analysis and peak extraction.

    Attributes:
        window_revs: window length L in rotor revolutions (paper: 8). Continuous.
        hop_revs: window start spacing in revolutions; 0 means consecutive windows (= L).
        harmonic: harmonic order k analysed; unset, the aircraft's blade count N (the
            blade-passage N/rev: 4/rev on the UH-60A).
        taper_revs: width of the raised-cosine window edges in revolutions; 0 gives the
            rectangular window (edges resolved to fractions of a sample).
        inputs: how a database row takes the flight state at the peak window: "mean"
            averages each channel over the window (the paper's replay inputs), "center"
            takes the instantaneous value at the window's center.
        axis: the pilot-floor acceleration the databases' output is the peak of: "az_g"
            vertical (the paper's PVV), "ax_g" longitudinal or "ay_g" lateral (data
            contract). With `harmonic`, it picks any of `build-db`'s per-axis tables as the
            output that the sweep, the replay and the dynamic model then work on.
    """

    window_revs: float = 8.0
    hop_revs: float = 0.0
    harmonic: int | None = None
    taper_revs: float = 0.0
    inputs: Literal["mean", "center"] = "mean"
    axis: Literal["az_g", "ax_g", "ay_g"] = "az_g"

    def __post_init__(self):
        if not 0 < self.window_revs <= MAX_WINDOW_REVS:
            raise ValueError(f"window_revs must be > 0 and at most {MAX_WINDOW_REVS:g} revolutions, got "
                             f"{self.window_revs}")
        if not 0 <= self.hop_revs <= MAX_WINDOW_REVS:
            raise ValueError(f"hop_revs must be >= 0 and at most {MAX_WINDOW_REVS:g}, got {self.hop_revs}")
        if self.harmonic is not None and not 1 <= self.harmonic <= 64:
            raise ValueError(f"harmonic must be >= 1 and at most 64, got {self.harmonic}")
        if self.taper_revs < 0 or self.taper_revs >= self.window_revs:
            raise ValueError(f"taper_revs must be in [0, window_revs), got {self.taper_revs}")

    @property
    def hop(self) -> float:
        return self.hop_revs or self.window_revs


def _check_databases(section: str, databases, field: str = "databases"):
    bad = [d for d in databases if d not in ("db1", "db2", "db3")]
    if bad or not databases:
        raise ValueError(f"{section}.{field}: unknown {bad}; use db1, db2, db3")


@dataclass(frozen=True)
class TrainConfig:
    """Full-batch training of one net.

    Attributes:
        learning_rate: Adam step size.
        max_steps: optimizer steps at most.
        eval_every: steps between validation evaluations.
        patience: evaluations without a better validation RMS before stopping.
        weight_decay: decoupled weight decay (AdamW) when > 0.
        divergence_factor: a training loss above this multiple of the initial loss is divergence.
    """

    learning_rate: float = 3e-3
    max_steps: int = 6000
    eval_every: int = 50
    patience: int = 10
    weight_decay: float = 0.0
    divergence_factor: float = 1e3

    def __post_init__(self):
        for name in ("learning_rate", "max_steps", "eval_every", "patience", "divergence_factor"):
            if not getattr(self, name) > 0:
                raise ValueError(f"train.{name} must be > 0, got {getattr(self, name)}")
        if self.weight_decay < 0:
            raise ValueError(f"train.weight_decay must be >= 0, got {self.weight_decay}")
        _within("train.learning_rate", self.learning_rate, 0, 1.0)
        _within("train.weight_decay", self.weight_decay, 0, 1.0)
        _within("train.max_steps", self.max_steps, 1, MAX_STEPS)
        _within("train.eval_every", self.eval_every, 1, self.max_steps, " (train.max_steps: an evaluation at least)")
        _within("train.patience", self.patience, 1, MAX_STEPS)
        if not self.divergence_factor > 1:
            raise ValueError(f"train.divergence_factor = {self.divergence_factor:g}: must be above 1 (a loss above "
                             "this multiple of the initial loss is divergence; at or below 1 every net diverges)")


@dataclass(frozen=True)
class SweepConfig:
    """A family of nets trained together: databases × architectures × seeds × folds.

    Attributes:
        databases: which of db1, db2, db3.
        family: "mlp" (back-propagation nets) or "rbf" (radial-basis-function nets).
        hidden: MLP hidden-layer widths per architecture, e.g. [[10, 5], [15, 5]].
        centers: RBF centre counts per architecture.
        seeds: number of initialisation seeds (0 .. seeds-1).
        learning_rates: Adam step sizes, an axis of the sweep (empty: `train.learning_rate`).
            Nets of every rate train in one batch and one compiled program.
        weight_decays: AdamW weight decays, an axis like `learning_rates` (empty:
            `train.weight_decay`).
        folds: k of the k-fold split by condition.
        test_folds: outer folds to run (empty: all k, so every condition is held out once).
        split_seed: seed of the assignment of conditions to folds.
        chunk_evals: on CPU, evaluations between the host's looks at which nets have stopped
            (finished nets leave the batch there when half of it has).
        checkpoint_s: write the nets finished so far at least this often, s: what a killed
            sweep keeps (it does not change the results).
        cpu_devices: on CPU, expose this many host devices so that the net axis is sharded
            over the cores (0: one per core; 1: off). Applied by `pvvjax sweep` before JAX
            starts; results then depend on it (same config, seed and devices: same numbers).
    """

    databases: tuple[str, ...] = ("db1", "db2", "db3")
    family: Literal["mlp", "rbf"] = "mlp"
    hidden: tuple[tuple[int, ...], ...] = ((10, 5),)
    centers: tuple[int, ...] = (20,)
    seeds: int = 1
    learning_rates: tuple[float, ...] = ()
    weight_decays: tuple[float, ...] = ()
    folds: int = 5
    test_folds: tuple[int, ...] = ()
    split_seed: int = 0
    chunk_evals: int = 4
    checkpoint_s: float = 60.0
    cpu_devices: int = 0

    def __post_init__(self):
        if self.cpu_devices < 0:
            raise ValueError(f"sweep.cpu_devices must be >= 0, got {self.cpu_devices}")
        _check_databases("sweep", self.databases)
        if any(not h or min(h) < 1 for h in self.hidden):
            raise ValueError(f"sweep.hidden: every architecture needs widths >= 1, got {self.hidden}")
        if self.seeds < 1 or self.folds < 3 or self.chunk_evals < 1:
            raise ValueError("sweep.seeds must be >= 1, sweep.folds >= 3, sweep.chunk_evals >= 1")
        if self.family == "mlp" and not self.hidden or self.family == "rbf" and not self.centers:
            raise ValueError(f"sweep.{'hidden' if self.family == 'mlp' else 'centers'} is empty: a {self.family} "
                             "sweep needs at least one architecture")
        for i, h in enumerate(self.hidden):
            _widths(f"sweep.hidden[{i}]", h)
        for c in self.centers:
            _within("sweep.centers", c, 1, MAX_WIDTH)
        _counts("sweep", self.seeds, self.folds)
        _within("sweep.chunk_evals", self.chunk_evals, 1, 10_000)
        _within("sweep.split_seed", self.split_seed, 0, 2**63 - 1)
        _within("sweep.cpu_devices", self.cpu_devices, 0, 1024)
        if any(v > 1 for v in (*self.learning_rates, *self.weight_decays)):
            raise ValueError(f"sweep.learning_rates and sweep.weight_decays lie within 0 to 1, got "
                             f"{list(self.learning_rates)} and {list(self.weight_decays)}")
        if not self.checkpoint_s > 0:
            raise ValueError(f"sweep.checkpoint_s must be > 0 s, got {self.checkpoint_s}")
        if any(not 0 <= f < self.folds for f in self.test_folds):
            raise ValueError(f"sweep.test_folds must lie in 0..{self.folds - 1}, got {self.test_folds}")
        if any(not (math.isfinite(v) and v > 0) for v in self.learning_rates):
            raise ValueError(f"sweep.learning_rates must be finite and > 0, got {list(self.learning_rates)}")
        if any(not (math.isfinite(v) and v >= 0) for v in self.weight_decays):
            raise ValueError(f"sweep.weight_decays must be finite and >= 0, got {list(self.weight_decays)}")
        for name in ("learning_rates", "weight_decays", "test_folds"):
            values = getattr(self, name)
            if len(set(values)) < len(values):
                raise ValueError(f"sweep.{name} lists a value twice: {list(values)}")

    @property
    def fold_list(self) -> tuple[int, ...]:
        return self.test_folds or tuple(range(self.folds))


TRANSIENT_MANEUVERS = ("pullup", "pushover", "roll", "autorotation", "flare")


def _bounds(name: str, b: tuple[float, float]):
    if len(b) != 2 or not b[0] < b[1]:
        raise ValueError(f"{name} must be [lo, hi] with lo < hi, got {list(b)}")


@dataclass(frozen=True)
class ReplayConfig:
    """Quasi-static replay of recorded counters through trained nets.

    Attributes:
        sweep: folder of the sweep whose nets are replayed ("": this config's own sweep,
            `<out_dir>/<name>/sweep`). Each counter is replayed by the nets that held its
            condition out, median over seeds.
        architecture: which architecture of the sweep ("": its only one).
        databases: which of db1, db2, db3.
        counters: counters to replay (empty: every counter of the `maneuvers` kinds).
        maneuvers: maneuver kinds replayed when `counters` is empty.
        offset_s: input-to-vibration offset τ, s (inputs precede the vibration when > 0).
        window_revs: window length L, revolutions (the paper: 8).
        stick_offset_s: extra offset of the three stick inputs, s.
        hop_revs: window spacing, revolutions (0: consecutive windows, as the paper).
    """

    sweep: str = ""
    architecture: str = ""
    databases: tuple[str, ...] = ("db1", "db2", "db3")
    counters: tuple[str, ...] = ()
    maneuvers: tuple[str, ...] = TRANSIENT_MANEUVERS
    offset_s: float = 0.0
    window_revs: float = 8.0
    stick_offset_s: float = 0.0
    hop_revs: float = 0.0

    def __post_init__(self):
        _check_databases("replay", self.databases)
        _maneuver_kinds("replay.maneuvers", self.maneuvers, allow_empty=bool(self.counters))
        _within("replay.offset_s", self.offset_s, -MAX_OFFSET_S, MAX_OFFSET_S, " s")
        _within("replay.stick_offset_s", self.stick_offset_s, -MAX_OFFSET_S, MAX_OFFSET_S, " s")
        if not 1.0 <= self.window_revs <= 64.0:
            raise ValueError(f"replay.window_revs must be in [1, 64], got {self.window_revs}")
        _within("replay.hop_revs", self.hop_revs, 0, self.window_revs, " revolutions (replay.window_revs)")


@dataclass(frozen=True)
class CalibrationConfig:
    """Gradient calibration of offset, window length and stick lag (see `pvvjax.replay.calibration`).

    Attributes:
        free: parameters fitted: any of offset_s, window_revs, stick_offset_s.
        groups: one θ for "all" counters, one per "maneuver" kind, or one per "counter".
        offset_bounds, window_bounds, stick_offset_bounds: [lo, hi] of each parameter
            (s, revolutions, s).
        hop_revs: window spacing of the calibration replays (finer than L resolves the
            peak time better than the paper's consecutive windows).
        reference_revs: length of the measured PVV windows (0: the fitted window length,
            shared by inputs and vibration as in the paper; > 0: fixed reference windows,
            and the window length is that of the input averaging only).
        coarse_offset_step_s, coarse_window_step_revs, coarse_stick_step_s: the coarse
            grid whose best point starts each solve.
        grid_offset_step_s, grid_window_step_revs: the brute-force grid reported beside
            the gradient optimum (0: no grid).
        peak_weight, phase_weight, rms_weight, peak_scale_g, phase_scale_s, temperature_g,
            phase_cap_s: the cost (`replay.CostWeights`).
        max_steps: Levenberg-Marquardt steps at most.
    """

    free: tuple[str, ...] = ("offset_s", "window_revs")
    groups: Literal["all", "maneuver", "counter"] = "all"
    offset_bounds: tuple[float, float] = (-1.0, 3.0)
    window_bounds: tuple[float, float] = (4.0, 16.0)
    stick_offset_bounds: tuple[float, float] = (-2.0, 2.0)
    hop_revs: float = 1.0
    reference_revs: float = 0.0
    coarse_offset_step_s: float = 0.25
    coarse_window_step_revs: float = 2.0
    coarse_stick_step_s: float = 0.5
    grid_offset_step_s: float = 0.1
    grid_window_step_revs: float = 0.5
    peak_weight: float = 1.0
    phase_weight: float = 1.0
    rms_weight: float = 1.0
    peak_scale_g: float = 0.02
    phase_scale_s: float = 1.0
    temperature_g: float = 0.005
    phase_cap_s: float = 3.0
    max_steps: int = 64

    def __post_init__(self):
        params = ("offset_s", "window_revs", "stick_offset_s")
        bad = [f for f in self.free if f not in params]
        if bad or not self.free or len(set(self.free)) != len(self.free):
            raise ValueError(f"calibration.free: unknown or repeated {bad or list(self.free)}; use {list(params)}")
        _offsets("calibration.offset_bounds", self.offset_bounds)
        _bounds("calibration.window_bounds", self.window_bounds)
        _offsets("calibration.stick_offset_bounds", self.stick_offset_bounds)
        _within("calibration.window_bounds[1]", self.window_bounds[1], 1, MAX_WINDOW_REVS, " revolutions")
        _within("calibration.max_steps", self.max_steps, 1, 10_000)
        if self.window_bounds[0] < 1.0:
            raise ValueError(f"calibration.window_bounds must start at >= 1 revolution, got {self.window_bounds[0]}")
        for name in ("hop_revs", "coarse_offset_step_s", "coarse_window_step_revs", "coarse_stick_step_s",
                     "peak_scale_g", "phase_scale_s", "temperature_g", "max_steps"):
            if not getattr(self, name) > 0:
                raise ValueError(f"calibration.{name} must be > 0, got {getattr(self, name)}")
        for name in ("grid_offset_step_s", "grid_window_step_revs", "peak_weight", "phase_weight", "rms_weight",
                     "phase_cap_s", "reference_revs"):
            if getattr(self, name) < 0:
                raise ValueError(f"calibration.{name} must be >= 0, got {getattr(self, name)}")
        if not self.peak_weight + self.phase_weight + self.rms_weight > 0:
            raise ValueError("calibration.peak_weight, phase_weight and rms_weight are all 0: the cost would be 0 "
                             "everywhere; give one of them a weight")
        for bounds, step in (("offset_bounds", "coarse_offset_step_s"), ("window_bounds", "coarse_window_step_revs"),
                             ("stick_offset_bounds", "coarse_stick_step_s"), ("offset_bounds", "grid_offset_step_s"),
                             ("window_bounds", "grid_window_step_revs")):
            if getattr(self, step) > 0:
                _grid(f"calibration.{bounds}", getattr(self, bounds), f"calibration.{step}", getattr(self, step))


@dataclass(frozen=True)
class RunConfig:
    """What the main job (`pvvjax run`) does beyond campaign, databases and figures.

    Attributes:
        networks: train the config's `[sweep]` (resumable) and report Figs 10-12 and Table 1
            beside the paper.
        replay: with `networks`, fit the offset on every transient maneuver ([replay]
            maneuvers, [calibration]) and replay the pull-up 11022 (Figs 13-14).
        studies: with `replay`, the studies the paper left open: one offset per maneuver
            kind, the window length (gradient and brute-force grid) and a stick lag.
        discovery_scenario: a generator config (TOML) whose campaign hides an effect; the
            main job runs the discovery workflow on it ("": no discovery stage).
        dynamic: the models of PVV through time beside the quasi-static map ([dynamic];
            `pvvjax dynamic` into `OUT/dynamic`), with its table and figures in the report.
        axes: the three-axis study ([axes]; `pvvjax axes` into `OUT/axes`): per pilot-floor
            axis the held-out error, the FAA pass share and which inputs it needs.
        html: also write report.html beside report.md.
    """

    networks: bool = False
    replay: bool = True
    studies: bool = True
    discovery_scenario: str = ""
    dynamic: bool = False
    axes: bool = False
    html: bool = True
