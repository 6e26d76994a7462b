"""The discovery workflow: its context, `discover` and the data-contract §3 summary."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .._timing import Stopwatch
from ..analysis.databases import DB_INPUTS, STATE_CHANNELS, build_databases
from ..config import DiscoveryConfig, ExperimentConfig
from ..data.batch import to_batch
from ..data.campaign import Campaign, load_campaign
from ..nets import train as _train
from ..replay.quasistatic import make_settings, prepare
from ._citest import UnitTest
from ._explain import Explanation
from ._fits import _fit_offset
from ._model import HOP_REVS, Model, _Ctx, _lag_windows, _replay
from ._results import Effect, Round
from ._tested import effect_region, held_out, tested
from ._train import _train_model
from .candidates import Candidate, sample_series, values, window_table
from .residuals import localize

TEST_COLUMNS = ("round", "key", "name", "kind", "statistic", "p_value", "adjusted_p", "theta", "left")


@dataclass(frozen=True)
class Discovery:
    """The outcome of `discover` (`summary` turns it into data-contract §3).

    Attributes:
        campaign: path or name. database: the model's database.
        baseline, final: the baseline and the final (augmented) `Model`.
        before, after: their held-out metrics (`metrics`: medians over seeds, `rms_by_seed`
            per seed, `ensemble_rms_g` of the median prediction).
        effects: the named effects (`Effect`), in the order named (missing ones, then a
            misfit).
        tries: every test of every round (`Explanation.tests`: one row per candidate and
            round; round 0 holds the misfit's forms).
        rounds: the rounds (`Round`): each one's tests and the effect it named.
        localized: `residuals.localize` tables of the baseline.
        windows: the baseline replay windows with `predicted_before_g`, `predicted_after_g` and
            `effect_<rank>`, each effect's column as it was tested (a resonance's band times
            the prediction, a lag as the lagged minus the plain prediction).
        seconds: wall time per stage.
        capacity: the baseline's capacity test (is its held-out residual predictable from
            its own inputs at all).
        carried: the keys of the candidates built only from the model's inputs: never
            named as missing (a misfit's forms).
        level: the family-wise level of each round.
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
    elif not isinstance(cfg, ExperimentConfig):
        raise TypeError(f"{caller}: cfg must be an ExperimentConfig or a DiscoveryConfig, got {type(cfg).__name__}")
    if isinstance(campaign, (str, os.PathLike)):
        name = name or str(campaign)
        campaign = load_campaign(campaign, cfg.campaign.columns, cfg.analysis.window_revs,
                                 harmonic=cfg.analysis.harmonic)
    elif not isinstance(campaign, Campaign):
        raise TypeError(f"{caller}: campaign must be a Campaign or a campaign folder, got {type(campaign).__name__}")
    return campaign, cfg, name


def discover(campaign: Campaign | str | os.PathLike, cfg: ExperimentConfig | DiscoveryConfig = ExperimentConfig(), *,
             name: str = "", log=print) -> Discovery:
    """Run the discovery workflow on a campaign: the baseline, where its residual lies, what
    explains it beyond the baseline's inputs at `discovery.level` (`explain`), the named
    effects' parameters with their intervals, and the model with them, retrained once (see
    the package docstring).

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
    clock = Stopwatch()
    with clock("prepare"):
        ctx = _context(campaign, cfg, log)
    with clock("train_baseline"):
        ctx.replay_params = _train_model(ctx, Model({}, tuple(DB_INPUTS[cfg.discovery.database])))
    with clock("offset_and_replay"):
        base = _fit_offset(ctx, Model(ctx.replay_params, tuple(DB_INPUTS[cfg.discovery.database])))
        pred, win, before = held_out(ctx, base)
    log(f"baseline {cfg.discovery.database}: offset {base.offset_s:.2f} s, held-out RMS {before['rms_g']:.4f} g, "
        f"peak error {before['peak_error_g']:.4f} g, phase error {before['phase_error_s']:.2f} s")
    localized = _localized(ctx, win, pred, log)
    if cfg.discovery.max_effects == 0:
        return _outcome(ctx, name or str(campaign.source), base, pred, before, None, base, clock.seconds, localized,
                        log)
    with clock("test"):
        t = tested(ctx, base, pred, log)
    return _outcome(ctx, name or str(campaign.source), base, pred, before, t, t.model, clock.seconds, localized, log)


def _localized(ctx: _Ctx, win, pred, log) -> dict:
    """Where the baseline's residual lies (`residuals.localize`), on its full windows."""
    full = win.table.weight.to_numpy() >= 0.999
    windows = win.table.assign(database=ctx.cfg.discovery.database, predicted_g=np.median(pred, axis=0))
    localized = localize(windows[full])
    log("residual by maneuver (share of the squared residual): " + ", ".join(
        f"{k} {v:.0%}" for k, v in localized["maneuver"].share_sq.head(4).items()))
    return localized


def _effects(ctx: _Ctx, base: Model, final: Model, t) -> list[Effect]:
    """The named effects as typed records: each with its test, fitted parameters and their
    intervals, and where the model with them changed the prediction."""
    if t is None or not t.fitted:
        return []
    region = effect_region(ctx, base, final)
    out = []
    for rank, f in enumerate(t.fitted, start=1):
        n, c = f.named, f.candidate
        out.append(Effect(rank=rank, round=n.round, name=c.name, operator=c.operator,
                          channels=tuple(c.channels) or tuple(base.inputs), parameters=_public_parameters(c),
                          explained_fraction=n.explained, p_value=n.adjusted_p, region=region, key=c.key, candidate=c,
                          found_in="all", kind=n.kind, statistic=n.statistic, intervals=f.intervals, tied=n.tied))
    return out


def _outcome(ctx: _Ctx, name: str, base: Model, base_pred, before: dict, t, final: Model, seconds: dict,
             localized: dict, log) -> Discovery:
    """Before and after on the final model's windows (the same counters and windows; the
    baseline re-predicted there if the offset moved), each effect's column as it was tested
    beside them."""
    final_pred, win, after = held_out(ctx, final) if final is not base else (base_pred, None, before)
    base_win = _replay(ctx, base.offset_s)
    yb = np.median(base_pred, axis=0)
    table = base_win.table.assign(predicted_before_g=yb)
    if win is None:
        table["predicted_after_g"] = yb
    else:
        table = table.merge(win.table[["counter", "window"]].assign(predicted_after_g=np.median(final_pred, axis=0)),
                            on=["counter", "window"], how="left")
    effects = _effects(ctx, base, final, t)
    for e in effects:  # for its partial-dependence plot
        c = e.candidate
        if c.operator == "lag":
            table[f"effect_{e.rank}"] = _lag_windows(yb[None], base_win, c.parameters["tau_s"])[0] - yb
        else:
            v = base_win.values(c) if "offset_s" in c.parameters else values(c, base_win.cands)
            table[f"effect_{e.rank}"] = v * yb if c.operator == "resonance" else v
    log(f"final: {len(effects)} effect(s); held-out RMS {before['rms_g']:.4f} -> {after['rms_g']:.4f} g")
    ex: Explanation | None = None if t is None else t.explanation
    tries = ex.tests if ex is not None else pd.DataFrame(columns=list(TEST_COLUMNS))
    by_round = {e.round: e for e in effects}
    typed = tuple(Round(int(n), tries[tries["round"] == n].reset_index(drop=True), by_round.get(int(n)))
                  for n in sorted(set(tries["round"])))
    return Discovery(name, ctx.cfg.discovery.database, base, final, before, after, tuple(effects), tries, localized,
                     table, seconds, None if ex is None else ex.capacity, () if ex is None else ex.carried,
                     ctx.cfg.discovery.level, typed)


def summary(res: Discovery) -> dict:
    """The data-contract §3 summary (`discovery.json`)."""
    m = lambda x: {k: round(float(x[k]), 6) for k in ("rms_g", "peak_error_g", "phase_error_s")}  # noqa: E731
    cap = res.capacity
    return {
        "campaign": res.campaign,
        "baseline": {"database": res.database, "metrics": m(res.before)},
        "effects": [e.summary() for e in res.effects],
        "augmented": {"added": [e.name for e in res.effects], "metrics": m(res.after)},
        "gap_shrink": round(1.0 - res.after["rms_g"] / res.before["rms_g"], 4),
        "level": res.level,
        "capacity": None if cap is None else {
            "statistic": round(float(cap.statistic), 4), "p_value": round(float(cap.p_value), 6),
            "misfit": [e.name for e in res.effects if e.kind == "misfit"],
            "carried": len(res.carried)},
    }
