"""pvvjax: neural-network modelling of helicopter pilot-floor 4/rev vibration (PVV) in JAX.

The pipeline: campaign → windowed harmonic analysis → peak PVV → databases 1-3 → networks
→ quasi-static replay. The numerical core is pure `jax.numpy`; files, CLI and plots sit
at the edges.
"""

from .batch import RecordBatch, to_batch
from .campaign import (
    MANEUVERS,
    REQUIRED_CHANNELS,
    Campaign,
    CampaignError,
    Problem,
    campaign_from_frames,
    load_campaign,
    validate_campaign,
    write_campaign,
)
from .config import AnalysisConfig, CampaignConfig, ColumnMap, ConfigError, ExperimentConfig, load_config
from .constants import UH60A, Aircraft
from .databases import DB_INPUTS, OUTPUT, build_databases, condition_peaks, peak_table
from .features import (
    advance_ratio,
    blade_loading,
    derive_features,
    maneuver_load_factor,
    thrust_coefficient,
)
from .harmonics import Windows, analyze, harmonic_windows, plan_windows

__version__ = "0.1.0"

__all__ = [
    "Aircraft", "AnalysisConfig", "Campaign", "CampaignConfig", "CampaignError", "ColumnMap", "ConfigError",
    "DB_INPUTS", "ExperimentConfig", "MANEUVERS", "OUTPUT", "Problem", "REQUIRED_CHANNELS", "RecordBatch", "UH60A",
    "Windows", "advance_ratio", "analyze", "blade_loading", "build_databases", "campaign_from_frames",
    "condition_peaks", "derive_features", "harmonic_windows", "load_campaign", "load_config",
    "maneuver_load_factor", "peak_table", "plan_windows", "thrust_coefficient", "to_batch", "validate_campaign",
    "write_campaign",
]
