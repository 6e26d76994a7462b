"""An experiment config, read from TOML and hashed."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

from .._strict import ConfigError, from_dict, to_dict
from ._axes import AxesConfig
from ._discovery import DiscoveryConfig
from ._dynamic import DynamicConfig
from ._sections import (
    AnalysisConfig,
    CalibrationConfig,
    CampaignConfig,
    ReplayConfig,
    RunConfig,
    SweepConfig,
    TrainConfig,
)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


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
    replay: ReplayConfig = field(default_factory=ReplayConfig)
    calibration: CalibrationConfig = field(default_factory=CalibrationConfig)
    discovery: DiscoveryConfig = field(default_factory=DiscoveryConfig)
    dynamic: DynamicConfig = field(default_factory=DynamicConfig)
    axes: AxesConfig = field(default_factory=AxesConfig)
    run: RunConfig = field(default_factory=RunConfig)

    def __post_init__(self):
        if self.seed < 0:
            raise ValueError(f"seed = {self.seed}: a random seed is a whole number >= 0")
        if not self.name.strip() or any(c in self.name for c in "/\\"):
            raise ValueError(f"name = {self.name!r}: the experiment's folder under out_dir; give a name without "
                             "a path separator")
        if self.campaign.path and self.campaign.synthetic:
            raise ValueError(f"campaign.path = {self.campaign.path!r} and campaign.synthetic = "
                             f"{self.campaign.synthetic!r} contradict each other: give one")

    def check_replay(self) -> None:
        """Refuse, by name, a replay of databases the config's own sweep does not train (with
        `replay.sweep` empty the replay uses that sweep); checked where a replay runs, since
        a config that only trains need not set `[replay]`."""
        if not self.replay.sweep:
            missing = [db for db in self.replay.databases if db not in self.sweep.databases]
            if missing:
                raise ConfigError(f"replay.databases {list(self.replay.databases)} names {', '.join(missing)}, which "
                                  f"sweep.databases {list(self.sweep.databases)} does not train (replay.sweep is "
                                  "empty: the replay uses the config's own sweep)")

    def check_scenario(self) -> None:
        """Read the main job's discovery scenario (`run.discovery_scenario`), refusing a
        missing or mistaken one by name before any work."""
        if self.run.discovery_scenario:
            from ..synth import load_synth_config

            try:
                load_synth_config(self.run.discovery_scenario)
            except ConfigError as e:
                raise ConfigError(f"run.discovery_scenario: {e}") from None

    def with_(self, **changes) -> "ExperimentConfig":
        return dataclasses.replace(self, **changes)


def load_toml(path: str | Path) -> dict:
    """Read a TOML file (UTF-8, with or without a byte-order mark); a syntax error, or text
    in another encoding, names the file and what to change."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such config file") from None
    except IsADirectoryError:
        raise ConfigError(f"{path}: is a folder, not a config file") from None
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise ConfigError(f"{path}: saved as UTF-16; save it as UTF-8 (TOML is UTF-8 text)")
    try:
        text = raw.decode("utf-8-sig")  # a byte-order mark (some Windows editors write one) is dropped
    except UnicodeDecodeError as e:
        line = raw[:e.start].count(b"\n") + 1
        raise ConfigError(f"{path}: not UTF-8 text (byte 0x{raw[e.start]:02x} on line {line}); save it as "
                          "UTF-8") from None
    try:
        return tomllib.loads(text)
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


def config_hash(cfg, data: str = "") -> str:
    """A short stable hash of a config's content and of the data fingerprint it ran on
    (for result tables and caches): a result of the same config on changed data hashes
    differently."""
    blob = json.dumps(to_dict(cfg), sort_keys=True, default=str) + (f"|{data}" if data else "")
    return hashlib.sha256(blob.encode()).hexdigest()[:12]
