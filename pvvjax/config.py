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
class ExperimentConfig:
    """One experiment: a campaign and the pipeline settings applied to it."""

    name: str = "experiment"
    out_dir: str = "runs"
    seed: int = 0
    campaign: CampaignConfig = field(default_factory=CampaignConfig)
    analysis: AnalysisConfig = field(default_factory=AnalysisConfig)

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
