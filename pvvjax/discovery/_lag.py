"""The lag test: nets trained through lags of several time constants against nets without one."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..candidates import Candidate
from ..databases import DB_INPUTS
from ._confirm import _SIGN_FLIPS, _active_kinds, _paired_errors, _paired_sign_flip, _region, _train_model
from ._fits import _fit_offset
from ._model import Model, _Ctx, _lag_windows, _replay, _Windows, metrics, predictions


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
    lo = ctx.cfg.discovery.offset_bounds[0]
    inputs = tuple(DB_INPUTS[ctx.cfg.discovery.database])
    runs = [(0.0, float(o)) for o in sorted({*map(float, reference_offsets), float(delta)})]
    runs += [(float(t), max(lo, round(delta - t, 6))) for t in taus]
    out = []
    for tau, off in runs:
        params = _train_model(ctx, Model({}, inputs, offset_s=off, lag_tau_s=tau, through_lag=True))
        model = _fit_offset(ctx, Model(params, inputs, lag_tau_s=tau, through_lag=True), with_lag=False)
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


def _lag_test(ctx: _Ctx, delta: float, log) -> dict:
    """Is there a lag slower than the fast dynamics the offset stands for? `_lag_trials` at
    `lag_test_taus`; the reference is the best ensemble without a lag or with one of at
    most `lag_fast_s` (rotor inflow and wake settle within about a second: the base
    dynamics of every world, which nets trained through a lag find as well); the slow lag
    is the best ensemble above it. Confirmed, as every effect is (`_confirm`), if the slow
    lag lowers the reference's held-out ensemble RMS by `min_shrink` over all windows and
    where it acts: the maneuver kinds where lagging the reference's prediction by the slow τ
    changes it (`_active_kinds`; the transients). A lag changes nothing in steady flight, so
    nets trained through one that gain there, not in the transients, are two retrainings of
    a map that misses something else (measured, weight missing from db3: −10.3 % over all
    windows, most of it in descents and turns, +0.4 % in flares, pull-ups, push-overs and
    rolls; a 2 s lag: −5.3 % over all, −32 % there). The p-value of a sign-flip test by
    condition (`_paired_sign_flip`) is reported, not required: the gain of a lag sits in the
    transients, a third of the conditions, while the rest carry the two retrainings' noise
    (the benchmark's 2 s lag worlds: drops of 21, 7 and 6 % at p = 0.001, 0.12 and 0.03).

    Returns:
        dict: table (one row per ensemble), reference and slow (their `_lag_trials` dicts),
        drop, local (the drop where the lag acts, on the windows both hold in full),
        judged_in (those kinds), p_value, explained_fraction (1 − the slow lag's squared
        error / the reference's, full windows of both), confirmed, why (empty if confirmed).
    """
    d = ctx.cfg.discovery
    trials = _lag_trials(ctx, delta, d.lag_test_taus, _LAG_REFERENCE_OFFSETS, log)
    ref = min((t for t in trials if t["tau_s"] <= d.lag_fast_s), key=lambda t: t["ensemble_rms_g"])
    slow = min((t for t in trials if t["tau_s"] > d.lag_fast_s), key=lambda t: t["ensemble_rms_g"])
    drop = 1.0 - slow["ensemble_rms_g"] / ref["ensemble_rms_g"]
    p, explained = _paired_sign_flip(ref, slow, _SIGN_FLIPS, ctx.cfg.seed)
    rwin = ref["win"]
    rfull = rwin.table.weight.to_numpy() >= 0.999
    yref = np.median(ref["pred"], axis=0)
    kinds = _active_kinds((_lag_windows(yref[None], rwin, slow["tau_s"])[0] - yref)[rfull],
                          rwin.table.maneuver.to_numpy()[rfull])
    both = _paired_errors(ref, slow)
    there = both[both.maneuver.isin(kinds)]
    local = float(1.0 - np.sqrt(there.e2_b.sum() / there.e2_a.sum()))
    why = ("" if drop >= d.min_shrink and local >= d.min_shrink else
           f"the slow lag lowers the reference's ensemble RMS {drop:+.1%} over all windows and {local:+.1%} where "
           f"it acts ({', '.join(kinds)}): less than min_shrink {d.min_shrink:.0%}")
    table = pd.DataFrame([{k: t[k] for k in ("tau_s", "train_offset_s", "ensemble_rms_g")}
                          | {"offset_s": t["model"].offset_s} | {k: t["metrics"][k] for k in
                                                                  ("rms_g", "peak_error_g", "phase_error_s")}
                          for t in trials])
    table = table.assign(role=np.where(table.tau_s <= d.lag_fast_s, "reference", "slow"),
                         drop=1.0 - table.ensemble_rms_g / ref["ensemble_rms_g"],
                         chosen=[t is ref or t is slow for t in trials])
    log(f"lag test: slow lag τ {slow['tau_s']:g} s against the reference (τ {ref['tau_s']:g} s): ensemble RMS "
        f"{ref['ensemble_rms_g']:.4f} -> {slow['ensemble_rms_g']:.4f} g ({-drop:+.1%}; {-local:+.1%} in "
        f"{', '.join(kinds)}), p = {p:.3f}: " + ("confirmed" if not why else "not confirmed"))
    return dict(table=table, reference=ref, slow=slow, drop=drop, local=local, judged_in=", ".join(kinds), p_value=p,
                explained_fraction=explained, confirmed=not why, why=why)


def _lag_round(ctx: _Ctx, lag: dict, inputs) -> tuple[dict, dict | None]:
    """The lag test (`_lag_test`) as round 0 of the rounds table and, if confirmed, the first
    effect (its region on the slow lag's windows, the reference re-predicted there)."""
    slow, ref = lag["slow"], lag["reference"]
    c = Candidate("lag", (), {"tau_s": slow["tau_s"]})
    row = dict(round=0, where="all", candidate=c.key, name=c.name, operator="lag", channels="",
               augment="trained through", p_value=lag["p_value"], cv_gain=np.nan,
               runners_up=f"reference: τ {ref['tau_s']:g} s", explained_fraction=lag["explained_fraction"],
               rms_before_g=ref["metrics"]["rms_g"], rms_after_g=slow["metrics"]["rms_g"],
               ensemble_rms_before_g=ref["ensemble_rms_g"], ensemble_rms_after_g=slow["ensemble_rms_g"],
               shrink=lag["drop"], judged_in=lag["judged_in"], region_shrink=lag["local"],
               confirmed=lag["confirmed"], why_not=lag["why"], p_best_better=np.nan, chosen=lag["confirmed"])
    if not lag["confirmed"]:
        return row, None
    swin = slow["win"]  # the effect's region: the reference re-predicted on the slow lag's windows
    region = _region(swin, swin.table.weight.to_numpy() >= 0.999, predictions(ctx, ref["model"], swin), slow["pred"])
    return row, dict(rank=1, round=0, name=c.name, operator="lag", channels=list(inputs),
                     parameters={"tau_s": slow["tau_s"]}, explained_fraction=lag["explained_fraction"],
                     p_value=lag["p_value"], region=region, key=c.key, candidate=c, found_in="all")


def _lag_candidates(yhat, win: _Windows, taus) -> tuple[list[Candidate], np.ndarray]:
    cols = [(_lag_windows(yhat[None], win, t)[0] - yhat) for t in taus]
    return [Candidate("lag", (), {"tau_s": float(t)}) for t in taus], np.column_stack(cols)
