"""The lag test: nets trained through lags of several time constants against nets without one."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..analysis.databases import DB_INPUTS
from . import _rules
from ._confirm import _SIGN_FLIPS, _active_kinds, _paired_errors, _paired_sign_flip, _region, _train_model
from ._fits import _fit_offset
from ._learned import fit_learned_lag
from ._model import Model, _Ctx, _inputs, _lag_windows, _replay, _Windows, metrics, predictions, window_layout
from ._results import Effect, Predicted
from .candidates import Candidate


def _through_lag(ctx: _Ctx, tau_s: float, train_offset_s: float) -> Model:
    """Window nets trained through a lag of `tau_s` (τ = 0: none) at `train_offset_s`, their
    offset refitted on the held-out windows."""
    inputs = tuple(DB_INPUTS[ctx.cfg.discovery.database])
    params = _train_model(ctx, Model({}, inputs, offset_s=train_offset_s, lag_tau_s=tau_s, through_lag=True))
    return _fit_offset(ctx, Model(params, inputs, lag_tau_s=tau_s, through_lag=True), with_lag=False)


def _lag_trials(ctx: _Ctx, delta: float, taus, reference_offsets, log=print) -> list[dict]:
    """Window nets trained through a lag of each τ, and without one (τ = 0), each replayed
    with its lag and its offset refitted: a lag tested against a pure delay.

    The reference (τ = 0) trains at the peak nets' offset δ and at each `reference_offsets`;
    each τ at max(lo, δ − τ) (a lag delays by about τ). Every ensemble trains on every
    `train_stride`-th full window (k-fold by condition × seeds) with its lag undone in the
    targets (`delag`); its offset is then refitted on the held-out windows, so that a lag is
    not credited with a better delay.

    Returns:
        One dict per ensemble: tau_s, train_offset_s, model (offset refitted), win, pred
        (S, n), metrics (`metrics`) and ensemble_rms_g (held-out RMS of the median over
        seeds, full windows).
    """
    lo = ctx.cfg.discovery.offset.bounds[0]
    runs = [(0.0, float(o)) for o in sorted({*map(float, reference_offsets), float(delta)})]
    runs += [(float(t), max(lo, round(delta - t, 6))) for t in taus]
    out = []
    for tau, off in runs:
        model = _through_lag(ctx, tau, off)
        win = _replay(ctx, model.offset_s)
        pred = predictions(ctx, model, win)
        m = metrics(pred, win)
        ens = m["ensemble_rms_g"]
        out.append(dict(tau_s=tau, train_offset_s=off, model=model, win=win, pred=pred, metrics=m, ensemble_rms_g=ens))
        log(f"  lag test: τ {tau:.2f} s trained at {off:.2f} s, refitted offset {model.offset_s:.2f} s: "
            f"ensemble RMS {ens:.4f} g")
    return out


# Training offsets of the lag test's reference nets besides the peak nets' offset, s.
_LAG_REFERENCE_OFFSETS = (0.0, 0.5)


# The flight state a lag is learned from, whatever the model's database: the controls of
# db2 and db3 lead the state by the airframe's response, which a lag learned from them would
# measure as well.
_STATE_INPUTS = DB_INPUTS["db1"]


def _learned_lag(ctx: _Ctx, log=print) -> dict:
    """Window nets on the flight state (`_STATE_INPUTS`) and a lag of learnable τ between
    them and the measured PVV, trained jointly (`fit_learned_lag`) at the lowest offset
    (`offset_bounds`), so that τ takes the delay and the fast dynamics with any slower lag:
    on every `train_stride`-th full window, k-fold by condition × seeds, the lag running over
    every window.

    Returns:
        dict: tau_s (folds, seeds), tau_median_s, offset_s, and held-out metrics (`metrics`)
        of the lagged nets.
    """
    d = ctx.cfg.discovery
    offset = float(d.offset.bounds[0])
    win = _replay(ctx, offset)
    t = win.table
    fold = ctx.counter_fold[t.i.to_numpy()]
    rows = (t.weight.to_numpy() >= 0.999) & (t.k.to_numpy() % _rules.TRAIN_STRIDE == 0)
    train_w = np.stack([rows & (fold != f) for f in range(d.ensemble.folds)])
    fit = fit_learned_lag(_inputs(Model({}, _STATE_INPUTS), win), t.measured_g.to_numpy(), train_w,
                          window_layout(win), d.ensemble.folds, seeds=d.ensemble.seeds, hidden=d.ensemble.hidden,
                          seed=ctx.cfg.seed,
                          steps=_rules.LAG_LEARN_STEPS)
    held = fit["pred"][fold, :, np.arange(len(fold))].T  # (seeds, n): each window by the nets that held it out
    tau = fit["tau_s"]
    out = dict(tau_s=tau, tau_median_s=float(np.median(tau)), offset_s=offset, metrics=metrics(held, win))
    log(f"  lag test: learned τ {out['tau_median_s']:.2f} s (folds × seeds {tau.min():.2f}-{tau.max():.2f} s) at "
        f"offset {offset:.2f} s: ensemble RMS {out['metrics']['ensemble_rms_g']:.4f} g")
    return out


def _table_row(tau_s: float, train_offset_s: float, offset_s: float, m: dict) -> dict:
    """One ensemble's row of the lag test's table: its lag, offsets and `metrics`."""
    return dict(tau_s=tau_s, train_offset_s=train_offset_s, ensemble_rms_g=m["ensemble_rms_g"], offset_s=offset_s,
                rms_g=m["rms_g"], peak_error_g=m["peak_error_g"], phase_error_s=m["phase_error_s"])


def _lag_table(learned: dict, trials: list, ref: dict | None, slow: dict | None, lag_fast_s: float) -> pd.DataFrame:
    """The lag test's table: the learned lag's row (its τ the median over folds × seeds, with
    their range), then one row per training through a lag (role reference or slow), each
    with its drop against the reference and whether it was chosen (NaN drops without one)."""
    tau = learned["tau_s"]
    table = pd.DataFrame([_table_row(learned["tau_median_s"], learned["offset_s"], learned["offset_s"],
                                     learned["metrics"])]
                         + [_table_row(t["tau_s"], t["train_offset_s"], t["model"].offset_s, t["metrics"])
                            for t in trials])
    return table.assign(role=["learned"] + ["reference" if t["tau_s"] <= lag_fast_s else "slow" for t in trials],
                        drop=1.0 - table.ensemble_rms_g / (ref["ensemble_rms_g"] if ref else np.nan),
                        chosen=[False] + [t is ref or t is slow for t in trials],
                        tau_min_s=[tau.min()] + [np.nan] * len(trials),
                        tau_max_s=[tau.max()] + [np.nan] * len(trials))


def _lag_test(ctx: _Ctx, delta: float, log, always_trials: bool = False) -> dict:
    """Is there a lag slower than the fast dynamics the offset stands for? Judged by a lag
    learned inside one training (`_learned_lag`): confirmed if its τ, the median over folds
    × seeds, is at least `lag_slow_s`. At the lowest offset the learned τ takes the delay
    and the fast dynamics too (rotor inflow and wake settle within about a second), so the
    threshold sits above them; it moves by tenths of a second over folds and seeds.

    The lag is then added as window nets trained through it (`_lag_trials` at
    `lag_test_taus`): the reference is the best ensemble without a lag or with one of at
    most `lag_fast_s`, the slow lag the best above it, and the slow lag's gain over the
    reference is reported, over all windows and where it acts (the maneuver kinds where
    lagging the reference's prediction by the slow τ changes it, `_active_kinds`), with the
    p-value of a sign-flip test by condition (`_paired_sign_flip`). It is not required: the
    difference of two window trainings moves with the nets' initialization, and nets trained
    through a slow lag can gain without one, where the learned τ separates the two. So where
    the learned τ confirms no lag the trainings, which would decide nothing, are skipped
    unless `always_trials` (then they are reported, for comparison with other campaigns).

    Returns:
        dict: table (one row per ensemble, the learned lag's first), learned
        (`_learned_lag`), reference and slow (their `_lag_trials` dicts; None where the
        trainings were skipped, and NaN for what they measure), drop, local (the drop where
        the lag acts, on the windows both hold in full), judged_in (those kinds), p_value,
        explained_fraction (1 − the slow lag's squared error / the reference's, full windows
        of both), confirmed, why (empty if confirmed).
    """
    d = ctx.cfg.discovery
    learned = _learned_lag(ctx, log)
    tau, tau_all = learned["tau_median_s"], learned["tau_s"]
    why = ("" if tau >= d.lag_test.slow_s else
           f"the learned τ {tau:.2f} s (folds × seeds {tau_all.min():.2f}-{tau_all.max():.2f} s) is below "
           f"lag_test.slow_s {d.lag_test.slow_s:g} s")
    if why and not always_trials:
        log(f"lag test: {why}: not confirmed (no trainings through lags)")
        return dict(table=_lag_table(learned, [], None, None, _rules.LAG_FAST_S), learned=learned, reference=None,
                    slow=None, drop=np.nan, local=np.nan, judged_in="", p_value=np.nan, explained_fraction=np.nan,
                    confirmed=False, why=why)
    trials = _lag_trials(ctx, delta, _rules.LAG_TEST_TAUS, _LAG_REFERENCE_OFFSETS, log)
    ref = min((t for t in trials if t["tau_s"] <= _rules.LAG_FAST_S), key=lambda t: t["ensemble_rms_g"])
    slow = min((t for t in trials if t["tau_s"] > _rules.LAG_FAST_S), key=lambda t: t["ensemble_rms_g"])
    drop = 1.0 - slow["ensemble_rms_g"] / ref["ensemble_rms_g"]
    p, explained = _paired_sign_flip(Predicted(ref["pred"], ref["win"]), Predicted(slow["pred"], slow["win"]),
                                     _SIGN_FLIPS, ctx.cfg.seed)
    rwin = ref["win"]
    rfull = rwin.table.weight.to_numpy() >= 0.999
    yref = np.median(ref["pred"], axis=0)
    kinds = _active_kinds((_lag_windows(yref[None], rwin, slow["tau_s"])[0] - yref)[rfull],
                          rwin.table.maneuver.to_numpy()[rfull])
    both = _paired_errors(Predicted(ref["pred"], ref["win"]), Predicted(slow["pred"], slow["win"]))
    there = both[both.maneuver.isin(kinds)]
    local = float(1.0 - np.sqrt(there.e2_b.sum() / there.e2_a.sum()))
    table = _lag_table(learned, trials, ref, slow, _rules.LAG_FAST_S)
    log(f"lag test: learned τ {tau:.2f} s against lag_test.slow_s {d.lag_test.slow_s:g} s; "
        f"the slow lag τ {slow['tau_s']:g} s "
        f"against the reference (τ {ref['tau_s']:g} s): ensemble RMS {ref['ensemble_rms_g']:.4f} -> "
        f"{slow['ensemble_rms_g']:.4f} g ({-drop:+.1%}; {-local:+.1%} in {', '.join(kinds)}), p = {p:.3f}: "
        + ("confirmed" if not why else "not confirmed"))
    return dict(table=table, learned=learned, reference=ref, slow=slow, drop=drop, local=local,
                judged_in=", ".join(kinds), p_value=p, explained_fraction=explained, confirmed=not why, why=why)


def _lag_round(ctx: _Ctx, lag: dict, inputs) -> tuple[dict, dict | None]:
    """The lag test (`_lag_test`) as round 0 of the rounds table and, if confirmed, the first
    effect (its region on the slow lag's windows, the reference re-predicted there). Without
    trainings through lags (skipped: no lag confirmed) the row holds the learned τ alone."""
    slow, ref = lag["slow"], lag["reference"]
    learned = f"learned τ {lag['learned']['tau_median_s']:.2f} s"
    c = Candidate("lag", (), {"tau_s": slow["tau_s"] if slow else round(float(lag["learned"]["tau_median_s"]), 2)})
    m = lambda t, k: t["metrics"][k] if t else np.nan  # noqa: E731
    row = dict(round=0, where="all", candidate=c.key, parameters=c.parameters_json, name=c.name, operator="lag",
               channels="",
               augment="trained through" if slow else "learned", p_value=lag["p_value"], cv_gain=np.nan,
               runners_up=f"{learned}; reference: τ {ref['tau_s']:g} s" if ref else learned,
               explained_fraction=lag["explained_fraction"],
               rms_before_g=m(ref, "rms_g"), rms_after_g=m(slow, "rms_g"),
               ensemble_rms_before_g=m(ref, "ensemble_rms_g"), ensemble_rms_after_g=m(slow, "ensemble_rms_g"),
               shrink=lag["drop"], judged_in=lag["judged_in"], region_shrink=lag["local"],
               confirmed=lag["confirmed"], why_not=lag["why"], p_best_better=np.nan, chosen=lag["confirmed"])
    if not lag["confirmed"]:
        return row, None
    swin = slow["win"]  # the effect's region: the reference re-predicted on the slow lag's windows
    region = _region(swin, swin.table.weight.to_numpy() >= 0.999, predictions(ctx, ref["model"], swin), slow["pred"])
    return row, Effect(rank=1, round=0, name=c.name, operator="lag", channels=tuple(inputs),
                       parameters={"tau_s": slow["tau_s"], "learned_tau_s": lag["learned"]["tau_median_s"]},
                       explained_fraction=lag["explained_fraction"], p_value=lag["p_value"], region=region,
                       key=c.key, candidate=c, found_in="all")


def _lag_candidates(yhat, win: _Windows, taus) -> tuple[list[Candidate], np.ndarray]:
    cols = [(_lag_windows(yhat[None], win, t)[0] - yhat) for t in taus]
    return [Candidate("lag", (), {"tau_s": float(t)}) for t in taus], np.column_stack(cols)
