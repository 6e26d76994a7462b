"""pvvjax: neural-network modelling of helicopter pilot-floor 4/rev vibration (PVV) in JAX.

The pipeline: campaign → windowed harmonic analysis → peak PVV → databases 1-3 → networks
→ quasi-static replay → calibration of the offset and window length → discovery of the
effects the static map misses. The numerical core is pure `jax.numpy`; files, CLI and plots
sit at the edges.

The subpackages follow the pipeline: `data` (campaigns, batches, features), `analysis`
(harmonics, databases), `nets` (networks, training, sweeps), `replay` (replay, calibration),
`dynamics` (PVV through time), `seat` (the three pilot-floor axes), `realtime` (the
simulator element), `discovery`, `paper` and `synth` (the generator); the
shell is `config`, `experiment`, `io`, `plots` and `cli`. Names are imported lazily, so
`pvvjax.realtime` (the NumPy element for a simulator host) can be used without importing JAX.
"""

import importlib

_EXPORTS = {
    "analysis": ["AXES", "DB_INPUTS", "OUTPUT", "Windows", "analyze", "analyze_axes", "axis_peak_tables",
                 "build_databases", "condition_peaks", "harmonic_windows", "peak_table", "plan_windows"],
    "config": ["AnalysisConfig", "ArgumentError", "CalibrationConfig", "CampaignConfig", "ColumnMap", "ConfigError",
               "DiscoveryConfig", "ExperimentConfig", "ReplayConfig", "SweepConfig", "TrainConfig", "load_config"],
    "data": ["MANEUVERS", "REQUIRED_CHANNELS", "UH60A", "Aircraft", "Campaign", "CampaignError", "Problem",
             "RecordBatch", "advance_ratio", "blade_loading", "campaign_from_frames", "derive_features",
             "load_campaign", "maneuver_load_factor", "thrust_coefficient", "to_batch", "validate_campaign",
             "write_campaign"],
    "discovery": ["Candidate", "Discovery", "discover", "explain", "library", "localize",
                  "residual_windows", "summary", "window_table", "write_discovery"],
    "nets": ["condition_folds", "fit", "heldout_models", "load_params", "make_data", "mlp_apply", "mlp_init",
             "rbf_apply", "rbf_fit", "run_sweep"],
    "realtime": ["NumpyNet", "VibrationElement"],
    # the function itself: pvvjax.replay.replay
    "replay": ["CostWeights", "Replay", "calibrate", "cost_grid", "counter_costs", "group_members", "load_replay_set",
               "make_settings", "peak_summary", "prepare", "replay_cost", "replay_windows"],
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
