"""The discovery workflow: its context, `discover` and the data-contract §3 summary."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pandas as pd

from .._timing import Stopwatch
from ..analysis.databases import DB_INPUTS, STATE_CHANNELS, build_databases
from ..config import DiscoveryConfig, ExperimentConfig
from ..data.batch import to_batch
from ..data.campaign import Campaign, load_campaign
from ..nets import train as _train
from ..replay.quasistatic import make_settings, prepare
from . import _rules
from ._confirm import _train_model
from ._fits import _fit_offset
from ._lag import _lag_round, _lag_test, _table_row
from ._model import (
    Model,
    _Ctx,
    _lag_windows,
    _replay,
    _selection_column,
    _Windows,
    floor_features,
    metrics,
    predictions,
)
from ._propose import (
    _candidate_matrix,
    _floor,
    _neighbour_cells,
    _propose,
    _resonance_probe,
    _source_tries,
    _unaligned_key,
)
from ._results import Effect, Round
from ._round import TRY_COLUMNS, _Round
from .candidates import Candidate, sample_series, window_table
from .residuals import localize
from .selection import gain as _selection_gain


class Residual(NamedTuple):
    """A round's selection design: the residual (measured − predicted, per window), the
    windows that enter the selection, the floor covariates on those windows, the condition
    of each window, and the folds and seed of the split."""

    residual: np.ndarray
    rows: np.ndarray
    floor: np.ndarray
    groups: np.ndarray
    folds: int
    seed: int


@dataclass(frozen=True)
class Discovery:
    """The outcome of `discover` (`summary` turns it into data-contract §3).

    Attributes:
        campaign: path or name. database: the model's database.
        baseline, final: the baseline and the final (augmented) `Model`.
        before, after: their held-out metrics (`metrics`: medians over seeds, `rms_by_seed`
            per seed, `ensemble_rms_g` of the median prediction).
        effects: the confirmed effects (`Effect`), in the order named.
        tries: every tried proposal of every round (a table, one row per proposal and way).
        rounds: the rounds (`Round`): each one's tries and the effect it named.
        localized: `residuals.localize` tables of the baseline.
        windows: the baseline replay windows with `predicted_before_g`, `predicted_after_g` and
            `effect_<rank>`, each effect's column as the selection saw it (a resonance times
            the prediction, a lag as the lagged minus the plain prediction).
        seconds: wall time per stage.
        residual: the first round's selection design (`Residual`), for `selection_gain`.
        lag_test: with `lag_test`, one row per ensemble of the test (`_lag_test`): tau_s,
            train_offset_s, offset_s (refitted), ensemble_rms_g, rms_g, peak_error_g,
            phase_error_s, role (reference or slow; a first row "baseline": the peak nets the test
            started from, a second "learned": the lag learned inside one training, with its
            tau_s the median and tau_min_s, tau_max_s the range over folds × seeds), drop
            (against the reference), chosen. The trainings through lags (reference, slow)
            only where a lag was confirmed or with `discover(..., lag_trials=True)`.
    """

    campaign: str
    database: str
    baseline: Model
    final: Model
    before: dict
    after: dict
    effects: tuple[Effect, ...]
    tries: pd.DataFrame
    localized: dict
    windows: pd.DataFrame
    seconds: dict
    residual: Residual | None = None
    lag_test: pd.DataFrame | None = None
    rounds: tuple[Round, ...] = ()


def _with_baseline_row(table: pd.DataFrame, offset_s: float, m: dict, reference_rms: float) -> pd.DataFrame:
    """The lag test's table with a first row for the nets the test started from (role
    "baseline": the peak nets at their offset, no lag; `m` their `metrics`), so that a
    campaign whose lag test confirmed still reports the plain baseline that campaigns without
    a lag are measured by."""
    row = _table_row(np.nan, np.nan, offset_s, m) | dict(
        role="baseline", drop=1.0 - m["ensemble_rms_g"] / reference_rms, chosen=False)
    return pd.concat([pd.DataFrame([row]), table], ignore_index=True)


def selection_gain(res: Discovery, values) -> float:
    """The held-out gain the first round's selection would credit a per-window column with
    (`selection.gain`: the same residual, floor covariates, rows and folds): e.g. the true
    per-window effect of a synthetic campaign, to ask whether the baseline's residual could
    have named it at all, or a candidate, to compare with the one named.

    Args:
        res: a `Discovery` with at least one round (`max_effects` ≥ 1).
        values: (n,) one value per row of `res.windows` (the baseline's windows).

    Returns:
        The relative drop of the held-out squared error.
    """
    e = res.residual
    if e is None:
        raise ValueError("selection_gain: the discovery ran no round (max_effects = 0)")
    v = np.asarray(values, float)
    if v.shape != e.residual.shape or not np.all(np.isfinite(v[e.rows])):
        raise ValueError(f"selection_gain: values must be {e.residual.shape[0]} finite numbers, one per window "
                         f"of res.windows; got shape {v.shape}")
    return _selection_gain(e.residual[e.rows], v[e.rows], e.groups[e.rows], base=e.floor, folds=e.folds, seed=e.seed)


def _context(campaign: Campaign, cfg: ExperimentConfig, log) -> _Ctx:
    d = cfg.discovery
    dbs = build_databases(campaign, cfg.analysis)
    db = dbs[d.database]
    source = campaign.source or "<memory>"  # for the errors below
    folds = _train.condition_folds(db.condition, d.ensemble.folds, d.ensemble.split_seed,
                                   f"discovery.ensemble.folds (campaign {source}, "
                                   f"{d.database})")
    fold_of = dict(zip(db.condition, folds))
    info = campaign.counters.loc[:, ["maneuver", "condition"]]
    info = info[info.condition.isin(fold_of)]
    if d.exclude_channels:  # a misspelt channel would silently stay a candidate
        known = sample_series(campaign.records[info.index[0]], campaign.aircraft)
        unknown = sorted(set(d.exclude_channels) - set(known))
        if unknown:
            raise ValueError(f"discovery.exclude_channels: {unknown} are not candidate channels of campaign "
                             f"{source} (channels and derived features: {sorted(known)})")
    batch = to_batch(campaign, STATE_CHANNELS, list(info.index), axis=cfg.analysis.axis)
    recs = prepare(batch, harmonic=cfg.analysis.harmonic or campaign.aircraft.blades)
    L = cfg.analysis.window_revs
    lo, hi = d.offset.bounds if d.offset.calibrate else (min(0.0, d.offset.fixed_s), max(0.0, d.offset.fixed_s))
    settings = make_settings(batch, max_window_revs=L, min_window_revs=L, hop_revs=_rules.HOP_REVS,
                             offset_bounds=(float(min(lo, 0.0)), float(max(hi, 0.0))))
    # Each database row's peak window (zero offset), where extra inputs are taken for training.
    rows, row_of = [], {c: i for i, c in enumerate(info.index)}
    for r in db.itertuples():
        rec = campaign.records[r.counter]
        m = np.asarray(batch.mask[row_of[r.counter]])
        rev = np.asarray(batch.rev[row_of[r.counter]])[m]
        t = rec.time_s.to_numpy()
        mid = np.interp(r.peak_time_s, t, rev)
        rows.append((r.counter, np.interp(mid - L / 2, rev, t), np.interp(mid + L / 2, rev, t)))
    train_iv = pd.DataFrame(rows, columns=["counter", "t0", "t1"])
    log(f"discovery: {d.database} on {len(db)} conditions, {len(info)} counters replayed "
        f"({d.ensemble.folds}-fold by condition x {d.ensemble.seeds} seeds)")
    return _Ctx(campaign, cfg, db, db[list(DB_INPUTS[d.database])].to_numpy(np.float64), folds, info,
                np.array([fold_of[c] for c in info.condition]), batch, recs, settings,
                window_table(campaign, train_iv, d.exclude_channels), replay_params={})


def _public_parameters(c: Candidate) -> dict:
    p = dict(c.parameters)
    p.pop("softness", None)
    p.pop("gain_unit", None)  # how the gain was trained, not a parameter of the effect
    return p


def _workflow_inputs(caller: str, campaign, cfg, name: str = "") -> tuple[Campaign, ExperimentConfig, str]:
    """(campaign, config, name) from what a caller may pass: a campaign or its folder (loaded
    as the CLI loads it; the folder names it), an ExperimentConfig or a bare DiscoveryConfig."""
    if isinstance(cfg, DiscoveryConfig):
        cfg = ExperimentConfig(discovery=cfg)
    elif not isinstance(cfg, ExperimentConfig):
        raise TypeError(f"{caller}: cfg must be an ExperimentConfig or a DiscoveryConfig, got {type(cfg).__name__}")
    if isinstance(campaign, (str, os.PathLike)):
        name = name or str(campaign)
        campaign = load_campaign(campaign, cfg.campaign.columns, cfg.analysis.window_revs,
                                 harmonic=cfg.analysis.harmonic)
    elif not isinstance(campaign, Campaign):
        raise TypeError(f"{caller}: campaign must be a Campaign or a campaign folder, got {type(campaign).__name__}")
    return campaign, cfg, name


class _Baseline(NamedTuple):
    """The model discovery starts from, with its replay windows, predictions (seeds ×
    windows) and `metrics`; `lag`: the lag test's outcome, where it ran."""

    model: Model
    win: _Windows
    pred: np.ndarray
    before: dict
    lag: dict | None


def discover(campaign: Campaign | str | os.PathLike, cfg: ExperimentConfig | DiscoveryConfig = ExperimentConfig(), *,
             name: str = "", log=print, lag_trials: bool = False) -> Discovery:
    """Run the discovery workflow on a campaign: the baseline (and the lag test), where its
    residual lies, then rounds of explain, add and confirm (see the package docstring).

    Args:
        campaign: any campaign in the data-contract format, loaded or its folder.
        cfg: experiment config (`analysis`, `train` and `discovery` sections), or only the
            `DiscoveryConfig` (the other sections at their defaults).
        name: the campaign's path or name, for the summary (default: the folder given).
        log: progress messages.
        lag_trials: with the lag test on, train the window nets through lags even where the
            learned lag confirms none: they decide nothing then, but their gains (in
            `Discovery.lag_test`) measure what a lag would close on this campaign.

    Returns:
        `Discovery`.
    """
    campaign, cfg, name = _workflow_inputs("discover", campaign, cfg, name)
    clock = Stopwatch()
    with clock("prepare"):
        ctx = _context(campaign, cfg, log)
    base = _baseline(ctx, clock, log, lag_trials)
    localized = _localized(ctx, base, log)
    effects, rounds, final, first = _rounds(ctx, base, clock, log)
    return _outcome(ctx, name or str(campaign.source), base, final, effects, rounds, localized, clock.seconds, first,
                    log)


def _baseline(ctx: _Ctx, clock: Stopwatch, log, lag_trials: bool) -> _Baseline:
    """Peak nets of the database, trained k-fold by condition (they calibrate the replay), at
    the offset fitted on their held-out windows; with the lag test, its reference where it
    confirmed a slow lag (before/after then measures the lag)."""
    d = ctx.cfg.discovery
    inputs = tuple(DB_INPUTS[d.database])
    with clock("train_baseline"):
        ctx.replay_params = _train_model(ctx, Model({}, inputs), rows="peaks")
    with clock("offset_and_replay"):
        model = _fit_offset(ctx, Model(ctx.replay_params, inputs), with_lag=False)
        win = _replay(ctx, model.offset_s)
        pred = predictions(ctx, model, win)
        before = metrics(pred, win)
    lag = None
    if d.lag_test.enabled and d.max_effects > 0:
        with clock("lag_test"):
            lag = _lag_test(ctx, model.offset_s, log, always_trials=lag_trials)
            reference_rms = lag["reference"]["ensemble_rms_g"] if lag["reference"] else np.nan
            lag["table"] = _with_baseline_row(lag["table"], model.offset_s, before, reference_rms)
            if lag["confirmed"]:
                model = lag["reference"]["model"]
                win = _replay(ctx, model.offset_s)
                pred = predictions(ctx, model, win)
                before = metrics(pred, win)
    log(f"baseline {d.database}: offset {model.offset_s:.2f} s, held-out RMS {before['rms_g']:.4f} g, peak error "
        f"{before['peak_error_g']:.4f} g, phase error {before['phase_error_s']:.2f} s")
    return _Baseline(model, win, pred, before, lag)


def _localized(ctx: _Ctx, base: _Baseline, log) -> dict:
    """Where the baseline's residual lies (`residuals.localize`), on its full windows."""
    full = base.win.table.weight.to_numpy() >= 0.999
    windows = base.win.table.assign(database=ctx.cfg.discovery.database, predicted_g=np.median(base.pred, axis=0))
    localized = localize(windows[full])
    log("residual by maneuver (share of the squared residual): " + ", ".join(
        f"{k} {v:.0%}" for k, v in localized["maneuver"].share_sq.head(4).items()))
    return localized


def _rounds(ctx: _Ctx, base: _Baseline, clock: Stopwatch, log) -> tuple[list, list, Model, Residual | None]:
    """The effects named, the rounds table's rows, the final model and the first round's
    selection design: the lag test's round, then rounds of explain (`_explain`) and add and
    confirm (`_Round.name`) until nothing confirms or `max_effects`."""
    d = ctx.cfg.discovery
    effects, rounds, used, first = [], [], set(), None
    current, pred, cur_metrics = base.model, base.pred, base.before
    if base.lag is not None:
        row, effect = _lag_round(ctx, base.lag, current.inputs)
        rounds.append(row)
        if effect is not None:
            effects.append(effect)
            slow = base.lag["slow"]
            current, pred, cur_metrics = slow["model"], slow["pred"], slow["metrics"]
    for rnd in range(d.max_effects - len(effects)):
        with clock("explain"):
            ex = _explain(ctx, rnd, current, pred, used, lags=base.lag is None, log=log)
        first = first or ex.design
        with clock("confirm"):
            step = _Round(ctx, rnd, current, pred, cur_metrics, ex.win, ex.yhat, ex.resid, ex.lib, ex.designs,
                          ex.refinements, ex.floor_terms, used, rounds, log)
            named = step.name(ex.proposals)
        if named is None:
            break
        c, conf = named.candidate, named.conf
        effects.append(Effect(rank=len(effects) + 1, round=rnd + 1, name=c.name, operator=c.operator,
                              channels=tuple(c.channels) or tuple(current.inputs), parameters=_public_parameters(c),
                              explained_fraction=named.selected.explained_fraction, p_value=named.selected.p_value,
                              region=conf.region, key=c.key, candidate=c, found_in=named.where))
        current, pred, cur_metrics = named.trial, conf.pred, conf.metrics
    return effects, rounds, current, first


class _Explained(NamedTuple):
    """One round's explanation of the current model's residual: its windows, median prediction
    and residual; the candidates (`lib`) the proposals index; each selection's (rows, floor);
    the proposals; the floor refinements over all windows (the floor control's inputs) and in
    words; and the selection's design (`Residual`)."""

    win: _Windows
    yhat: np.ndarray
    resid: np.ndarray
    lib: list
    designs: dict
    proposals: list
    refinements: list
    floor_terms: str
    design: Residual


def _explain(ctx: _Ctx, rnd: int, current: Model, pred, used: set, lags: bool, log) -> _Explained:
    """The candidates that explain the current model's residual beyond its floor: the
    selection's proposals, the cells next to a proposed band, the source tries and the
    resonance probe (each as the config asks). Without `lags` (a lag test ran: its trainings
    through the lag are the finer test, and a lag of the prediction that a round confirms
    after it rejected one is a smoother of the nets' transients) no lag is a candidate."""
    d, seed = ctx.cfg.discovery, ctx.cfg.seed + rnd
    win = _replay(ctx, current.offset_s)
    full = win.table.weight.to_numpy() >= 0.999
    yhat = np.median(pred, axis=0)
    resid = win.table.measured_g.to_numpy() - yhat
    lib, C, flib, F = _candidate_matrix(ctx, current, win, yhat, used, lags=lags)
    sel_rows = full & (win.table.k.to_numpy() % _rules.SELECTION_STRIDE == 0)
    own = floor_features(current.inputs)
    groups = win.table.condition.to_numpy()
    floor = _floor(win, yhat, resid, sel_rows, own, groups)
    lib, M = lib + flib, np.column_stack([C, F])  # proposals and their runners-up index both
    proposals, absorbed, designs = _propose(win, yhat, resid, M, sel_rows, own, floor, d, seed=seed,
                                            complexity=np.array([c.complexity for c in lib]),
                                            keys=[_unaligned_key(c) for c in lib],
                                            is_floor=np.arange(len(lib)) >= len(lib) - len(flib))
    proposals = _neighbour_cells(proposals, lib, M, designs, resid, groups, d, seed=seed)
    round_log = lambda m: log(f"round {rnd + 1}: {m}")  # noqa: E731
    proposals = _source_tries(proposals, lib, M, designs, resid, groups, current.inputs, d, seed, round_log)
    if d.resonance.probe:
        proposals = _resonance_probe(ctx, current, proposals, lib, M, designs, resid, groups, d, seed, round_log)
    # The selection's design: its floor with the refinements it took over all windows.
    taken = [M[sel_rows, j] for where, j, _ in absorbed if where == "all"]
    design = Residual(resid, sel_rows, np.column_stack([floor, *taken]) if taken else floor, groups,
                      d.ensemble.folds, ctx.cfg.seed)
    floor_terms = "; ".join(f"{lib[j].name} in {where} ({g:.3f})" for where, j, g in absorbed)
    if absorbed:
        round_log(f"the floor takes {floor_terms}")
    round_log(f"{len(lib) - len(flib)} candidates, {len(proposals)} proposed: "
              + (", ".join(f"{lib[j].name} in {where} (p={s.p_value:.4f}, gain {s.gain:.3f})"
                           for where, j, s in proposals) or "none")
              + "".join(f"; {len(s.equivalents)} equivalent to the best in {where}: "
                        + ", ".join(lib[a].name for a, _ in s.equivalents[:10]) for where, _, s in proposals[:1]))
    refinements = [lib[j] for where, j, _ in absorbed if where == "all"]
    return _Explained(win, yhat, resid, lib, designs, proposals, refinements, floor_terms, design)


def _outcome(ctx: _Ctx, name: str, base: _Baseline, final: Model, effects: list, rounds: list, localized: dict,
             seconds: dict, first: Residual | None, log) -> Discovery:
    """Before and after on the final model's windows (the same counters and windows; the
    baseline re-predicted there if the offset moved), each effect's column as the selection
    saw it beside them."""
    win = _replay(ctx, final.offset_s)
    final_pred = predictions(ctx, final, win)
    base_win = _replay(ctx, base.model.offset_s)
    after = metrics(final_pred, win)
    yb = np.median(base.pred, axis=0)
    table = base_win.table.assign(predicted_before_g=yb)
    table = table.merge(win.table[["counter", "window"]].assign(predicted_after_g=np.median(final_pred, axis=0)),
                        on=["counter", "window"], how="left")
    for e in effects:  # for its partial-dependence plot
        c = e.candidate
        if c.operator == "lag":
            table[f"effect_{e.rank}"] = _lag_windows(yb[None], base_win, c.parameters["tau_s"])[0] - yb
        else:
            table[f"effect_{e.rank}"] = _selection_column(c, base_win.values(c), yb)
    log(f"final: {len(effects)} effect(s); held-out RMS {base.before['rms_g']:.4f} -> {after['rms_g']:.4f} g")
    tries = pd.DataFrame(rounds) if rounds else pd.DataFrame(columns=list(TRY_COLUMNS))
    by_round = {e.round: e for e in effects}
    numbers = sorted(set(tries["round"])) if len(tries) else []
    typed = tuple(Round(int(n), tries[tries["round"] == n].reset_index(drop=True), by_round.get(int(n)))
                  for n in numbers)
    return Discovery(name, ctx.cfg.discovery.database, base.model, final, base.before, after, tuple(effects),
                     tries, localized, table, seconds, first, None if base.lag is None else base.lag["table"], typed)


def summary(res: Discovery) -> dict:
    """The data-contract §3 summary (`discovery.json`)."""
    m = lambda x: {k: round(float(x[k]), 6) for k in ("rms_g", "peak_error_g", "phase_error_s")}  # noqa: E731
    return {
        "campaign": res.campaign,
        "baseline": {"database": res.database, "metrics": m(res.before)},
        "effects": [e.summary() for e in res.effects],
        "augmented": {"added": [e.name for e in res.effects], "metrics": m(res.after)},
        "gap_shrink": round(1.0 - res.after["rms_g"] / res.before["rms_g"], 4),
    }
