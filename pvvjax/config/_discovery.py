"""The discovery workflow's settings: what a user sets, in sections."""

from __future__ import annotations

from dataclasses import dataclass, field

from ._sections import MAX_OFFSET_S, _check_databases, _counts, _grid, _offsets, _widths, _within


@dataclass(frozen=True)
class EnsembleConfig:
    """The nets of every model discovery trains: k-fold by condition over several seeds.

    Attributes:
        hidden: hidden-layer widths of the nets.
        seeds: training seeds; metrics are medians over seeds, predictions the ensemble's.
        folds: k of the k-fold split by condition (every counter is replayed by the nets that
            held its condition out).
        split_seed: seed of the assignment of conditions to folds.
    """

    hidden: tuple[int, ...] = field(default=(10, 5), metadata={"repeats": True})  # layer widths
    seeds: int = 4
    folds: int = 5
    split_seed: int = 0

    def __post_init__(self):
        _widths("discovery.ensemble.hidden", self.hidden)
        _counts("discovery.ensemble", self.seeds, self.folds)
        _within("discovery.ensemble.split_seed", self.split_seed, 0, 2**63 - 1)


@dataclass(frozen=True)
class OffsetConfig:
    """The input-to-vibration offset of the replays (inputs precede the vibration when > 0).

    Attributes:
        calibrate: fit the offset on the held-out windows over a grid (else use `fixed_s`).
        fixed_s: the offset when it is not calibrated, s.
        bounds: [lo, hi] of the grid, s.
        step_s: the grid's step, s.
    """

    calibrate: bool = True
    fixed_s: float = 0.0
    bounds: tuple[float, float] = (0.0, 3.0)
    step_s: float = 0.1

    def __post_init__(self):
        _offsets("discovery.offset.bounds", self.bounds)
        if not self.step_s > 0:
            raise ValueError(f"discovery.offset.step_s must be > 0, got {self.step_s}")
        _grid("discovery.offset.bounds", self.bounds, "discovery.offset.step_s", self.step_s)
        _within("discovery.offset.fixed_s", self.fixed_s, -MAX_OFFSET_S, MAX_OFFSET_S, " s")


@dataclass(frozen=True)
class DiscoveryConfig:
    """The discovery workflow (see `pvvjax.discovery`): one test at one stated level decides
    what is named; no other decision rule is a setting.

    Attributes:
        database: the model's database (db1, db2 or db3).
        level: the family-wise error of each round of the test (Holm over the candidates):
            on a campaign where nothing is missing, discovery names something at about this
            rate.
        max_effects: effects of each kind named at most: forms of the misfit, then missing
            effects (0: the baseline and its residual map only).
        exclude_channels: campaign channels never offered as candidates (e.g. one a user
            knows to be derived from the vibration).
        simulation: a column of every record that holds the user's own simulated PVV (g,
            per sample, from whatever code produced it): the baseline instead of the
            database's nets ("" for the nets). Its windows are the measured ones at offset 0.
        simulation_inputs: the channels (or derived features) that simulation took as its
            inputs: what explains the residual beyond any function of them is named.
        ensemble, offset: the sections above.
    """

    database: str = "db1"
    level: float = 0.05
    max_effects: int = 3
    exclude_channels: tuple[str, ...] = ()
    simulation: str = ""
    simulation_inputs: tuple[str, ...] = ()
    ensemble: EnsembleConfig = field(default_factory=EnsembleConfig)
    offset: OffsetConfig = field(default_factory=OffsetConfig)

    def __post_init__(self):
        _check_databases("discovery", (self.database,), "database")
        if not 0 < self.level < 1:
            raise ValueError(f"discovery.level must lie in (0, 1) (a family-wise error rate), got {self.level}")
        if self.max_effects < 0:
            raise ValueError(f"discovery.max_effects must be >= 0 (0: baseline and residual map only), "
                             f"got {self.max_effects}")
        _within("discovery.max_effects", self.max_effects, 0, 20)
        if bool(self.simulation) != bool(self.simulation_inputs):
            raise ValueError("discovery.simulation and discovery.simulation_inputs go together: the column of the "
                             "simulated PVV and the channels the simulation took as its inputs"
                             + (f" (simulation = {self.simulation!r} has no inputs)" if self.simulation else
                                f" (simulation_inputs = {list(self.simulation_inputs)} without a simulation)"))
        if self.simulation in self.simulation_inputs:
            raise ValueError(f"discovery.simulation_inputs: {self.simulation!r} is the simulation's own output")
