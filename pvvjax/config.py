"""Experiment configs: TOML files validated into frozen dataclasses.

An unknown or mistyped key, a value of the wrong type, or a value out of range is a
`ConfigError` that names the file and the key. Relative paths in a config are relative to
the working directory the command runs in.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from ._strict import ConfigError, from_dict, to_dict
from .units import CANONICAL_UNITS, conversion_factor

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "AnalysisConfig",
    "CampaignConfig",
    "ColumnMap",
    "ConfigError",
    "ExperimentConfig",
    "SweepConfig",
    "TrainConfig",
    "config_hash",
    "load_config",
    "load_toml",
]


@dataclass(frozen=True)
class ColumnMap:
    """How one foreign column becomes a canonical channel.

    canonical value = raw value × (unit conversion, if `unit` is given) × `scale` + `offset`.
    """

    to: str
    unit: str | None = None
    scale: float = 1.0
    offset: float = 0.0

    def __post_init__(self):
        if self.unit is not None:
            conversion_factor(self.unit, self.to)  # raises on an unknown unit or wrong dimension

    def factor(self) -> float:
        return (conversion_factor(self.unit, self.to) if self.unit else 1.0) * self.scale


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
        harmonic: harmonic order k analysed (4 for the 4-bladed UH-60A: 4/rev).
        taper_revs: width of the raised-cosine window edges in revolutions; 0 gives the
            rectangular window (edges resolved to fractions of a sample).
        inputs: how a database row takes the flight state at the peak window: "mean"
            averages each channel over the window (the paper's replay inputs), "center"
            takes the instantaneous value at the window's center.
    """

    window_revs: float = 8.0
    hop_revs: float = 0.0
    harmonic: int = 4
    taper_revs: float = 0.0
    inputs: Literal["mean", "center"] = "mean"

    def __post_init__(self):
        if not self.window_revs > 0:
            raise ValueError(f"window_revs must be > 0, got {self.window_revs}")
        if self.hop_revs < 0:
            raise ValueError(f"hop_revs must be >= 0, got {self.hop_revs}")
        if self.harmonic < 1:
            raise ValueError(f"harmonic must be >= 1, got {self.harmonic}")
        if self.taper_revs < 0 or self.taper_revs >= self.window_revs:
            raise ValueError(f"taper_revs must be in [0, window_revs), got {self.taper_revs}")

    @property
    def hop(self) -> float:
        return self.hop_revs or self.window_revs


@dataclass(frozen=True)
class TrainConfig:
    """Full-batch training of one net.

    Attributes:
        optimizer: "adam" (first order) or "lm" (Levenberg-Marquardt, second order).
        learning_rate: Adam step size.
        max_steps: optimizer steps at most.
        eval_every: steps between validation evaluations.
        patience: evaluations without a better validation RMS before stopping.
        weight_decay: decoupled weight decay (AdamW) when > 0.
        lm_damping: initial Levenberg-Marquardt damping λ.
        divergence_factor: a training loss above this multiple of the initial loss is divergence.
    """

    optimizer: Literal["adam", "lm"] = "adam"
    learning_rate: float = 3e-3
    max_steps: int = 6000
    eval_every: int = 50
    patience: int = 10
    weight_decay: float = 0.0
    lm_damping: float = 1e-2
    divergence_factor: float = 1e3

    def __post_init__(self):
        for name in ("learning_rate", "max_steps", "eval_every", "patience", "lm_damping", "divergence_factor"):
            if not getattr(self, name) > 0:
                raise ValueError(f"train.{name} must be > 0, got {getattr(self, name)}")
        if self.weight_decay < 0:
            raise ValueError(f"train.weight_decay must be >= 0, got {self.weight_decay}")


@dataclass(frozen=True)
class SweepConfig:
    """A family of nets trained together: databases × architectures × seeds × folds.

    Attributes:
        databases: which of db1, db2, db3.
        family: "mlp" (back-propagation nets) or "rbf" (radial-basis-function nets).
        hidden: MLP hidden-layer widths per architecture, e.g. [[10, 5], [15, 5]].
        centers: RBF centre counts per architecture.
        seeds: number of initialisation seeds (0 .. seeds-1).
        folds: k of the k-fold split by condition.
        test_folds: outer folds to run (empty: all k, so every condition is held out once).
        split_seed: seed of the assignment of conditions to folds.
        chunk_evals: evaluations per compiled chunk; finished nets leave the batch between chunks.
        cpu_devices: on CPU, expose this many host devices so that the net axis is sharded
            over the cores (0: one per core; 1: off). Applied by `pvvjax sweep` before JAX
            starts; results then depend on it (same config, seed and devices: same numbers).
    """

    databases: tuple[str, ...] = ("db1", "db2", "db3")
    family: Literal["mlp", "rbf"] = "mlp"
    hidden: tuple[tuple[int, ...], ...] = ((10, 5),)
    centers: tuple[int, ...] = (20,)
    seeds: int = 1
    folds: int = 5
    test_folds: tuple[int, ...] = ()
    split_seed: int = 0
    chunk_evals: int = 4
    cpu_devices: int = 0

    def __post_init__(self):
        if self.cpu_devices < 0:
            raise ValueError(f"sweep.cpu_devices must be >= 0, got {self.cpu_devices}")
        bad = [d for d in self.databases if d not in ("db1", "db2", "db3")]
        if bad or not self.databases:
            raise ValueError(f"sweep.databases: unknown {bad}; use db1, db2, db3")
        if any(not h or min(h) < 1 for h in self.hidden):
            raise ValueError(f"sweep.hidden: every architecture needs widths >= 1, got {self.hidden}")
        if self.seeds < 1 or self.folds < 3 or self.chunk_evals < 1:
            raise ValueError("sweep.seeds must be >= 1, sweep.folds >= 3, sweep.chunk_evals >= 1")
        if any(not 0 <= f < self.folds for f in self.test_folds):
            raise ValueError(f"sweep.test_folds must lie in 0..{self.folds - 1}, got {self.test_folds}")

    @property
    def fold_list(self) -> tuple[int, ...]:
        return self.test_folds or tuple(range(self.folds))


@dataclass(frozen=True)
class ExperimentConfig:
    """One experiment: a campaign and the pipeline settings applied to it."""

    name: str = "experiment"
    out_dir: str = "runs"
    seed: int = 0
    campaign: CampaignConfig = field(default_factory=CampaignConfig)
    analysis: AnalysisConfig = field(default_factory=AnalysisConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    sweep: SweepConfig = field(default_factory=SweepConfig)

    def with_(self, **changes) -> "ExperimentConfig":
        return dataclasses.replace(self, **changes)


def load_toml(path: str | Path) -> dict:
    """Read a TOML file; a syntax error names the file."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such config file") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: not valid TOML: {e}") from None


def load_config(path: str | Path, cls: type = ExperimentConfig):
    """Load and validate a TOML config into the frozen dataclass `cls`.

    Raises:
        ConfigError: naming the file and the offending key.
    """
    data = load_toml(path)
    try:
        return from_dict(cls, data)
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from None


def config_hash(cfg) -> str:
    """A short stable hash of a config's content (for result tables and caches)."""
    blob = json.dumps(to_dict(cfg), sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:12]
