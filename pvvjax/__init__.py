"""pvvjax: neural-network modelling of helicopter pilot-floor 4/rev vibration (PVV) in JAX.

The pipeline: campaign → windowed harmonic analysis → peak PVV → databases 1-3 → networks
→ quasi-static replay → calibration of the offset and window length → discovery of the
effects the static map misses. The numerical core is pure `jax.numpy`; files, CLI and plots
sit at the edges.

Names are imported lazily, so `pvvjax.npnet` (the NumPy evaluator for a simulator host)
can be used without importing JAX.
"""

import importlib

_EXPORTS = {
    "batch": ["RecordBatch", "to_batch"],
    "calibration": ["calibrate", "cost_grid", "counter_costs", "group_members"],
    "campaign": ["MANEUVERS", "REQUIRED_CHANNELS", "Campaign", "CampaignError", "Problem", "campaign_from_frames",
                 "load_campaign", "validate_campaign", "write_campaign"],
    "candidates": ["Candidate", "library", "window_table"],
    "config": ["AnalysisConfig", "CalibrationConfig", "CampaignConfig", "ColumnMap", "ConfigError", "DiscoveryConfig",
               "ExperimentConfig", "ReplayConfig", "SweepConfig", "TrainConfig", "load_config"],
    "constants": ["UH60A", "Aircraft"],
    "databases": ["DB_INPUTS", "OUTPUT", "build_databases", "condition_peaks", "peak_table"],
    "discovery": ["Discovery", "delag", "discover", "summary"],
    "discovery_report": ["write_discovery"],
    "features": ["advance_ratio", "blade_loading", "derive_features", "maneuver_load_factor", "thrust_coefficient"],
    "harmonics": ["Windows", "analyze", "harmonic_windows", "plan_windows"],
    "lag_study": ["lag_study"],
    "networks": ["mlp_apply", "mlp_init", "rbf_apply", "rbf_fit"],
    "npnet": ["NumpyNet"],
    # the function itself: pvvjax.replay.replay
    "replay": ["CostWeights", "Replay", "make_settings", "prepare", "replay_cost"],
    "replay_tables": ["load_replay_set", "peak_summary", "replay_windows"],
    "residuals": ["localize", "residual_windows"],
    "rtelement": ["VibrationElement"],
    "selection": ["forward_select"],
    "sweep": ["heldout_models", "load_params", "run_sweep"],
    "train": ["fit", "make_data", "condition_folds"],
}
_WHERE = {name: mod for mod, names in _EXPORTS.items() for name in names}

__version__ = "0.1.0"
__all__ = sorted(_WHERE)


def __getattr__(name):
    mod = _WHERE.get(name)
    if mod is None:
        raise AttributeError(f"module 'pvvjax' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{mod}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
