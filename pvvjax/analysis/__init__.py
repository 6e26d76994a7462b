"""Windowed harmonic analysis of the pilot-floor acceleration and the databases built on it.

`harmonics` measures the N/rev amplitude per window of L rotor revolutions (jit, vmap,
differentiable in L); `databases` takes each condition's peak window into db1-db3
(data-contract §2).
"""

from .databases import (
    DATABASES,
    DB_INPUTS,
    META_COLUMNS,
    OUTPUT,
    STATE_CHANNELS,
    Peaks,
    build_databases,
    condition_peaks,
    peak_table,
    window_table,
)
from .harmonics import (
    EDGES,
    Columns,
    WindowPlan,
    Windows,
    analyze,
    edge_weight,
    harmonic_from_means,
    harmonic_windows,
    means_from_sums,
    plan_windows,
    record_bounds,
    record_columns,
    stack_columns,
    window_sums,
    with_prefix,
)

__all__ = [
    "Columns",
    "DATABASES",
    "DB_INPUTS",
    "EDGES",
    "META_COLUMNS",
    "OUTPUT",
    "Peaks",
    "STATE_CHANNELS",
    "WindowPlan",
    "Windows",
    "analyze",
    "build_databases",
    "condition_peaks",
    "edge_weight",
    "harmonic_from_means",
    "harmonic_windows",
    "means_from_sums",
    "peak_table",
    "plan_windows",
    "record_bounds",
    "record_columns",
    "stack_columns",
    "window_sums",
    "window_table",
    "with_prefix",
]
