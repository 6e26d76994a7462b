"""Quasi-static replay of recorded maneuvers through trained nets, and its calibration.

`quasistatic` replays one record at an input-to-vibration offset and window length (pure,
differentiable in both); `calibration` fits them by Levenberg-Marquardt; `tables` turns
replays into tables; `studies` runs the studies the paper left open.
"""

from .calibration import PARAMS, Bounds, Calibration, calibrate, cost_grid, counter_costs, group_members
from .quasistatic import (
    FEATURES,
    STICKS,
    CostWeights,
    Replay,
    ReplayRecord,
    Settings,
    cost_terms,
    input_index,
    make_settings,
    prepare,
    replay,
    replay_cost,
    residuals,
    soft_peak,
)
from .studies import Study, offset_per_kind, one_offset, stick_lag, window_length
from .tables import (
    calibration_settings,
    calibration_table,
    cost_weights,
    counter_cost_table,
    grid_table,
    load_replay_set,
    peak_summary,
    replay_windows,
    select_counters,
    settings_at,
    take_counters,
)

__all__ = [
    "Bounds",
    "Calibration",
    "CostWeights",
    "FEATURES",
    "PARAMS",
    "Replay",
    "ReplayRecord",
    "STICKS",
    "Settings",
    "Study",
    "calibrate",
    "calibration_settings",
    "calibration_table",
    "cost_grid",
    "cost_terms",
    "cost_weights",
    "counter_cost_table",
    "counter_costs",
    "grid_table",
    "group_members",
    "input_index",
    "load_replay_set",
    "make_settings",
    "offset_per_kind",
    "one_offset",
    "peak_summary",
    "prepare",
    "replay",
    "replay_cost",
    "replay_windows",
    "residuals",
    "select_counters",
    "settings_at",
    "soft_peak",
    "stick_lag",
    "take_counters",
    "window_length",
]
