"""Add and confirm: a candidate added to the model (input, additive term or gain), the nets
retrained, the held-out ensemble compared by condition, and which confirmed try a round names."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..analysis.databases import OUTPUT
from . import _rules
from ._fits import _lag_identified
from ._model import (
    Model,
    _columns,
    _Ctx,
    _inputs,
    _lag_windows,
    _replay,
    _rms_by_seed,
    _terms,
    _Windows,
    delag,
    fit_ensemble,
    metrics,
    predictions,
    source_channels,
)
from ._results import Confirmation
from .candidates import Candidate, values


def _train_model(ctx: _Ctx, model: Model, rows: str = "peaks") -> dict:
    """Nets on the database inputs and the model's extra inputs, with its gains, trained on
    the peaks or the windows (`rows`) minus its additive terms (per fold: each fold's terms
    were fitted without it). A model `through_lag` trains on the windows, the measured ones
    with the model's lag undone (`delag`)."""
    d = ctx.cfg.discovery
    if model.through_lag or rows == "windows":  # every TRAIN_STRIDE-th full window at the offset
        win = _replay(ctx, model.offset_s)
        t = win.table
        sel = (t.weight.to_numpy() >= 0.999) & (t.k.to_numpy() % _rules.TRAIN_STRIDE == 0)
        x, value = _inputs(model, win)[sel], lambda c: win.values(c)[sel]
        y = t.measured_g.to_numpy()
        if model.through_lag:
            y = delag(y, t.time_s.to_numpy(), t.i.to_numpy(), model.lag_tau_s)
        y, folds = y[sel], ctx.counter_fold[t.i.to_numpy()[sel]]
    else:
        value = lambda c: values(c, ctx.train_table)  # noqa: E731
        x, y, folds = _columns(ctx.x_db, model, value), ctx.db[OUTPUT].to_numpy(np.float64), ctx.folds
    if model.terms:
        y = np.stack([y - _terms(model, value, np.full(len(y), f)) for f in range(d.ensemble.folds)])
    e = d.ensemble
    return fit_ensemble(x, y, folds, k=e.folds, seeds=e.seeds, hidden=e.hidden, train_cfg=ctx.cfg.train,
                        seed=ctx.cfg.seed, n_gain=len(model.gains))


def _fit_term(ctx: _Ctx, model: Model, c: Candidate, win: _Windows) -> np.ndarray:
    """Intercept and coefficient of an additive term on the residual of `model`, per fold,
    each fitted on the windows of the other folds' conditions (cross-fitting). (k, 2). With
    a lag in the model the term acts before it (`predictions`), so it is fitted lagged."""
    full = win.table.weight.to_numpy() >= 0.999
    fold = ctx.counter_fold[win.table.i.to_numpy()]
    r = win.table.measured_g.to_numpy() - np.median(predictions(ctx, model, win), axis=0)
    A = np.column_stack([np.ones(len(r)), _lag_windows(win.values(c)[None], win, model.lag_tau_s)[0]])
    out = np.zeros((ctx.cfg.discovery.ensemble.folds, 2))
    for f in range(len(out)):
        rows = full & (fold != f)
        out[f] = np.linalg.lstsq(A[rows], r[rows], rcond=None)[0]
    return out


def _augment(ctx: _Ctx, model: Model, c: Candidate, how: str, refit: str = "peaks") -> Model:
    """The model with one more effect: an extra network input, a learned gain on the nets'
    output (`gain_apply`), or an additive term (fitted on the windows, the nets retrained on
    the corrected peaks, the term refitted: on those nets' residual, or, where `refit` is
    "windows" and the model trains on the peaks, on that of nets trained on the windows minus
    it, the peak nets then retrained on the peaks minus the refitted term)."""
    if how in ("input", "gain"):
        trial = model._replace(**({"extra": model.extra + (c,)} if how == "input" else {"gains": model.gains + (c,)}))
        return trial._replace(params=_train_model(ctx, trial))
    win = _replay(ctx, model.offset_s)
    first = model._replace(terms=model.terms + ((c, _fit_term(ctx, model, c, win)),))
    if refit == "windows" and not model.through_lag:
        refit = _fit_term(ctx, model._replace(params=_train_model(ctx, first, rows="windows")), c, win)
        refitted = model._replace(terms=model.terms + ((c, refit),))
        return refitted._replace(params=_train_model(ctx, refitted))
    params = _train_model(ctx, first)
    refit = _fit_term(ctx, model._replace(params=params), c, win)
    return model._replace(params=params, terms=model.terms + ((c, refit),))


def _active_kinds(v, maneuver) -> list[str]:
    """The maneuver kinds where a column `v` (one value per window) is active: its mean squared
    deviation from its median over the windows of the kind is at least that over all windows."""
    dev = pd.Series((v - np.median(v)) ** 2, index=maneuver)
    by_kind = dev.groupby(level=0).mean()
    return sorted(by_kind.index[by_kind >= dev.mean()])


def _confirm(ctx: _Ctx, current: Model, trial: Model, c: Candidate, where: str, d,
             slack: float = 0.0) -> Confirmation:
    """Whether a trial model confirms its effect: the held-out RMS of the ensemble's
    prediction (the median over seeds, whose residual the selection explained) drops by
    `min_shrink` where the effect acts and does not rise over all windows (or by twice
    `min_shrink` there and rises by less than `slack`: on a floor control, `shrink_noise`,
    see `_floor_control`), or by twice
    `min_shrink` over all windows. Where it acts: the maneuver kind it was found in; for an
    effect found over all windows, the kinds where the candidate is active (`_active_kinds`;
    for a lag, the kinds that hold most of the change it makes), so that an effect of a few
    maneuver kinds is not diluted among all windows.

    The ensemble, not each seed: one net retrained on a few hundred peaks moves its held-out
    RMS by several percent by itself, so a median of per-seed shrinks still swings, where the
    median prediction averages that noise out.

    A lag must also have a time constant inside `lag_taus`: at the largest the fit wants ever
    more smoothing, which damps the nets' over-response in transients whether or not the
    vibration lags: a smoother, not a measured lag.

    Returns:
        The `Confirmation`: whether it confirms and why not, the trial's predictions and
        windows, metrics, shrinks, region and the ensemble's RMS before and after.
    """
    twin = _replay(ctx, trial.offset_s)
    tpred = predictions(ctx, trial, twin)
    prev = predictions(ctx, current, twin)  # the current model on the same windows
    tfull = twin.table.weight.to_numpy() >= 0.999
    region = _region(twin, tfull, prev, tpred)
    if where != "all":
        kinds = [where]
    elif c.operator == "lag":
        kinds = region["where"].split(", ")
    else:
        kinds = _active_kinds(twin.values(c)[tfull], twin.table.maneuver.to_numpy()[tfull])
    local_rows = tfull & np.isin(twin.table.maneuver.to_numpy(), kinds)
    t_ens, p_ens = np.median(tpred, axis=0)[None], np.median(prev, axis=0)[None]
    ens = (float(_rms_by_seed(p_ens, twin, tfull)[0]), float(_rms_by_seed(t_ens, twin, tfull)[0]))
    shrink = 1.0 - ens[1] / ens[0]
    local = float(1.0 - _rms_by_seed(t_ens, twin, local_rows)[0] / _rms_by_seed(p_ens, twin, local_rows)[0])
    # Twice `min_shrink` over all windows confirms wherever the gain lies: the active kinds are
    # a guess at where an effect acts (|q| is small but steady in turns and level flight, the
    # many windows where a pitch-rate effect's retraining gained on seed 54).
    where_it_acts = (local >= d.min_shrink and shrink > 0.0) or (local >= 2 * d.min_shrink and shrink > -slack)
    why = "" if where_it_acts or shrink >= 2 * d.min_shrink else "too small a shrink"
    if c.operator == "lag" and not _lag_identified(trial.lag_tau_s, _rules.LAG_TAUS):
        why = f"time constant at the grid's largest, {max(_rules.LAG_TAUS):g} s: a smoother, not a lag"
    return Confirmation(not why, why, tpred, twin, metrics(tpred, twin), shrink, local, region, ", ".join(kinds), ens)


def _control_refinements(refinements, c: Candidate) -> tuple:
    """The floor refinements a try of `c` is controlled by: those not built from any channel
    `c` is built from (`source_channels`). An effect that acts through the model's own inputs
    (a mode of rotor speed; the pitch rate, which the load factor carries) is partly a knee
    of them: a control holding that knee would test the effect against a piece of itself."""
    mine = source_channels(c.channels)
    return tuple(r for r in refinements if not source_channels(r.channels) & mine)


def _floor_control(ctx: _Ctx, current: Model, refinements) -> Model | None:
    """The current model retrained with the selection's floor refinements (knees and
    products of its own inputs) as extra network inputs; None without refinements.

    The selection asks a candidate beside those refinements, but the retraining that
    confirms it compares it with a model that has none: a misfit of the model's own inputs
    that the refinements describe, and a channel that follows those inputs (the shaft power,
    a stick, below a knee in descents and flares), both lower the current model's RMS. A try
    is also confirmed on top of this control (`_confirm` of the control with the try added
    the same way), where only an effect still lowers it; or, failing that, against the
    control with the try alone (`_confirm` of the try's model against the control's), where
    the control predicts at least as well as the current model (a try that beat the current
    model beats a worse control too). A floor proxy predicts no better than the refinements it
    stands for, while an effect still lowers the RMS on top of them. On a control, the RMS
    over all windows may rise by `shrink_noise` (the retraining's noise) where the try gains
    twice `min_shrink` where it acts: the control's inputs move every window, so an effect of
    a few maneuver kinds can gain where it acts and lose a little elsewhere."""
    if not refinements:
        return None
    control = current._replace(extra=current.extra + tuple(refinements))
    return control._replace(params=_train_model(ctx, control))


def _paired_errors(a, b) -> pd.DataFrame:
    """The squared errors of trials `a`'s and `b`'s ensembles (the median over seeds) on the
    windows both hold in full: counter, window, condition, maneuver, e2_a, e2_b. A trial is
    anything with `pred` and `win` (`Predicted`, `Confirmation`)."""
    def table(t):
        full = t.win.table.weight.to_numpy() >= 0.999
        e2 = (np.median(t.pred, axis=0) - t.win.table.measured_g.to_numpy()) ** 2
        return t.win.table.loc[full, ["counter", "window", "condition", "maneuver"]].assign(e2=e2[full])
    return table(a).merge(table(b), on=["counter", "window", "condition", "maneuver"], suffixes=("_a", "_b"))


def _paired_sign_flip(a, b, permutations: int, seed: int) -> tuple[float, float]:
    """Whether trial `b`'s ensemble predicts the measured windows better than `a`'s, on the
    windows both hold in full: per condition, the sum of the difference of their squared
    errors; their total against random sign flips (conditions are the independent units,
    windows of one condition are not).

    Returns:
        (one-sided p-value, 1 − b's squared error / a's).
    """
    both = _paired_errors(a, b)
    return _sign_flip_p(both, permutations, seed), _explained(both)


def _explained(both: pd.DataFrame) -> float:
    """1 − the second trial's squared error / the first's (`_paired_errors`' table)."""
    return float(1.0 - both.e2_b.sum() / both.e2_a.sum())


def _sign_flip_p(both: pd.DataFrame, permutations: int, seed: int) -> float:
    """One-sided p-value that e2_b < e2_a, by condition (`_paired_errors`' table)."""
    dc = (both.e2_a - both.e2_b).groupby(both.condition).sum().to_numpy()
    signs = np.random.default_rng(seed).choice([-1.0, 1.0], size=(permutations, len(dc)))
    return float((1 + np.sum(signs @ dc >= dc.sum())) / (permutations + 1))


# Sign flips of a paired test by condition (the lag test's; the tie of a round's tries: cheap).
_SIGN_FLIPS = 9999


def _region(win: _Windows, full, before, after) -> dict:
    """The maneuver kinds that hold ≥ 80 % of the squared change the effect made, with the
    RMS there before and after (medians over seeds)."""
    t = win.table[full]
    change = (np.median(after, axis=0) - np.median(before, axis=0))[full] ** 2
    share = pd.Series(change, index=t.maneuver.to_numpy()).groupby(level=0).sum().sort_values(ascending=False)
    share = share / max(share.sum(), 1e-30)
    kinds = list(share.index[: int(np.searchsorted(share.cumsum().to_numpy(), 0.8) + 1)])
    sel = t.maneuver.isin(kinds).to_numpy()
    meas = t.measured_g.to_numpy()[sel]
    rms = lambda p: float(np.median(np.sqrt(np.mean((p[:, full][:, sel] - meas) ** 2, axis=1))))  # noqa: E731
    return {"where": ", ".join(kinds), "before_rms_g": rms(before), "after_rms_g": rms(after)}


def _beyond_floor(control_shrink: float, min_shrink: float) -> bool:
    """Whether a try lowers the RMS over all windows by `min_shrink` on top of its floor
    control; a try without a control (NaN) counts as beyond: nothing says it is floor."""
    return not control_shrink < min_shrink


def _tied(shrink: float, best: float, p: float, noise: float, alpha: float, share: float) -> bool:
    """Whether a try of this shrink ties with the best's (`_choose`): within `noise` of it, or
    not beaten at p < `alpha` (p: that the best predicts better) with `share` of it."""
    return shrink >= best - noise or (p >= alpha and shrink >= share * best)


def _ties(tries, noise: float, alpha: float, min_shrink: float, share: float = 0.0) -> list[int]:
    """The indices of the tries `_choose` names among: those tied with the largest shrink,
    less those that do not gain beyond their floor control where some tied candidate does."""
    best = max(t[0] for t in tries)
    tied = [i for i, t in enumerate(tries) if _tied(t[0], best, t[2], noise, alpha, share)]
    beyond = {tries[i][3] for i in tied if _beyond_floor(tries[i][4], min_shrink)}
    return [i for i in tied if tries[i][3] in beyond] or tied


def _rival_encompasses(shares: tuple[float, float], margin: float) -> bool:
    """Whether a tied rival is named over the named try: it kept more of its coefficient on
    top of the named's term (shares: (rival's, named's)) by more than `margin`."""
    return shares[0] > shares[1] + margin


def _encompassed(k: int, tied, proposal, term, sources, measure, margin: float, shrink) -> int:
    """The encompassing test's choice (`encompassing`): each tied try `i` of another proposal,
    on other source channels, both proposals confirmed as terms, is compared with the named
    `k` in turn, and its proposal is named (its try of the largest shrink) where its term kept
    more of its coefficient on top of the named's than the named's on top of its own, by
    more than `margin`. Shared by the workflow (which retrains) and discovery_rechoose (which
    reads what was logged).

    Args:
        k: the named try's index. tied: `_ties`. proposal: each try's proposal.
        term, sources: a try's index -> whether its proposal confirmed as a term (lags and
            bands aside); its source channels.
        measure: (named index, rival index) -> (rival's share, named's share), or None where
            not measured. shrink: a try's index -> its shrink.

    Returns:
        The named try's index."""
    seen = {proposal[k]}
    for i in tied:
        if proposal[i] in seen or not term(k) or not term(i) or sources(i) & sources(k):
            continue
        seen.add(proposal[i])
        shares = measure(k, i)
        if shares is not None and _rival_encompasses(shares, margin):
            k = max((j for j, p in enumerate(proposal) if p == proposal[i]), key=shrink)
    return k


def _choose(tries, noise: float, alpha: float, min_shrink: float, share: float = 0.0) -> int:
    """Which confirmed try of a round is named. tries: (shrink, selection gain, p, candidate,
    control shrink) of each: p the one-sided p-value that the try of the largest shrink
    predicts better than this one (`_paired_sign_flip` by condition; 1 for that try itself),
    the gain NaN for a try the selection did not rank (the resonance probe's band), candidate
    any label shared by the tries of one proposal (its ways of being added), and the control
    shrink the try's shrink over all windows on top of its floor control (NaN without one).

    The retraining decides first: the try that lowers the ensemble's RMS over all windows most
    (the same windows for every try). Tries it does not beat significantly (p ≥ `alpha`), or
    that come within `noise` of its shrink (a retrained placebo input moves the ensemble's RMS
    by < 2 %), are tied, and of those the one the selection credits with the largest held-out
    gain is named: one column against the same residual on every window is the finer
    comparison of two retrainings' noise (then the larger shrink). Measured: two proxies of a
    collective stall knee, retrained, lower the RMS 22.0 % (shaft power) and 17.1 % (the
    collective), p = 0.03 by condition: a tie the selection decides (the collective, 0.250 against 0.239).
    Not beaten significantly ties a try only if its shrink is at least `share` (`tie_share`)
    of the best's: the sign-flip test by condition asks how consistently the best wins, not
    by how much, and an effect of a few conditions cannot win consistently over many. Measured
    on weight missing 52 (fresh seeds + 11): blade loading 22.9 %, a pitch-attitude knee 7.7 %,
    p = 0.012, and the knee's gain (0.117 against 0.095) named it; on all 87 logged rounds
    with a confirmed try, shares from 0.35 to 0.6 change that choice alone (0.67 also
    pitch rate 58's, the truth's 12.5 % against a shaft-power knee's 19.9 %).

    Beyond the floor first: if some tied candidate lowers the RMS over all windows by
    `min_shrink` on top of its floor control (in one of its tied tries, or has no control),
    the tied candidates that do not are left out. Those confirmed on their control only where
    they act: most of their gain over all windows is what the floor's refinements explain. On
    pitch rate 51 the yaw rate (a proxy of |q| in turns) and its knee tied with |q| (7.8 %,
    5.4 % and 6.1 %, p ≥ 0.17) and had the larger gains (0.072 against 0.063); on top of their
    controls they kept 2.0 % and 2.8 % over all windows (14–17 % in turns), |q| 9.4 %.

    A tied try without a selection gain competes with the selection's pick on the shrink
    alone: a probe's band is a column the selection cannot credit (a mode the nets learned as
    a mean per rotor-speed level leaves no prediction × band residual), so its gain, ~0, says
    nothing about it.
    """
    tied = _ties(tries, noise, alpha, min_shrink, share)
    ranked = [i for i in tied if np.isfinite(tries[i][1])]
    pick = [max(ranked, key=lambda i: (tries[i][1], tries[i][0]))] if ranked else []
    return max(pick + [i for i in tied if not np.isfinite(tries[i][1])], key=lambda i: tries[i][0])


def _rival(named: int, tries, alternatives, channels, taken, min_shrink: float, min_gain: float):
    """A second opinion on a weak name: the column of the selection's runner-up to retrain
    beside the named try, or None.

    A name is weak when none of its proposal's confirmed tries lowers the RMS over all
    windows by `min_shrink` on top of its floor control: it predicts little beyond the
    refinements of the model's own inputs. Then a proxy may have outscored the effect it
    stands for (a pilot input ahead of the aircraft's response: on pitch acceleration 31 the
    rate of the longitudinal stick, gain 0.093, ahead of |q̇|, 0.082, which the paired
    one-standard-error rule sets apart; retrained, both lower the RMS ~9 %, on top of their
    controls 3.8 % and 8.0 %). The rival is the best of the named selection's runners-up that
    gains `min_gain` and is built from none of the campaign channels the round's proposals
    were (a spread of the same channel is the same source, not a rival); `_choose` then
    decides among all the confirmed tries, its "beyond the floor first" included.

    Args:
        named: index in `tries` of the named try. tries: `_choose`'s (shrink, gain, p,
            proposal, control shrink) of the round's confirmed tries.
        alternatives: ((column, gain), ...) of the named try's selection (`Selected`), best
            first. channels: the candidate's channels of each column. taken: the campaign
            channels the round's proposals are built from (`source_channels`).

    Returns:
        (column, gain) or None (a strong name, or no runner-up on other channels).
    """
    if any(_beyond_floor(t[4], min_shrink) for t in tries if t[3] == tries[named][3]):
        return None
    for col, g in alternatives:
        if g >= min_gain and not source_channels(channels[col]) & set(taken):
            return col, g
    return None
