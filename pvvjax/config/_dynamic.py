"""The `[dynamic]` section: the dynamic PVV models and their comparison with the
quasi-static map (`pvvjax dynamic`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ._sections import (
    MAX_OFFSET_S,
    MAX_WIDTH,
    MAX_WINDOW_REVS,
    TRANSIENT_MANEUVERS,
    _advance_ratio_band,
    _check_databases,
    _counts,
    _grid,
    _maneuver_kinds,
    _offsets,
    _widths,
)

MODELS = ("quasi_static", "window_static", "window_static_rates", "dynamic", "rnn")
# The damping ratio of a response the seat can show: below 0.01 a mode rings on through a
# whole campaign; above 20 it is a first-order lag that ω_n and ζ no longer identify apart.
ZETA_RANGE = (0.01, 20.0)


@dataclass(frozen=True)
class DynamicConfig:
    """Models of PVV through time, trained on window sequences and judged on held-out
    conditions beside the paper's quasi-static map (`pvvjax.dynamics.compare`).

    Attributes:
        databases: input sets compared (db1, db2, db3); each model takes the database's
            inputs, and the `_rates` variants and `rnn` their rates too.
        models: which models: quasi_static (the peak map, replayed), window_static (the
            same map trained on every window), window_static_rates (with the inputs'
            rates), dynamic (the map, a delay and a second-order response), rnn (a GRU).
        window_revs: sequence window length, revolutions (short windows resolve the time
            history; the quasi-static map keeps `[analysis] window_revs`).
        hop_revs: window spacing, revolutions (at most 1).
        hidden: the static map's hidden-layer widths.
        rnn_hidden: the recurrent model's GRU units.
        seeds: initialisation seeds per fold (predictions are their mean).
        folds: k of the k-fold split by condition (every condition held out once).
        kind_holdout: also hold out one maneuver kind at a time (a second split).
        f_n_hz, zeta, delay_s: the response's starting natural frequency (Hz), damping
            ratio and delay (s).
        offset_bounds, offset_step_s: the grid the quasi-static map's input-to-vibration
            offset is calibrated on, per fold on its training records (s).
        cruise_advance_ratio: [lo, hi] advance ratio of the level flights whose median
            measured peak is the nominal cruise level of the FAA tolerance.
        transients: maneuver kinds whose time of peak is scored.
        learning_rate: Adam step size of the models trained on window sequences (every
            model but quasi_static, which trains as the paper's map with `[train]`); their
            other training settings are `[train]`'s. Tens of thousands of windows give a
            smooth loss that takes a larger step than a database of peaks.
        burn_in_s: the models with a state (dynamic, rnn) train on pieces of the records,
            each scored after this long of its record has run through the state (a piece
            is three burn-ins long; `compare.record_pieces`), s: at least a few time
            constants of the slowest response the data hold. 0: whole records (slower: the
            recurrence walks the longest record at every step). Held-out predictions always
            run on whole records.
    """

    databases: tuple[str, ...] = ("db1",)
    models: tuple[str, ...] = MODELS
    window_revs: float = 2.0
    hop_revs: float = 1.0
    hidden: tuple[int, ...] = field(default=(10, 5), metadata={"repeats": True})  # layer widths
    rnn_hidden: int = 8
    seeds: int = 4
    folds: int = 5
    kind_holdout: bool = True
    f_n_hz: float = 0.5
    zeta: float = 0.7
    delay_s: float = 0.1
    offset_bounds: tuple[float, float] = field(default=(-1.0, 3.0), metadata={"repeats": True})
    offset_step_s: float = 0.1
    cruise_advance_ratio: tuple[float, float] = field(default=(0.25, 0.35), metadata={"repeats": True})
    transients: tuple[str, ...] = TRANSIENT_MANEUVERS
    learning_rate: float = 0.01
    burn_in_s: float = 4.0

    def __post_init__(self):
        _check_databases("dynamic", self.databases)
        bad = [m for m in self.models if m not in MODELS]
        if bad or not self.models:
            raise ValueError(f"dynamic.models: unknown {bad}; use {list(MODELS)}")
        if not 0 < self.hop_revs <= 1:
            raise ValueError(f"dynamic.hop_revs must lie in (0, 1] revolution, got {self.hop_revs}")
        if not self.window_revs >= 1:
            raise ValueError(f"dynamic.window_revs must be >= 1 revolution, got {self.window_revs}")
        if not self.window_revs <= MAX_WINDOW_REVS:
            raise ValueError(f"dynamic.window_revs must be at most {MAX_WINDOW_REVS:g} revolutions, got "
                             f"{self.window_revs}")
        _widths("dynamic.hidden", self.hidden)
        if not 1 <= self.rnn_hidden <= MAX_WIDTH:
            raise ValueError(f"dynamic.rnn_hidden = {self.rnn_hidden}: give 1 to {MAX_WIDTH} units")
        _counts("dynamic", self.seeds, self.folds)
        for name in ("f_n_hz", "zeta", "offset_step_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"dynamic.{name} must be > 0, got {getattr(self, name)}")
        if not ZETA_RANGE[0] <= self.zeta <= ZETA_RANGE[1]:
            raise ValueError(f"dynamic.zeta = {self.zeta:g}: a damping ratio within {ZETA_RANGE[0]:g} to "
                             f"{ZETA_RANGE[1]:g}")
        if self.delay_s < 0:
            raise ValueError(f"dynamic.delay_s must be >= 0, got {self.delay_s}")
        _offsets("dynamic.offset_bounds", self.offset_bounds)
        _grid("dynamic.offset_bounds", self.offset_bounds, "dynamic.offset_step_s", self.offset_step_s)
        _advance_ratio_band("dynamic.cruise_advance_ratio", self.cruise_advance_ratio)
        _maneuver_kinds("dynamic.transients", self.transients)
        if not 0 <= self.burn_in_s <= MAX_OFFSET_S:
            raise ValueError(f"dynamic.burn_in_s = {self.burn_in_s:g}: give 0 (whole records) to {MAX_OFFSET_S:g} s")
        if not 0 < self.learning_rate <= 1:
            raise ValueError(f"dynamic.learning_rate = {self.learning_rate!r}: must lie within 0 (excluded) to 1")
