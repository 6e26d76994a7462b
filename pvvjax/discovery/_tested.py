"""Discovery's decision as one calibrated test: the baseline's misfit named by form and
taken off its out-of-fold residual, what is left explained (`misfits`, `explain`), the named
effects' parameters fitted by gradient with their spread over a bootstrap of conditions,
then added to the model, which is retrained once.

Candidates are the library of the window table (channels, magnitudes, rates, spreads, knees,
bands, products) at the model's offset, and the responses: first-order lags of the model's
own prediction corrected by the misfit's forms (the lagged prediction minus the prediction)
over a grid of time constants that places the start of the fit (a named lag's τ moves within
a factor 2 of its grid point).
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np
import pandas as pd

from ._explain import Explanation, Named, explain, misfits, out_of_fold_linear, tested_column
from ._fits import _refine, fit_lag
from ._model import Model, _Ctx, _lag_windows, _replay, _Windows, metrics, predictions
from ._train import _region, _train_model
from .candidates import Candidate, library

# Time constants of the lag candidates, s: a log grid from the rotor's fast response to lags
# slower than most maneuvers (a named lag's τ is then fitted within a factor 2 of its point).
LAG_TAUS = tuple(float(0.25 * 2 ** (k / 2)) for k in range(13))

# Draws of the bootstrap over conditions that gives each fitted parameter its interval.
BOOTSTRAP = 40

# A band's learned gain is trained in steps of 1 / GAIN_UNIT: Adam moves every parameter by
# about one step, and in unit steps the nets' many weights take the mode before the one gain
# grows.
GAIN_UNIT = 10.0

# The interval of a fitted parameter: these quantiles of its bootstrap draws.
INTERVAL = (0.05, 0.95)


class Fitted(NamedTuple):
    """A named candidate with its parameters fitted on all conditions and their interval
    (`INTERVAL` quantiles over the bootstrap), one (low, high) per fitted parameter."""

    named: Named
    candidate: Candidate
    intervals: dict


def response_candidates(yhat, win: _Windows, taus=LAG_TAUS) -> tuple[list[Candidate], np.ndarray]:
    """Lags of the model's prediction `yhat` (n,) on its replay windows: candidates and their
    (n, len(taus)) columns, the lagged prediction minus the prediction."""
    cols = [_lag_windows(yhat[None], win, t)[0] - yhat for t in taus]
    return [Candidate("lag", (), {"tau_s": float(t)}) for t in taus], np.column_stack(cols)


def bootstrap_weights(groups, draws: int, seed: int) -> np.ndarray:
    """(draws, n) weights of a bootstrap over units: each draw deals the units with
    replacement, and a row weighs as often as its unit was drawn (every shape kept)."""
    units, inverse = np.unique(np.asarray(groups), return_inverse=True)
    counts = np.random.default_rng(seed).multinomial(len(units), np.full(len(units), 1.0 / len(units)), size=draws)
    return counts[:, inverse].astype(float)


def _interval(draws) -> tuple[float, float]:
    lo, hi = np.quantile(np.asarray(draws, float), INTERVAL)
    return float(lo), float(hi)


def _fit(n: Named, ctx: _Ctx, win: _Windows, rows, yhat, resid, table: pd.DataFrame, base, groups) -> Fitted:
    """A named candidate's parameters on all conditions, then on each bootstrap draw of
    conditions (the same fit, from where the test named it): a lag's τ (of the prediction
    `yhat`, all windows), a knee, a band's centre and width (of the residual `resid` on
    `rows`, beside the covariates `base`)."""
    c, seed = n.candidate, ctx.cfg.seed
    meas = win.table.measured_g.to_numpy()
    weights = bootstrap_weights(groups, BOOTSTRAP, seed)
    # Each bootstrap draw repeats the whole fit, from the same start and within the same
    # bounds (the estimator's own search space), so the interval is the spread of the estimate.
    if c.operator == "lag":
        tau = fit_lag(yhat, meas, win, rows, c.parameters["tau_s"])
        draws = [fit_lag(yhat, meas, win, rows, c.parameters["tau_s"], weights=w) for w in weights]
        return Fitted(n, replace(c, parameters={"tau_s": tau}), {"tau_s": _interval(draws)})
    if c.operator not in ("threshold", "resonance"):
        return Fitted(n, c, {})
    fitted = _refine(c, resid[rows], table, yhat[rows], base=base)
    names = ("knee",) if c.operator == "threshold" else ("center", "width")
    draws = [_refine(c, resid[rows], table, yhat[rows], base=base, weights=w).parameters for w in weights]
    return Fitted(n, fitted, {k: _interval([d[k] for d in draws]) for k in names})


def linear_shift(ctx: _Ctx, win: _Windows, y, candidates) -> np.ndarray:
    """(n,) the `candidates`' columns (`tested_column` beside the prediction `y`, (n,) per
    window) fitted to the residual of `y` out of fold by condition (the ensemble's folds, on
    the fully weighted windows), on every window: what a linear term of them adds to `y`."""
    if not candidates:
        return np.zeros(len(y))
    cols = np.column_stack([tested_column(c, win.cands, y) for c in candidates])
    fold = ctx.counter_fold[win.table.i.to_numpy()]
    return out_of_fold_linear(cols, win.table.measured_g.to_numpy() - y, win.table.weight.to_numpy() >= 0.999, fold)


def _tested_windows(win: _Windows, pred):
    """What the test and the fits see of the replay windows: the fully weighted rows (mask),
    the ensemble's median prediction and the measured level (all windows), the candidates'
    window table and each window's condition on those rows."""
    rows = win.table.weight.to_numpy() >= 0.999
    return (rows, np.median(pred, axis=0), win.table.measured_g.to_numpy(), win.cands[rows].reset_index(drop=True),
            win.table.condition.astype(str).to_numpy()[rows])


def tested(ctx: _Ctx, win: _Windows, pred, inputs, log=print, exclude=()) -> tuple[Explanation, np.ndarray]:
    """Explain the residual of a baseline (its held-out predictions `pred`, seeds × windows,
    on the replay windows `win`) beyond any function of its `inputs` (`x:` columns of the
    window table) at `discovery.level`.

    The misfit comes first (`misfits`); its forms' out-of-fold fit joins the prediction on
    every window; the forms of the inputs' history, lags of that corrected prediction among
    them, then the missing candidates are tested against what is left (`explain`).

    Args:
        exclude: channels never offered as candidates here (a simulation's own column).

    Returns:
        The `Explanation`, and the prediction corrected by the misfit's forms, (n,) per window.
    """
    d = ctx.cfg.discovery
    rows, yhat, meas, table, groups = _tested_windows(win, pred)
    lib = [c for c in library(table, model_inputs=inputs) if not set(c.channels) & set(exclude)]
    common = dict(level=d.level, folds=d.ensemble.folds, seed=ctx.cfg.seed, max_named=d.max_effects)
    m = misfits(meas[rows] - yhat[rows], table, inputs, groups, candidates=lib, prediction=yhat[rows], **common)
    yc = yhat + linear_shift(ctx, win, yhat, [n.candidate for n in m.named])
    lags, L = response_candidates(yc, win)
    ex = explain(meas[rows] - yc[rows], table, inputs, groups, candidates=lib, responses=(lags, L[rows]),
                 prediction=yc[rows], given=m, **common)
    log(f"capacity of the baseline: t = {ex.capacity.statistic:.2f}, p = {ex.capacity.p_value:.3g}; "
        f"{len(ex.tests)} tests at {d.level:g} family-wise, named: "
        + (", ".join(f"{n.candidate.name} ({n.kind}, p = {n.adjusted_p:.2g})" for n in ex.named) or "none"))
    if ex.nuisance is not None and len(ex.nuisance):
        log("nuisance regressions' out-of-fold skill (1 - SSE/SST): residual " + ", ".join(
            f"{r.kind} round {r.round} {r.residual_learner} {r.residual_skill:.2f}" for r in ex.nuisance.itertuples())
            + f"; candidates' median {ex.nuisance.candidates_median_skill.median():.2f}")
    return ex, yc


def fitted(ctx: _Ctx, win: _Windows, pred, corrected, ex: Explanation, inputs) -> tuple[Fitted, ...]:
    """The named candidates of `ex` with their parameters fitted and their intervals: each
    misfit form against the baseline's residual beside the other forms named (two knees of one
    channel stay apart), each missing one against the residual of the `corrected` prediction
    beside the inputs."""
    rows, yhat, meas, table, groups = _tested_windows(win, pred)
    Z = table[[f"x:{k}" for k in inputs]].to_numpy(float)
    forms = [n for n in ex.named if n.kind == "misfit"]
    out = []
    for n in ex.named:
        if n.kind == "misfit":
            others = [tested_column(o.candidate, table, yhat[rows]) for o in forms if o is not n]
            out.append(_fit(n, ctx, win, rows, yhat, meas - yhat, table, np.column_stack(others) if others else None,
                            groups))
        else:
            out.append(_fit(n, ctx, win, rows, corrected, meas - corrected, table, Z, groups))
    return tuple(out)


def with_effects(ctx: _Ctx, model: Model, fitted) -> Model:
    """The model with the fitted effects: the misfit's forms as its linear term (`Model.linear`:
    a function of its own inputs, which as more net inputs the nets would refit from a few
    hundred peaks), and the missing effects by retraining it once: a lag of its prediction,
    a band as a learned gain on the nets' output (a mode magnifies the whole response), any
    other candidate as a network input at the model's offset. The offset stays the model's:
    the effects were tested and fitted at it (a lag's τ given it), so before and after differ
    by the effects alone."""
    extra, gains, tau = list(model.extra), list(model.gains), model.lag_tau_s
    linear = list(model.linear)
    for f in fitted:
        c = f.candidate
        if f.named.kind == "misfit":
            linear.append(c)
        elif c.operator == "lag":
            tau = c.parameters["tau_s"]
        elif c.operator == "resonance":
            gains.append(replace(c, parameters={**c.parameters, "gain_unit": GAIN_UNIT}))
        else:
            extra.append(replace(c, parameters={**c.parameters, "offset_s": model.offset_s}))
    trial = model._replace(extra=tuple(extra), gains=tuple(gains), lag_tau_s=tau, linear=tuple(linear))
    retrain = (trial.extra, trial.gains, trial.lag_tau_s) != (model.extra, model.gains, model.lag_tau_s)
    return trial._replace(params=_train_model(ctx, trial)) if retrain else trial


def effect_region(win: _Windows, before, after) -> dict:
    """Where the added effects changed the prediction ((S, n) before and after on `win`):
    the maneuver kinds holding 80 % of the squared change, with the held-out RMS there
    before and after."""
    return _region(win, win.table.weight.to_numpy() >= 0.999, before, after)


def held_out(ctx: _Ctx, model: Model) -> tuple[np.ndarray, _Windows, dict]:
    """A model's held-out predictions (seeds, n) on its replay windows, its linear term added
    (fitted to the ensemble median's residual, `linear_shift`), and their `metrics`."""
    win = _replay(ctx, model.offset_s)
    pred = predictions(ctx, model, win)
    if model.linear:
        pred = pred + linear_shift(ctx, win, np.median(pred, axis=0), model.linear)[None]
    return pred, win, metrics(pred, win)
