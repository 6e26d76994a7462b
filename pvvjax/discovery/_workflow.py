"""The discovery workflow: its context, `discover` and the data-contract §3 summary."""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pandas as pd

from .._arguments import instance
from .._timing import Stopwatch
from ..analysis.databases import DB_INPUTS, STATE_CHANNELS, build_databases
from ..config import DiscoveryConfig, ExperimentConfig
from ..data.batch import to_batch
from ..data.campaign import Campaign, CampaignWarning, load_campaign
from ..nets import train as _train
from ..replay.quasistatic import make_settings, prepare
from ._citest import UnitTest
from ._explain import TEST_COLUMNS, Explanation, tested_column
from ._fits import _fit_offset
from ._model import HOP_REVS, Model, _Ctx, _lag_windows, metrics, predictions
from ._results import Effect, Round
from ._simulation import placeholder_params, simulated_after, simulation_windows
from ._tested import effect_region, fitted, held_out, tested, with_effects
from ._train import _train_model
from .candidates import Candidate, channels_lacking, sample_series, window_table
from .residuals import localize


@dataclass(frozen=True)
class Discovery:
    """The outcome of `discover` (`summary` turns it into data-contract §3).

    Attributes:
        campaign: path or name. database: the model's database, or "simulation:<column>"
            for the user's own simulation as the baseline.
        baseline, final: the baseline and the final (augmented) `Model`.
        before, after: their held-out metrics (`metrics`: medians over seeds, `rms_by_seed`
            per seed, `ensemble_rms_g` of the median prediction).
        effects: the named effects (`Effect`), in the order named (the misfit's forms, then
            the missing ones).
        tries: every test of every round (`Explanation.tests`: one row per candidate and
            round; the misfit's rounds first).
        rounds: the rounds (`Round`): each one's tests and the effect it named.
        localized: `residuals.localize` tables of the baseline.
        windows: the baseline replay windows with `predicted_before_g`, `predicted_after_g` and
            `effect_<rank>`, each effect's column as it was tested (a resonance's band times
            the prediction, a lag as the lagged minus the plain prediction).
        seconds: wall time per stage (prepare, train_baseline, offset_and_replay, test, fit,
            retrain; a simulation: add instead of retrain).
        capacity: the baseline's capacity test (is its held-out residual predictable from
            its own inputs at all).
        carried: the keys of the candidates built only from the model's inputs: never
            named as missing (the misfit's forms).
        level: the family-wise level of each round.
        nuisance: the test's nuisance regressions per round (`Explanation.nuisance`): the
            residual's learner and out-of-fold skill, the candidates' median and smallest.
        with_misfit: keys of candidates the data cannot tell from a misfit of the inputs
            (`Explanation.with_misfit`): reported, never named as missing.
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
    capacity: UnitTest | None = None
    carried: tuple[str, ...] = ()
    level: float = 0.05
    rounds: tuple[Round, ...] = ()
    nuisance: pd.DataFrame | None = None
    with_misfit: tuple[str, ...] = ()


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
    lacking = channels_lacking(campaign, list(info.index))
    if lacking:
        warnings.warn(f"discovery: campaign {source}: " + "; ".join(
            f"{k} is missing in {len(v)} counter(s) ({', '.join(v[:3])}{', …' if len(v) > 3 else ''})"
            for k, v in lacking.items()) + ": not candidates (a candidate needs a value in every record); the "
            "records themselves are kept", CampaignWarning, stacklevel=3)
    batch = to_batch(campaign, STATE_CHANNELS, list(info.index), axis=cfg.analysis.axis)
    recs = prepare(batch, harmonic=cfg.analysis.harmonic or campaign.aircraft.blades)
    L = cfg.analysis.window_revs
    lo, hi = d.offset.bounds if d.offset.calibrate else (min(0.0, d.offset.fixed_s), max(0.0, d.offset.fixed_s))
    settings = make_settings(batch, max_window_revs=L, min_window_revs=L, hop_revs=HOP_REVS,
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
    instance(caller, "cfg", cfg, ExperimentConfig, "an ExperimentConfig or a DiscoveryConfig")
    if isinstance(campaign, (str, os.PathLike)):
        name = name or str(campaign)
        campaign = load_campaign(campaign, cfg.campaign.columns, cfg.analysis.window_revs,
                                 harmonic=cfg.analysis.harmonic)
    instance(caller, "campaign", campaign, Campaign, "a Campaign or a campaign folder")
    return campaign, cfg, name


def discover(campaign: Campaign | str | os.PathLike, cfg: ExperimentConfig | DiscoveryConfig = ExperimentConfig(), *,
             name: str = "", log=print) -> Discovery:
    """Run the discovery workflow on a campaign: the baseline, where its residual lies, what
    explains it beyond the baseline's inputs at `discovery.level` (`explain`), the named
    effects' parameters with their intervals, and the model with them, retrained once (see
    the package docstring).

    The baseline is the database's nets, or, with `discovery.simulation`, the user's own
    simulation: a column of predicted vibration in every record, with the channels it took
    as inputs (`discovery.simulation_inputs`); the named effects then join it as a lag of
    its prediction and a linear term fitted out of fold by condition.

    Args:
        campaign: any campaign in the data-contract format, loaded or its folder.
        cfg: experiment config (`analysis`, `train` and `discovery` sections), or only the
            `DiscoveryConfig` (the other sections at their defaults).
        name: the campaign's path or name, for the summary (default: the folder given).
        log: progress messages.

    Returns:
        `Discovery`.
    """
    campaign, cfg, name = _workflow_inputs("discover", campaign, cfg, name)
    d, clock = cfg.discovery, Stopwatch()
    with clock("prepare"):
        ctx = _context(campaign, cfg, log)
    if d.simulation:
        with clock("offset_and_replay"):
            ctx.replay_params = placeholder_params(ctx)
            win, pred = simulation_windows(ctx)
        base, inputs, exclude = Model({}, tuple(d.simulation_inputs)), tuple(d.simulation_inputs), (d.simulation,)
    else:
        inputs, exclude = tuple(DB_INPUTS[d.database]), ()
        with clock("train_baseline"):
            ctx.replay_params = _train_model(ctx, Model({}, inputs))
        with clock("offset_and_replay"):
            base = _fit_offset(ctx, Model(ctx.replay_params, inputs))
            pred, win, _ = held_out(ctx, base)
    before = metrics(pred, win)
    log(f"baseline {d.simulation or d.database}: offset {base.offset_s:.2f} s, held-out RMS {before['rms_g']:.4f} g, "
        f"peak error {before['peak_error_g']:.4f} g, phase error {before['phase_error_s']:.2f} s")
    localized = _localized(ctx, win, pred, log)
    ex, effects, final, after_pred, after_win = None, (), base, pred, win
    if d.max_effects > 0:
        with clock("test"):
            ex, corrected = tested(ctx, win, pred, inputs, log, exclude)
        with clock("fit"):
            effects = fitted(ctx, win, pred, corrected, ex, inputs)
        if effects:
            if d.simulation:
                final = base._replace(extra=tuple(f.candidate for f in effects))
                with clock("add"):
                    after_pred = simulated_after(ctx, win, pred, effects)
            else:
                with clock("retrain"):
                    final = with_effects(ctx, base, effects)
                    after_pred, after_win, _ = held_out(ctx, final)
    return _outcome(ctx, name or str(campaign.source), _Run(base, win, pred, before, ex, effects, final, after_win,
                                                           after_pred), clock.seconds, localized, log)


class _Run(NamedTuple):
    """What a discovery ran: the baseline model, its windows, predictions (S, n) and metrics;
    the explanation and the fitted named effects (None and () without a test); the final
    model, its windows and predictions."""

    base: Model
    win: object
    pred: np.ndarray
    before: dict
    ex: Explanation | None
    fitted: tuple
    final: Model
    after_win: object
    after_pred: np.ndarray


def _localized(ctx: _Ctx, win, pred, log) -> dict:
    """Where the baseline's residual lies (`residuals.localize`), on its full windows."""
    full = win.table.weight.to_numpy() >= 0.999
    windows = win.table.assign(database=ctx.cfg.discovery.database, predicted_g=np.median(pred, axis=0))
    localized = localize(windows[full])
    log("residual by maneuver (share of the squared residual): " + ", ".join(
        f"{k} {v:.0%}" for k, v in localized["maneuver"].share_sq.head(4).items()))
    return localized


def _effects(run: _Run, before_there, after_there) -> list[Effect]:
    """The named effects as typed records: each with its test, fitted parameters and their
    intervals, and where the model with them changed the prediction (predictions (S, n) of
    the baseline and the final model on the final model's windows)."""
    if not run.fitted:
        return []
    region = effect_region(run.after_win, before_there, after_there)
    out = []
    for rank, f in enumerate(run.fitted, start=1):
        n, c = f.named, f.candidate
        out.append(Effect(rank=rank, round=n.round, name=c.name, operator=c.operator,
                          channels=tuple(c.channels) or tuple(run.base.inputs), parameters=_public_parameters(c),
                          explained_fraction=n.explained, p_value=n.adjusted_p, region=region, key=c.key, candidate=c,
                          found_in="all", kind=n.kind, statistic=n.statistic, intervals=f.intervals, tied=n.tied))
    return out


def _outcome(ctx: _Ctx, name: str, run: _Run, seconds: dict, localized: dict, log) -> Discovery:
    """Before and after on the final model's windows (the same counters and windows; the
    baseline re-predicted there if the offset moved), each effect's column as it was tested
    beside them."""
    after = metrics(run.after_pred, run.after_win)
    yb = np.median(run.pred, axis=0)
    table = run.win.table.assign(predicted_before_g=yb)
    table = table.merge(run.after_win.table[["counter", "window"]].assign(
        predicted_after_g=np.median(run.after_pred, axis=0)), on=["counter", "window"], how="left")
    before_there = run.pred if run.after_win is run.win else predictions(ctx, run.base, run.after_win)
    effects = _effects(run, before_there, run.after_pred)
    for e in effects:  # for its partial-dependence plot
        c = e.candidate
        if c.operator == "lag":
            table[f"effect_{e.rank}"] = _lag_windows(yb[None], run.win, c.parameters["tau_s"])[0] - yb
        else:
            table[f"effect_{e.rank}"] = tested_column(c, run.win.cands, yb)
    log(f"final: {len(effects)} effect(s); held-out RMS {run.before['rms_g']:.4f} -> {after['rms_g']:.4f} g")
    if _worse(effects, run.before, after):
        warnings.warn(f"discovery on {name}: the model with the named effects predicts worse held out than the "
                      f"baseline (RMS {run.before['rms_g']:.4f} -> {after['rms_g']:.4f} g): "
                      "what the test named is reported, but adding it as fitted did not help", UserWarning,
                      stacklevel=3)
    ex = run.ex
    tries = ex.tests if ex is not None else pd.DataFrame(columns=list(TEST_COLUMNS))
    by_round = {e.round: e for e in effects}
    typed = tuple(Round(int(n), tries[tries["round"] == n].reset_index(drop=True), by_round.get(int(n)))
                  for n in sorted(set(tries["round"])))
    d = ctx.cfg.discovery
    return Discovery(name, f"simulation:{d.simulation}" if d.simulation else d.database, run.base, run.final,
                     run.before, after, tuple(effects), tries, localized, table, seconds,
                     None if ex is None else ex.capacity, () if ex is None else ex.carried, d.level, typed,
                     None if ex is None else ex.nuisance, () if ex is None else ex.with_misfit)


def _worse(effects, before: dict, after: dict) -> bool:
    """Whether the model with named effects predicts worse held out than the baseline."""
    return bool(effects) and after["rms_g"] > before["rms_g"]


def _plain(v):
    """A table's value for JSON: a NumPy scalar as Python's, a float to 4 decimals."""
    v = v.item() if isinstance(v, np.generic) else v
    return round(v, 4) if isinstance(v, float) else v


def summary(res: Discovery) -> dict:
    """The data-contract §3 summary (`discovery.json`)."""
    m = lambda x: {k: round(float(x[k]), 6) for k in ("rms_g", "peak_error_g", "phase_error_s")}  # noqa: E731
    cap = res.capacity
    return {
        "campaign": res.campaign,
        "baseline": {"database": res.database, "metrics": m(res.before)},
        "effects": [e.summary() for e in res.effects],
        "augmented": {"added": [e.name for e in res.effects], "metrics": m(res.after),
                      "worse_than_baseline": _worse(res.effects, res.before, res.after)},
        "gap_shrink": round(1.0 - res.after["rms_g"] / res.before["rms_g"], 4),
        "level": res.level,
        "capacity": None if cap is None else {
            "statistic": round(float(cap.statistic), 4), "p_value": round(float(cap.p_value), 6),
            "misfit": [e.name for e in res.effects if e.kind == "misfit"],
            "carried": len(res.carried), "tied_with_misfit": list(res.with_misfit)},
        "nuisance": [] if res.nuisance is None else [
            {k: _plain(v) for k, v in r.items()} for r in res.nuisance.to_dict("records")],
    }
