"""Experiment configs: TOML files validated into frozen dataclasses.

An unknown or mistyped key, a value of the wrong type, or a value out of range is a
`ConfigError` that names the file and the key. Relative paths in a config are relative to
the working directory the command runs in.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from ._strict import ConfigError, from_dict, to_dict
from .data.units import CANONICAL_UNITS, ColumnMap

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "AnalysisConfig",
    "CalibrationConfig",
    "CampaignConfig",
    "ColumnMap",
    "ConfigError",
    "DiscoveryConfig",
    "ExperimentConfig",
    "ReplayConfig",
    "RunConfig",
    "SweepConfig",
    "TrainConfig",
    "config_hash",
    "from_dict",
    "load_config",
    "load_toml",
    "to_dict",
]


@dataclass(frozen=True)
class CampaignConfig:
    """Where the flight-test campaign comes from.

    Attributes:
        path: campaign folder (data-contract §1). Empty: the embedded synthetic campaign.
        synthetic: generator config (TOML) for the embedded campaign; empty: the default
            campaign with the experiment's seed.
        columns: foreign column name -> `ColumnMap`, applied to counters.csv and time series.
    """

    path: str = ""
    synthetic: str = ""
    columns: dict[str, ColumnMap] = field(default_factory=dict)

    def __post_init__(self):
        targets = [m.to for m in self.columns.values()]
        dup = {t for t in targets if targets.count(t) > 1}
        if dup:
            raise ValueError(f"columns: several columns map to {sorted(dup)}")
        for src, m in self.columns.items():
            if m.to not in CANONICAL_UNITS and m.unit is not None:
                raise ValueError(f"columns.{src}: {m.to!r} is not a canonical channel")


@dataclass(frozen=True)
class AnalysisConfig:
    """Windowed harmonic analysis and peak extraction.

    Attributes:
        window_revs: window length L in rotor revolutions (paper: 8). Continuous.
        hop_revs: window start spacing in revolutions; 0 means consecutive windows (= L).
        harmonic: harmonic order k analysed (4 for the 4-bladed UH-60A: 4/rev).
        taper_revs: width of the raised-cosine window edges in revolutions; 0 gives the
            rectangular window (edges resolved to fractions of a sample).
        inputs: how a database row takes the flight state at the peak window: "mean"
            averages each channel over the window (the paper's replay inputs), "center"
            takes the instantaneous value at the window's center.
    """

    window_revs: float = 8.0
    hop_revs: float = 0.0
    harmonic: int = 4
    taper_revs: float = 0.0
    inputs: Literal["mean", "center"] = "mean"

    def __post_init__(self):
        if not self.window_revs > 0:
            raise ValueError(f"window_revs must be > 0, got {self.window_revs}")
        if self.hop_revs < 0:
            raise ValueError(f"hop_revs must be >= 0, got {self.hop_revs}")
        if self.harmonic < 1:
            raise ValueError(f"harmonic must be >= 1, got {self.harmonic}")
        if self.taper_revs < 0 or self.taper_revs >= self.window_revs:
            raise ValueError(f"taper_revs must be in [0, window_revs), got {self.taper_revs}")

    @property
    def hop(self) -> float:
        return self.hop_revs or self.window_revs


def _check_databases(section: str, databases, field: str = "databases"):
    bad = [d for d in databases if d not in ("db1", "db2", "db3")]
    if bad or not databases:
        raise ValueError(f"{section}.{field}: unknown {bad}; use db1, db2, db3")


@dataclass(frozen=True)
class TrainConfig:
    """Full-batch training of one net.

    Attributes:
        optimizer: "adam" (first order) or "lm" (Levenberg-Marquardt, second order).
        learning_rate: Adam step size.
        max_steps: optimizer steps at most.
        eval_every: steps between validation evaluations.
        patience: evaluations without a better validation RMS before stopping.
        weight_decay: decoupled weight decay (AdamW) when > 0.
        lm_damping: initial Levenberg-Marquardt damping λ.
        divergence_factor: a training loss above this multiple of the initial loss is divergence.
    """

    optimizer: Literal["adam", "lm"] = "adam"
    learning_rate: float = 3e-3
    max_steps: int = 6000
    eval_every: int = 50
    patience: int = 10
    weight_decay: float = 0.0
    lm_damping: float = 1e-2
    divergence_factor: float = 1e3

    def __post_init__(self):
        for name in ("learning_rate", "max_steps", "eval_every", "patience", "lm_damping", "divergence_factor"):
            if not getattr(self, name) > 0:
                raise ValueError(f"train.{name} must be > 0, got {getattr(self, name)}")
        if self.weight_decay < 0:
            raise ValueError(f"train.weight_decay must be >= 0, got {self.weight_decay}")


@dataclass(frozen=True)
class SweepConfig:
    """A family of nets trained together: databases × architectures × seeds × folds.

    Attributes:
        databases: which of db1, db2, db3.
        family: "mlp" (back-propagation nets) or "rbf" (radial-basis-function nets).
        hidden: MLP hidden-layer widths per architecture, e.g. [[10, 5], [15, 5]].
        centers: RBF centre counts per architecture.
        seeds: number of initialisation seeds (0 .. seeds-1).
        folds: k of the k-fold split by condition.
        test_folds: outer folds to run (empty: all k, so every condition is held out once).
        split_seed: seed of the assignment of conditions to folds.
        chunk_evals: evaluations per compiled chunk; finished nets leave the batch between chunks.
        cpu_devices: on CPU, expose this many host devices so that the net axis is sharded
            over the cores (0: one per core; 1: off). Applied by `pvvjax sweep` before JAX
            starts; results then depend on it (same config, seed and devices: same numbers).
    """

    databases: tuple[str, ...] = ("db1", "db2", "db3")
    family: Literal["mlp", "rbf"] = "mlp"
    hidden: tuple[tuple[int, ...], ...] = ((10, 5),)
    centers: tuple[int, ...] = (20,)
    seeds: int = 1
    folds: int = 5
    test_folds: tuple[int, ...] = ()
    split_seed: int = 0
    chunk_evals: int = 4
    cpu_devices: int = 0

    def __post_init__(self):
        if self.cpu_devices < 0:
            raise ValueError(f"sweep.cpu_devices must be >= 0, got {self.cpu_devices}")
        _check_databases("sweep", self.databases)
        if any(not h or min(h) < 1 for h in self.hidden):
            raise ValueError(f"sweep.hidden: every architecture needs widths >= 1, got {self.hidden}")
        if self.seeds < 1 or self.folds < 3 or self.chunk_evals < 1:
            raise ValueError("sweep.seeds must be >= 1, sweep.folds >= 3, sweep.chunk_evals >= 1")
        if any(not 0 <= f < self.folds for f in self.test_folds):
            raise ValueError(f"sweep.test_folds must lie in 0..{self.folds - 1}, got {self.test_folds}")

    @property
    def fold_list(self) -> tuple[int, ...]:
        return self.test_folds or tuple(range(self.folds))


TRANSIENT_MANEUVERS = ("pullup", "pushover", "roll", "autorotation", "flare")


def _bounds(name: str, b: tuple[float, float]):
    if len(b) != 2 or not b[0] < b[1]:
        raise ValueError(f"{name} must be [lo, hi] with lo < hi, got {list(b)}")


@dataclass(frozen=True)
class ReplayConfig:
    """Quasi-static replay of recorded counters through trained nets.

    Attributes:
        sweep: folder of the sweep whose nets are replayed ("": this config's own sweep,
            `<out_dir>/<name>/sweep`). Each counter is replayed by the nets that held its
            condition out, median over seeds.
        architecture: which architecture of the sweep ("": its only one).
        databases: which of db1, db2, db3.
        counters: counters to replay (empty: every counter of the `maneuvers` kinds).
        maneuvers: maneuver kinds replayed when `counters` is empty.
        offset_s: input-to-vibration offset τ, s (inputs precede the vibration when > 0).
        window_revs: window length L, revolutions (the paper: 8).
        stick_offset_s: extra offset of the three stick inputs, s.
        hop_revs: window spacing, revolutions (0: consecutive windows, as the paper).
    """

    sweep: str = ""
    architecture: str = ""
    databases: tuple[str, ...] = ("db1", "db2", "db3")
    counters: tuple[str, ...] = ()
    maneuvers: tuple[str, ...] = TRANSIENT_MANEUVERS
    offset_s: float = 0.0
    window_revs: float = 8.0
    stick_offset_s: float = 0.0
    hop_revs: float = 0.0

    def __post_init__(self):
        _check_databases("replay", self.databases)
        if not 1.0 <= self.window_revs <= 64.0:
            raise ValueError(f"replay.window_revs must be in [1, 64], got {self.window_revs}")
        if self.hop_revs < 0:
            raise ValueError(f"replay.hop_revs must be >= 0, got {self.hop_revs}")


@dataclass(frozen=True)
class CalibrationConfig:
    """Gradient calibration of offset, window length and stick lag (see `pvvjax.replay.calibration`).

    Attributes:
        free: parameters fitted: any of offset_s, window_revs, stick_offset_s.
        groups: one θ for "all" counters, one per "maneuver" kind, or one per "counter".
        offset_bounds, window_bounds, stick_offset_bounds: [lo, hi] of each parameter
            (s, revolutions, s).
        hop_revs: window spacing of the calibration replays (finer than L resolves the
            peak time better than the paper's consecutive windows).
        reference_revs: length of the measured PVV windows (0: the fitted window length,
            shared by inputs and vibration as in the paper; > 0: fixed reference windows,
            and the window length is that of the input averaging only).
        coarse_offset_step_s, coarse_window_step_revs, coarse_stick_step_s: the coarse
            grid whose best point starts each solve.
        grid_offset_step_s, grid_window_step_revs: the brute-force grid reported beside
            the gradient optimum (0: no grid).
        peak_weight, phase_weight, rms_weight, peak_scale_g, phase_scale_s, temperature_g,
            phase_cap_s: the cost (`replay.CostWeights`).
        max_steps: Levenberg-Marquardt steps at most.
    """

    free: tuple[str, ...] = ("offset_s", "window_revs")
    groups: Literal["all", "maneuver", "counter"] = "all"
    offset_bounds: tuple[float, float] = (-1.0, 3.0)
    window_bounds: tuple[float, float] = (4.0, 16.0)
    stick_offset_bounds: tuple[float, float] = (-2.0, 2.0)
    hop_revs: float = 1.0
    reference_revs: float = 0.0
    coarse_offset_step_s: float = 0.25
    coarse_window_step_revs: float = 2.0
    coarse_stick_step_s: float = 0.5
    grid_offset_step_s: float = 0.1
    grid_window_step_revs: float = 0.5
    peak_weight: float = 1.0
    phase_weight: float = 1.0
    rms_weight: float = 1.0
    peak_scale_g: float = 0.02
    phase_scale_s: float = 1.0
    temperature_g: float = 0.005
    phase_cap_s: float = 3.0
    max_steps: int = 64

    def __post_init__(self):
        params = ("offset_s", "window_revs", "stick_offset_s")
        bad = [f for f in self.free if f not in params]
        if bad or not self.free or len(set(self.free)) != len(self.free):
            raise ValueError(f"calibration.free: unknown or repeated {bad or list(self.free)}; use {list(params)}")
        _bounds("calibration.offset_bounds", self.offset_bounds)
        _bounds("calibration.window_bounds", self.window_bounds)
        _bounds("calibration.stick_offset_bounds", self.stick_offset_bounds)
        if self.window_bounds[0] < 1.0:
            raise ValueError(f"calibration.window_bounds must start at >= 1 revolution, got {self.window_bounds[0]}")
        for name in ("hop_revs", "coarse_offset_step_s", "coarse_window_step_revs", "coarse_stick_step_s",
                     "peak_scale_g", "phase_scale_s", "temperature_g", "max_steps"):
            if not getattr(self, name) > 0:
                raise ValueError(f"calibration.{name} must be > 0, got {getattr(self, name)}")
        for name in ("grid_offset_step_s", "grid_window_step_revs", "peak_weight", "phase_weight", "rms_weight",
                     "phase_cap_s", "reference_revs"):
            if getattr(self, name) < 0:
                raise ValueError(f"calibration.{name} must be >= 0, got {getattr(self, name)}")


@dataclass(frozen=True)
class DiscoveryConfig:
    """The discovery workflow (see `pvvjax.discovery`).

    Attributes:
        database: the model's database (db1, db2 or db3).
        hidden: hidden-layer widths of its nets.
        seeds: training seeds of the ensemble; metrics are medians over seeds.
        folds: k of the k-fold split by condition (every counter is replayed by the nets that
            held its condition out).
        split_seed: seed of the assignment of conditions to folds.
        hop_revs: spacing of the replay windows, revolutions.
        calibrate_offset: fit the input-to-vibration offset on the held-out windows (else
            use `offset_s`).
        offset_s: the offset when it is not calibrated, s.
        offset_bounds: [lo, hi] of the offset grid, s; offset_step_s: its step.
        max_effects: effects added at most (0: the baseline and its residual map only).
        proposals: significant candidates tried (in rank order) per round.
        alpha: significance level of the permutation test; permutations: its permutations.
        min_gain: smallest relative drop of the held-out (by condition) residual error a
            candidate must bring to be proposed.
        parsimony: once the best candidate is significant, name the simplest candidate
            (fewest operators and fitted parameters) whose held-out error is within this many
            standard errors of the best's (0: always the best).
        min_shrink: smallest relative drop of the held-out RMS of the ensemble's prediction
            (median over seeds), where the effect acts, that confirms it after retraining; or
            twice this over all windows, wherever the drop lies (`discovery._confirm._confirm`).
        shrink_noise: confirmed tries of a round whose shrinks (over all windows) are within
            this of the best are tied with it, as are those it does not beat at p < `alpha`
            (a sign-flip test by condition); of tied tries, the one the selection credits with
            the largest gain is named, those that lower the RMS by `min_shrink` over all
            windows on top of their floor control first (`discovery._confirm._choose`). Also the
            rise of the RMS over all windows a try may cause on its floor control where it
            gains twice `min_shrink` where it acts (`discovery._confirm._floor_control`).
        tie_share: a try not beaten at p < `alpha` is tied only if its shrink is at least
            this share of the best's (within `shrink_noise` it is tied regardless): the
            sign-flip test by condition measures how consistently the best wins, not by
            how much, and an effect of a few conditions cannot win consistently over many
            (`discovery._confirm._choose`).
        floor_refinements: knees and products of the model's own inputs that join each
            selection's floor covariates before any candidate is asked, the best first while it
            gains `min_gain` (`discovery._propose._propose`): the map's floor where ~200 peaks did not
            teach the nets a knee of their own inputs, which a channel that follows them (a
            stick, the shaft power) would otherwise be named for. 0: the fixed floor only.
        floor_control: a try that confirms against the current model must confirm again,
            added the same way, against a control: the current model retrained with the
            refinements its round's selection took over all windows as extra network inputs
            (the floor's own model, in which the nets may combine them, e.g. a climb-rate
            knee with the speed), less those built from the channels the try is built from
            (`discovery._confirm._floor_control`, `_control_refinements`; one more retraining
            per confirmed try, and one per distinct control). A try that fails there is still
            confirmed if its own model beats the control as a confirmation would (a floor
            proxy does not beat the floor it stands for). On by default (the benchmark's 77
            worlds, docs/discovery-studies.md); off: the current model alone.
        augment: how a candidate joins the model: "additive" (a term b·candidate fitted on the
            windows, cross-fitted by fold, the nets retrained on the peaks minus it),
            "input" (an extra network input: the nets learn its shape and its interactions),
            or "auto" (both; which is kept: `augment_tie`). A lag is always a
            learned lag of the replay, a resonance a learned gain on the nets' output.
        augment_tie: with "auto", which way of the named proposal is kept: "additive" (its
            term wherever the term ties with the input as `_choose` ties tries, confirmed on
            its own or not) or "shrink" (the way that lowered the RMS more, the rule of the
            benchmark's table). The round has confirmed the effect; how to add it is a choice
            between two fits, and one training's shrink is one draw of it: a term is two
            numbers per fold fitted on every window, an input is learned anew by each
            training on ~200 peaks; tied, the term is the smaller model. Over eight
            training draws the term's held-out RMS is the lower on the five benchmark worlds
            of the config's seeds (by 2.2 ± 0.4 mg on average), and on the five worlds
            where the rule changes the way by 0.5 ± 0.4 mg (pitch rate 51's attributable
            shrink 0.29 → 0.62), docs/discovery-studies.md "A term or an input, over training draws".
        term_refit: what an additive term is refitted on after the nets are retrained on the
            peaks minus its first fit: "peaks" (the residual of those nets) or "windows" (of
            nets trained on every `train_stride`-th replay window minus it, about 25 times
            the rows: the peak nets learn part of an effect through the inputs it moves with,
            the load factor for |q̇|, and their residual holds the term's coefficient short);
            the peak nets are then retrained on the peaks minus the refitted term. Every try
            refitted so lifts the benchmark's pitch families but names the load factor on two
            of its null worlds (docs/discovery-studies.md, "A term refitted on window nets"), so
            "named" refits the tries on the peaks (which tries confirm, and which one a round
            names, are those of "peaks") and refits only the named term on window nets, kept
            where that model confirms too: the default since 2026-11-27. Single draws could
            not tell it from "peaks" (on 34 benchmark worlds the attributable shrink rose on
            13 and fell on 18; on six fresh seeds it fell on four). Over eight training draws
            of eight worlds its held-out RMS is lower by 0.4 ± 0.2 mg on average (lower on
            seven), fresh seeds included, and its coefficients are closer to the generator's
            (roll rate 4 / 4, pitch acceleration 4 / 5 on the table), docs/discovery-studies.md "The
            named term refitted on window nets". Cost: one training on the windows per named
            term.
        encompassing: of the named try and the tries tied with it (as `_choose` ties them) on
            other source channels, both confirmed as additive terms, name the rival where its
            term keeps a larger share of its own coefficient when fitted on top of the named's
            model than the named's term keeps on top of the rival's, by more than
            `encompassing_margin` (`_round._kept_on_top`: the other's model with it added,
            retrained). A term the other explains keeps about none. On since 2026-11-27:
            offline it favours the truth in 11 of 12 cross-channel ties of the benchmark's
            table and seeds + 15 (15 of 16 training draws); inside the workflow it names |p|
            where roll rate 56 named |ṙ| (the coordinated turn's |ṙ| is |p| weighted by
            sec²φ / V), and on the table's 9 rounds with a pair to measure it keeps every
            name (docs/discovery-studies.md, "The encompassing test on the table"). Cost: two
            retrainings per tied pair.
        encompassing_margin: how much more of its coefficient (a share) the rival's term must
            keep than the named's for the rival to be named. Two forms of one signal (|p| and
            the roll angle's rate) keep about the same, and which keeps more is the
            retraining's noise: over four training draws of one pair the difference moved
            from −0.05 to +0.06 (collective stall 56), where |p| over |ṙ| kept 0.36–0.48
            more. Without it the table's pitch rate 55 traded |q| for the pitch attitude's
            rate on 0.11 against 0.06, its attributable shrink 0.71 → 0.52.
        selection_stride: every n-th window of a counter enters the selection.
        local_selection: also run the selection inside each maneuver kind where the residual
            concentrates (Bonferroni over the subsets). Off by default: on the benchmark's
            null worlds it names floor structure of single kinds (a collective knee in
            descents), see docs/discovery-benchmark.md.
        min_subset_conditions: conditions a maneuver kind needs for a selection of its own.
        lag_taus: time constants of the lag candidates, s (the chosen one is refined; a lag
            fitted at the largest is a smoother, not confirmed).
        knee_quantiles: quantiles of a channel where threshold candidates put their knee.
        exclude_channels: channels never used as candidates.
        train_rows: what the nets train on: "peaks" (each condition's peak row of the
            database, the paper's map) or "windows" (every `train_stride`-th fully weighted
            replay window of each counter, at the model's offset: the map of the whole
            maneuvers, a lower error floor).
        train_stride: see `train_rows` (8: adjacent windows of 8 revolutions at a hop of 1,
            which overlap by nothing and carry the whole measured series at that resolution;
            the lag test's trainings use it too).
        lag_test: before the first round, test for a slow lag (`discovery._lag._lag_test`):
            window nets on the flight state (db1's inputs, whatever the database) and a lag
            of learnable τ between them and the measured PVV, trained jointly at the lowest
            offset, judge it (`lag_slow_s`); window nets trained through
            lags of `lag_test_taus` (up to six trainings) add a confirmed lag, which is the
            first effect, and every later model trains through it. Either way the rounds
            then propose no lag of the prediction: the test decided.
        lag_test_taus: time constants the lag test trains through, s (> 0; at least one
            above `lag_fast_s`).
        lag_fast_s: the fast dynamics every world has (rotor inflow and wake settle within
            about a second): lags up to this count as the lag test's reference, not as a
            discovery.
        lag_slow_s: the learned τ (median over folds × seeds) from which the lag test
            confirms a slow lag, s. The learned τ takes the delay and the fast dynamics as
            well: 0.9-1.9 s on the benchmark's worlds without a slow lag (the largest, 1.85 s,
            on a pitch-acceleration world), 2.6-3.2 s with a 2 s lag.
        lag_learn_steps: Adam steps of the learned lag's training.
        lag_trials_always: run the lag test's trainings through lags even where the learned
            τ confirms no lag: they decide nothing then (their gains are reported in
            `lag_test.csv`), and they are about
            half of a discovery's time with `lag_test` (the benchmark runs them on the null
            worlds whose window nets measure its lag worlds' gap).
        candidate_offsets_s: further alignments (input-to-vibration offsets, s, >= 0) of the
            candidates without a fitted parameter (a channel, its rate, its spread), beside
            the model's own offset: the static map's offset matches the slow, quasi-static
            changes, and a transient effect reaches the vibration through the faster rotor
            response (about 0.5 s).
        resonance_probe: in a round that proposes no resonance, train the nets once with a
            learned gain on every rotor-speed band of the grid at once and propose the band
            of the largest gain as a resonance (retrained as a gain; the confirmation decides).
            A mode the nets learned as a mean per rotor-speed level leaves a residual no
            prediction × band column explains (`docs/discovery-studies.md`). Only for nets trained on
            the peaks: window nets (after a confirmed lag, or `train_rows = "windows"`)
            under-learn the lowest rotor speed, and a band there confirmed on two of three
            long-lag worlds. Off by default.
        band_shape: the resonance bands' shape (`effects.band`): "gaussian", or "lorentzian",
            the line shape of a lightly damped mode. Rotor speed is flown at a few settings
            ~2.5 % apart, wider than a mode's band, so the band's tails decide what it predicts
            at the settings next to the mode: a Gaussian's vanish there, a mode's do not.
        resonance_input: also try a resonance band as an extra network input, beside its
            gain on the nets' output (the better confirmed try is kept, as for `augment =
            "auto"`). Where the nets already learned most of a mode through rotor speed, what
            is left is not proportional to their prediction, and a gain cannot undo it.
        gain_unit: the unit, 1 / gain_unit, in which the nets train the gain of a resonance
            band that the selection proposed (its permutation test found the magnification
            in the residual): Adam moves every parameter by about one step, and in unit steps
            the nets' many weights take the mode's top rotor-speed level additively before the
            one gain grows (learned 0.6-0.7, the truth ~1.2). The resonance probe's band, a
            forced guess without a test, trains in unit steps (1): in steps of 10 it confirms a
            band on a world without a mode (`docs/discovery-studies.md`).
        probe_alpha: the probe's band confirms only if its retraining predicts better where
            the band acts at this level (`discovery._propose._probe_test`, by condition): the
            band is a forced guess, and its shrink alone confirmed bands on worlds without a
            mode (p 0.41 and 0.80; the modes measured scored 0.018 and 0.029, so `alpha` would
            reject them).
        source_tries: how many candidates built only from the campaign channels the model's
            derived inputs are computed from, but that it does not take itself (for db1, the
            load factor's roll angle and pitch rate), a round also tries beside its
            proposals. It takes the best by the selection's held-out gain, if above 0. The nets
            learn part of such an effect through the derived input, and on the residual the
            rest can point the other way: on pitch rate 57, |q| is not proposed, yet, tried, it
            is named and closes the gap (`docs/discovery-studies.md`). 0 (none) by default.
    """

    database: str = "db1"
    hidden: tuple[int, ...] = (10, 5)
    seeds: int = 4
    folds: int = 5
    split_seed: int = 0
    hop_revs: float = 1.0
    calibrate_offset: bool = True
    offset_s: float = 0.0
    offset_bounds: tuple[float, float] = (0.0, 3.0)
    offset_step_s: float = 0.1
    max_effects: int = 3
    proposals: int = 3
    alpha: float = 0.01
    permutations: int = 99
    min_gain: float = 0.02
    parsimony: float = 1.0
    min_shrink: float = 0.05
    shrink_noise: float = 0.02
    tie_share: float = 0.5
    floor_refinements: int = 4
    floor_control: bool = True
    augment: Literal["additive", "input", "auto"] = "auto"
    augment_tie: Literal["shrink", "additive"] = "additive"
    term_refit: Literal["peaks", "windows", "named"] = "named"
    encompassing: bool = True
    encompassing_margin: float = 0.1
    selection_stride: int = 4
    local_selection: bool = False
    min_subset_conditions: int = 20
    lag_taus: tuple[float, ...] = (0.25, 0.5, 1.0, 1.5, 2.0, 3.0)
    knee_quantiles: tuple[float, ...] = (0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95)
    exclude_channels: tuple[str, ...] = ()
    train_rows: Literal["peaks", "windows"] = "peaks"
    train_stride: int = 8
    lag_test: bool = False
    lag_test_taus: tuple[float, ...] = (1.0, 2.0, 3.0)
    lag_fast_s: float = 1.0
    lag_slow_s: float = 2.0
    lag_learn_steps: int = 2000
    lag_trials_always: bool = False
    candidate_offsets_s: tuple[float, ...] = (0.5,)
    resonance_probe: bool = False
    band_shape: Literal["gaussian", "lorentzian"] = "gaussian"
    resonance_input: bool = False
    gain_unit: float = 10.0
    probe_alpha: float = 0.05
    source_tries: int = 0

    def __post_init__(self):
        _check_databases("discovery", (self.database,), "database")
        if (min(self.lag_test_taus, default=0.0) <= 0 or max(self.lag_test_taus, default=0.0) <= self.lag_fast_s
                or self.lag_fast_s < 0):
            raise ValueError(f"discovery.lag_test_taus must be > 0 with at least one above discovery.lag_fast_s "
                             f"({self.lag_fast_s}), got {list(self.lag_test_taus)}")
        _bounds("discovery.offset_bounds", self.offset_bounds)
        if any(not v >= 0 for v in self.candidate_offsets_s):
            raise ValueError(f"discovery.candidate_offsets_s must be >= 0 s, got {list(self.candidate_offsets_s)}")
        if not self.hidden or min(self.hidden) < 1:
            raise ValueError(f"discovery.hidden needs widths >= 1, got {list(self.hidden)}")
        if self.parsimony < 0:
            raise ValueError(f"discovery.parsimony must be >= 0 (standard errors), got {self.parsimony}")
        if self.floor_refinements < 0:
            raise ValueError(f"discovery.floor_refinements must be >= 0, got {self.floor_refinements}")
        if self.source_tries < 0:
            raise ValueError(f"discovery.source_tries must be >= 0, got {self.source_tries}")
        if not self.encompassing_margin >= 0:
            raise ValueError(f"discovery.encompassing_margin must be >= 0 (a share), got {self.encompassing_margin}")
        if self.max_effects < 0:
            raise ValueError(f"discovery.max_effects must be >= 0 (0: baseline and residual map only), "
                             f"got {self.max_effects}")
        if self.min_subset_conditions < self.folds:
            raise ValueError(f"discovery.min_subset_conditions must be >= folds ({self.folds}), "
                             f"got {self.min_subset_conditions}")
        if not self.lag_slow_s > 0:
            raise ValueError(f"discovery.lag_slow_s must be > 0 s, got {self.lag_slow_s}")
        for name in ("seeds", "proposals", "selection_stride", "permutations", "train_stride", "lag_learn_steps"):
            if getattr(self, name) < 1:
                raise ValueError(f"discovery.{name} must be >= 1, got {getattr(self, name)}")
        if self.folds < 3:
            raise ValueError(f"discovery.folds must be >= 3, got {self.folds}")
        for name in ("hop_revs", "offset_step_s", "gain_unit"):
            if not getattr(self, name) > 0:
                raise ValueError(f"discovery.{name} must be > 0, got {getattr(self, name)}")
        for name in ("alpha", "probe_alpha"):
            if not 0 < getattr(self, name) < 1:
                raise ValueError(f"discovery.{name} must lie in (0, 1), got {getattr(self, name)}")
        for name in ("min_gain", "min_shrink", "shrink_noise"):
            if not 0 <= getattr(self, name) < 1:
                raise ValueError(f"discovery.{name} must lie in [0, 1), got {getattr(self, name)}")
        if not 0 <= self.tie_share <= 1:
            raise ValueError(f"discovery.tie_share must lie in [0, 1], got {self.tie_share}")
        if not self.lag_taus or min(self.lag_taus) <= 0:
            raise ValueError(f"discovery.lag_taus must be > 0, got {list(self.lag_taus)}")
        if any(not 0 < q < 1 for q in self.knee_quantiles):
            raise ValueError(f"discovery.knee_quantiles must lie in (0, 1), got {list(self.knee_quantiles)}")


@dataclass(frozen=True)
class RunConfig:
    """What the main job (`pvvjax run`) does beyond campaign, databases and figures.

    Attributes:
        networks: train the config's `[sweep]` (resumable) and report Figs 10-12 and Table 1
            beside the paper.
        replay: with `networks`, fit the offset on every transient maneuver ([replay]
            maneuvers, [calibration]) and replay the pull-up 11022 (Figs 13-14).
        studies: with `replay`, the studies the paper left open: one offset per maneuver
            kind, the window length (gradient and brute-force grid) and a stick lag.
        discovery_scenario: a generator config (TOML) whose campaign hides an effect; the
            main job runs the discovery workflow on it ("": no discovery stage).
        html: also write report.html beside report.md.
    """

    networks: bool = False
    replay: bool = True
    studies: bool = True
    discovery_scenario: str = ""
    html: bool = True


@dataclass(frozen=True)
class ExperimentConfig:
    """One experiment: a campaign and the pipeline settings applied to it."""

    name: str = "experiment"
    out_dir: str = "runs"
    seed: int = 0
    campaign: CampaignConfig = field(default_factory=CampaignConfig)
    analysis: AnalysisConfig = field(default_factory=AnalysisConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    sweep: SweepConfig = field(default_factory=SweepConfig)
    replay: ReplayConfig = field(default_factory=ReplayConfig)
    calibration: CalibrationConfig = field(default_factory=CalibrationConfig)
    discovery: DiscoveryConfig = field(default_factory=DiscoveryConfig)
    run: RunConfig = field(default_factory=RunConfig)

    def with_(self, **changes) -> "ExperimentConfig":
        return dataclasses.replace(self, **changes)


def load_toml(path: str | Path) -> dict:
    """Read a TOML file; a syntax error names the file."""
    path = Path(path)
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such config file") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: not valid TOML: {e}") from None


def load_config(path: str | Path, cls: type = ExperimentConfig):
    """Load and validate a TOML config into the frozen dataclass `cls`.

    Raises:
        ConfigError: naming the file and the offending key.
    """
    return _validated(path, load_toml(path), cls)


def _validated(path, data: dict, cls: type):
    try:
        return from_dict(cls, data)
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from None


# Settings added after results were written, each at the value that reproduces those results:
# left out of `config_hash` at that value, so that tables written before the setting existed
# still compare equal to a config that leaves it there (`--resume`, `--update` of the benchmark).
_ADDED_LATER = {"discovery": {"encompassing": False, "encompassing_margin": 0.0, "source_tries": 0}}


def load_written_config(path: str | Path, cls: type = ExperimentConfig):
    """`load_config` for a config a run wrote beside its results: a setting of `_ADDED_LATER`
    that it lacks was written before the setting existed, so it takes its earlier
    behaviour's value, not today's default."""
    data = load_toml(path)
    for section, added in _ADDED_LATER.items():
        if isinstance(data.get(section), dict):
            data = {**data, section: {**added, **data[section]}}
    return _validated(path, data, cls)


def config_hash(cfg) -> str:
    """A short stable hash of a config's content (for result tables and caches); a setting of
    `_ADDED_LATER` at its earlier behaviour's value is left out."""
    d = to_dict(cfg)
    for section, added in _ADDED_LATER.items():
        if isinstance(d.get(section), dict):
            d = {**d, section: {k: v for k, v in d[section].items() if not (k in added and v == added[k])}}
    blob = json.dumps(d, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:12]
