"""The `[axes]` section: the three-axis study (`pvvjax axes`): which inputs each pilot-floor
axis needs, judged by FAA Part 60 test 3.f.1."""

from __future__ import annotations

from dataclasses import dataclass, field

from ._sections import _advance_ratio_band, _check_databases, _counts, _widths


@dataclass(frozen=True)
class AxesConfig:
    """Nets of one output per pilot-floor axis (`analysis.axes_database`), trained k-fold by
    condition on each database's inputs and judged per axis on held-out conditions.

    Attributes:
        databases: input sets compared (db1, db2, db3), in the order a smaller set is
            preferred: an axis needs the first one that passes.
        hidden: hidden-layer widths of the nets (one net predicts every axis).
        seeds: initialisation seeds per fold (predictions are their mean).
        folds: k of the k-fold split by condition.
        cruise_advance_ratio: [lo, hi] advance ratio of the level flights whose median
            measured peak is an axis's nominal cruise level (the FAA tolerance's 10 %).
        pass_share: the share of held-out conditions that must pass test 3.f.1 for a
            database's inputs to suffice for an axis.
        discovery: run the discovery (`[discovery]`) on every axis no database suffices
            for, to name the input it lacks (minutes on a full campaign).
    """

    databases: tuple[str, ...] = ("db1", "db2", "db3")
    hidden: tuple[int, ...] = field(default=(10, 5), metadata={"repeats": True})  # layer widths
    seeds: int = 4
    folds: int = 5
    cruise_advance_ratio: tuple[float, float] = field(default=(0.25, 0.35), metadata={"repeats": True})
    pass_share: float = 0.9
    discovery: bool = True

    def __post_init__(self):
        _check_databases("axes", self.databases)
        _widths("axes.hidden", self.hidden)
        _counts("axes", self.seeds, self.folds)
        if not 0 < self.pass_share <= 1:
            raise ValueError(f"axes.pass_share must lie in (0, 1], got {self.pass_share}")
        _advance_ratio_band("axes.cruise_advance_ratio", self.cruise_advance_ratio)
