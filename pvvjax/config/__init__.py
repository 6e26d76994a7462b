"""Experiment configs: TOML files validated into frozen dataclasses.

An unknown or mistyped key, a value of the wrong type, or a value out of range is a
`ConfigError` that names the file and the key. Relative paths in a config are relative to
the working directory the command runs in. The Python functions refuse an argument they
cannot use with one `ArgumentError` that names the function and the argument.
"""

from .._arguments import ArgumentError
from .._strict import ConfigError, from_dict, to_dict
from ..data.units import ColumnMap
from ._axes import AxesConfig
from ._discovery import DiscoveryConfig, EnsembleConfig, OffsetConfig
from ._dynamic import MODELS as DYNAMIC_MODELS
from ._dynamic import ZETA_RANGE, DynamicConfig
from ._experiment import ExperimentConfig, config_hash, load_config, load_toml
from ._sections import (
    TRANSIENT_MANEUVERS,
    AnalysisConfig,
    CalibrationConfig,
    CampaignConfig,
    ReplayConfig,
    RunConfig,
    SweepConfig,
    TrainConfig,
)

__all__ = [
    "AnalysisConfig",
    "ArgumentError",
    "AxesConfig",
    "CalibrationConfig",
    "CampaignConfig",
    "ColumnMap",
    "ConfigError",
    "DYNAMIC_MODELS",
    "DiscoveryConfig",
    "DynamicConfig",
    "EnsembleConfig",
    "ExperimentConfig",
    "OffsetConfig",
    "ReplayConfig",
    "RunConfig",
    "SweepConfig",
    "TRANSIENT_MANEUVERS",
    "TrainConfig",
    "ZETA_RANGE",
    "config_hash",
    "from_dict",
    "load_config",
    "load_toml",
    "to_dict",
]
