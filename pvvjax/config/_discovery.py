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
class SelectionConfig:
    """Which candidates a round proposes (`discovery.selection.forward_select`).

    Attributes:
        proposals: significant candidates retrained per round, in rank order.
        alpha: significance level of the selection's block-permutation test.
        permutations: permutations of that test.
        source_tries: candidates built only from the channels that the model's derived
            inputs are computed from but that it does not take (for db1, the load factor's
            roll angle and pitch rate), tried beside the proposals, the best by held-out gain
            first. The nets learn part of such an effect through the derived input, so the
            residual can under-rank it. Each costs two retrainings a round.
    """

    proposals: int = 3
    alpha: float = 0.01
    permutations: int = 99
    source_tries: int = 0

    def __post_init__(self):
        for name in ("proposals", "permutations"):
            if getattr(self, name) < 1:
                raise ValueError(f"discovery.selection.{name} must be >= 1, got {getattr(self, name)}")
        if not 0 < self.alpha < 1:
            raise ValueError(f"discovery.selection.alpha must lie in (0, 1), got {self.alpha}")
        if self.source_tries < 0:
            raise ValueError(f"discovery.selection.source_tries must be >= 0, got {self.source_tries}")
        _within("discovery.selection.proposals", self.proposals, 1, 50)
        _within("discovery.selection.permutations", self.permutations, 1, 100_000)
        _within("discovery.selection.source_tries", self.source_tries, 0, 50)


@dataclass(frozen=True)
class LagTestConfig:
    """The test for a slow lag of the vibration behind the flight state, before the first round.

    Window nets and a lag of learnable τ between them and the measured PVV are trained
    jointly; a τ (median over folds × seeds) of at least `slow_s` confirms a slow lag, which
    window nets trained through it then add as the first effect. The rounds then propose no
    lag of the prediction.

    Attributes:
        enabled: run the test.
        slow_s: the learned τ from which a lag counts as slow, s. The learned τ includes the
            fast rotor dynamics that the offset stands for, so it sits above them.
    """

    enabled: bool = False
    slow_s: float = 2.0

    def __post_init__(self):
        if not self.slow_s > 0:
            raise ValueError(f"discovery.lag_test.slow_s must be > 0 s, got {self.slow_s}")
        _within("discovery.lag_test.slow_s", self.slow_s, 0, MAX_OFFSET_S, " s")


@dataclass(frozen=True)
class ResonanceConfig:
    """Resonances of a structural mode at a rotor speed (a gain on the nets' output).

    Attributes:
        probe: in a round that proposes no resonance, train a gain on every rotor-speed band
            at once and propose the band of the largest gain (the confirmation decides). A
            mode the nets learned as a mean per rotor-speed level leaves no residual that a
            prediction × band column explains.
        as_input: also try a band as an extra network input beside its gain, the better
            confirmed kept. Where the nets already learned most of a mode through rotor speed,
            what is left is not proportional to their prediction.
    """

    probe: bool = False
    as_input: bool = False


@dataclass(frozen=True)
class DiscoveryConfig:
    """The discovery workflow (see `pvvjax.discovery`). Its decision rules, which no user
    tunes, are constants beside the code (`pvvjax.discovery` documents them).

    Attributes:
        database: the model's database (db1, db2 or db3).
        max_effects: effects added at most (0: the baseline and its residual map only).
        min_shrink: the smallest relative drop of the ensemble's held-out RMS, where the
            effect acts, that confirms an effect after retraining (or twice this over all
            windows): less is retraining noise.
        exclude_channels: campaign channels never offered as candidates (e.g. one a user
            knows to be derived from the vibration).
        ensemble, offset, selection, lag_test, resonance: the sections above.
    """

    database: str = "db1"
    max_effects: int = 3
    min_shrink: float = 0.05
    exclude_channels: tuple[str, ...] = ()
    ensemble: EnsembleConfig = field(default_factory=EnsembleConfig)
    offset: OffsetConfig = field(default_factory=OffsetConfig)
    selection: SelectionConfig = field(default_factory=SelectionConfig)
    lag_test: LagTestConfig = field(default_factory=LagTestConfig)
    resonance: ResonanceConfig = field(default_factory=ResonanceConfig)

    def __post_init__(self):
        _check_databases("discovery", (self.database,), "database")
        if self.max_effects < 0:
            raise ValueError(f"discovery.max_effects must be >= 0 (0: baseline and residual map only), "
                             f"got {self.max_effects}")
        _within("discovery.max_effects", self.max_effects, 0, 20)
        if not 0 <= self.min_shrink < 1:
            raise ValueError(f"discovery.min_shrink must lie in [0, 1), got {self.min_shrink}")
        if self.max_effects == 0:  # no rounds: what runs in a round would be skipped without a word
            asked = [k for k, on in (("lag_test.enabled", self.lag_test.enabled),
                                     ("resonance.probe", self.resonance.probe)) if on]
            if asked:
                raise ValueError(f"discovery.{asked[0]} = true contradicts discovery.max_effects = 0 (no effect "
                                 "rounds, where it runs); set max_effects >= 1 or turn it off")
