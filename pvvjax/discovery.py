"""Discovery: find where simulation and measurement disagree, name the missing effect, add
it to the model and show the gap shrink (data-contract §3).

1. **Baseline.** Nets of one database, trained k-fold by condition over several seeds
   (`fit_ensemble`) on its peak rows. Every counter is replayed by the nets that held its
   condition out; the input-to-vibration offset is fitted on the held-out windows. (With
   `train_rows = "windows"` the nets are then retrained on the replay windows at that offset.)
   With `lag_test`, window nets trained *through* lags of several time constants (`delag`)
   then ask whether the vibration lags the state more slowly than the fast dynamics the
   offset stands for (`_lag_test`); a confirmed slow lag is the first effect, its reference
   (the best nets without one) the baseline, and every later model trains through it.
2. **Localize.** Window residuals (measured − predicted, median over seeds) by maneuver
   kind, flight regime and position inside the maneuvers (`residuals.localize`).
3. **Explain.** The candidate library (`candidates`) and lags of the model's own
   prediction, ranked by forward selection with cross-validation by condition and a
   selection-aware block permutation test (`selection.forward_select`). A chosen knee,
   resonance or time constant is then refined by least squares (optimistix LM).
4. **Add and confirm.** A candidate becomes an extra network input (each condition's
   database row gets the candidate at its peak window, and the nets are retrained with the
   same folds and seeds); a lag becomes a learned first-order lag of the replayed
   prediction (offset and τ refitted); a resonance becomes a gain on the nets' output,
   1 + a·band(rotor speed), with a trained jointly with the nets (`gain_apply`: a structural
   mode magnifies the whole 4P response). The effect is kept only if the held-out RMS of the
   ensemble's prediction (median over seeds) drops by `min_shrink`: a candidate that only re-expresses the static map's
   error floor, or retraining noise, gains nothing once the nets are retrained with it.
   Then the next round, until nothing significant confirms.

The workflow reads the campaign only (never a generator's ground truth).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pandas as pd

from . import train as _train
from .batch import to_batch
from .campaign import Campaign, load_campaign
from .candidates import Candidate, library, sample_series, values, window_table, window_tables
from .config import DiscoveryConfig, ExperimentConfig
from .databases import DB_INPUTS, OUTPUT, STATE_CHANNELS, build_databases
from .effects import lag as _lag
from .networks import mlp_apply, mlp_init, scaling
from .replay import FEATURES, input_index, make_settings, prepare
from .replay_tables import _replay_all
from .residuals import localize
from .selection import Selected as _Selected
from .selection import _standardise, forward_select, gains
from .selection import gain as _selection_gain
from .sweep import _stack, train_nets

__all__ = [
    "Discovery",
    "Model",
    "Residual",
    "delag",
    "discover",
    "fit_ensemble",
    "floor_features",
    "gain_apply",
    "knn_floor",
    "metrics",
    "selection_gain",
    "summary",
]

TRANSIENT = ("pullup", "pushover", "roll", "autorotation", "flare")
# The canonical inputs each derived feature is computed from (`features`): a derived feature
# belongs to a model's own inputs when they include all of these.
_DERIVED_FROM = {
    "advance_ratio": ("advance_ratio",), "mlf": ("mlf",),
    "thrust_coefficient": ("gross_weight_lb", "density_ratio", "rotor_rpm"),
    "blade_loading": ("gross_weight_lb", "density_ratio", "rotor_rpm", "mlf"),
}


# Campaign channels that the model's inputs determine exactly (airspeed = μ·ΩR).
_DETERMINED_BY = {"airspeed_kt": ("advance_ratio", "rotor_rpm")}


def floor_features(inputs) -> tuple[str, ...]:
    """The model's inputs and the derived features computed from them alone: a static map
    on these can express anything built from them, so a misfit in them is the map's error
    floor (too few peaks to learn it), not a missing effect."""
    return tuple(inputs) + tuple(k for k, src in _DERIVED_FROM.items() if k not in inputs and set(src) <= set(inputs))


def _determined(inputs) -> tuple[str, ...]:
    """`floor_features` and the campaign channels the inputs determine exactly: a knee of
    airspeed is a knee of the advance ratio at the rotor speed, which the map has."""
    own = floor_features(inputs)
    return own + tuple(k for k, src in _DETERMINED_BY.items() if k not in own and set(src) <= set(own))


# --------------------------------------------------------------------------- networks


def gain_apply(params: dict, x):
    """A net whose output is multiplied by a learned gain, 1 + Σ_j gain_j·x_j, over the last
    `len(params["gain"])` columns of x (e.g. a rotor-speed resonance band): the nets learn the
    response, the gain its magnification, jointly (a structural mode amplifies every 4P
    load, which a map of ~200 peaks cannot learn as an interaction of its inputs)."""
    g = params["gain"]
    n = g.shape[-1]
    return mlp_apply(params, x[..., :-n]) * (1.0 + x[..., -n:] @ g)


def fit_ensemble(x, y, folds, *, k: int, seeds: int, hidden, train_cfg, seed: int = 0, n_gain: int = 0) -> dict:
    """Nets trained k-fold by condition over seeds (validation: the next fold).

    Args:
        x: (n, d) inputs. y: (n,) peak PVV, or (k, n) a target per fold. folds: (n,) fold of
            each row (by condition).
        k, seeds: folds and seeds. hidden: hidden widths. train_cfg: `TrainConfig`.
        n_gain: the last `n_gain` columns of x are gain columns (`gain_apply`), not inputs.

    Returns:
        Parameters stacked (k, seeds, ...): entry (f, s) never saw fold f.
    """
    x, y = np.asarray(x, np.float32), np.asarray(y, np.float32)
    y = np.broadcast_to(y, (k, x.shape[0]))
    splits = [_train.split_masks(folds, f, k) for f in range(k)]
    n_tr = max(int(w.sum()) for w, _, _ in splits)
    n_va = max(int(v.sum()) for _, v, _ in splits)
    data = [_train.make_data(x, y[f], w, v, n_tr, n_va) for f, (w, v, _) in enumerate(splits)]
    params = []
    n_in = x.shape[1] - n_gain
    gain = {"gain": jnp.zeros(n_gain)} if n_gain else {}
    for f, (w, _, _) in enumerate(splits):
        sc = scaling(x[w > 0][:, :n_in], y[f][w > 0])
        params += [{**mlp_init(jax.random.key(seed + s), n_in, tuple(hidden), scale=sc), **gain} for s in range(seeds)]
    fits = train_nets(_stack(params), _stack(data), np.repeat(np.arange(k), seeds), train_cfg,
                      apply=gain_apply if n_gain else mlp_apply)
    if np.any(np.asarray(fits.failed_step) >= 0):
        raise _train.TrainingError("discovery: a net diverged; lower train.learning_rate")
    return jax.tree.map(lambda a: np.asarray(a).reshape((k, seeds) + a.shape[1:]), fits.params)


_apply_seeds = {f: jax.jit(jax.vmap(f, in_axes=(0, None))) for f in (mlp_apply, gain_apply)}


def _predict(params, fold, x) -> np.ndarray:
    """(S, n) predictions of each seed's net that held out each row's fold."""
    S = jax.tree.leaves(params)[0].shape[1]
    apply = _apply_seeds[gain_apply if "gain" in params else mlp_apply]
    out = np.zeros((S, len(fold)), np.float64)
    for f in np.unique(fold):
        rows = fold == f
        out[:, rows] = np.asarray(apply(jax.tree.map(lambda a: a[f], params), jnp.asarray(x[rows], jnp.float32)))
    return out


# --------------------------------------------------------------------------- model and replay


class Model(NamedTuple):
    """A model under discovery: nets, extra inputs, additive effect terms, gains, offset
    and an optional learned lag.

    Attributes:
        params: nets (k, seeds, ...). inputs: database inputs. extra: candidates added as
        network inputs. terms: (candidate, (k, 2) intercept and coefficient per fold)
        added to the nets' output (the nets are trained on the peaks minus the terms).
        gains: candidates whose learned gain multiplies the nets' output (`gain_apply`; the
        coefficients are in `params["gain"]`).
        offset_s: input-to-vibration offset, s. lag_tau_s: first-order lag of the replayed
        prediction, s (0: none). through_lag: the nets train on the replay windows with the
        lag undone in their targets (`delag`), as the lag test trains them, whatever
        `train_rows` says.
    """

    params: dict
    inputs: tuple[str, ...]
    extra: tuple[Candidate, ...] = ()
    offset_s: float = 0.0
    lag_tau_s: float = 0.0
    terms: tuple = ()
    gains: tuple = ()
    through_lag: bool = False


@dataclass
class _Ctx:
    campaign: Campaign
    cfg: ExperimentConfig
    db: pd.DataFrame
    x_db: np.ndarray
    folds: np.ndarray
    info: pd.DataFrame
    counter_fold: np.ndarray
    batch: object
    recs: object
    settings: object
    train_table: pd.DataFrame
    replay_params: dict
    cache: dict = field(default_factory=dict)


@dataclass
class _Windows:
    """Replayed windows at one offset (weight > 0), flattened, and their (N, W) layout."""

    table: pd.DataFrame  # counter, condition, maneuver, window, time_s, t0, t1, measured_g, weight, FEATURES, i, k
    shape: tuple[int, int]
    exclude: tuple
    campaign: Campaign
    _cands: pd.DataFrame | None = None
    offset: float = 0.0
    _shifted: dict = field(default_factory=dict)

    @property
    def cands(self) -> pd.DataFrame:
        """`candidates.window_table` of the same rows (computed on first use)."""
        if self._cands is None:
            self._cands = window_table(self.campaign, self.table[["counter", "t0", "t1"]], self.exclude)
        return self._cands

    def at(self, offset: float, extra=None) -> pd.DataFrame:
        """Window means with the input windows `offset` s before the measured windows
        (the replay's own offset: `cands`); only the channels of `extra` if given and the
        full table is not computed yet."""
        if abs(offset - self.offset) < 1e-9 and (extra is None or self._cands is not None):
            return self.cands
        key = round(float(offset), 6)
        if key in self._shifted:
            return self._shifted[key]
        iv = self._shift(offset)
        chans = None if extra is None else {ch for c in extra for ch in c.channels}
        out = window_table(self.campaign, iv, self.exclude, channels=chans)
        if extra is None:
            self._shifted[key] = out
        return out

    def _shift(self, offset: float) -> pd.DataFrame:
        return self.table[["counter", "t0", "t1"]].assign(t0=self.table.t0 + self.offset - offset,
                                                         t1=self.table.t1 + self.offset - offset)

    def prefetch(self, offsets) -> None:
        """Compute the full tables at these offsets that `at` has not computed yet, in one
        pass over the records (`window_tables`: a record's series once for all offsets)."""
        todo = {}  # key -> (own offset?, offset), as `at` would compute them
        for off in offsets:
            own, key = abs(off - self.offset) < 1e-9, round(float(off), 6)
            if ((self._cands is None) if own else (key not in self._shifted)) and key not in todo:
                todo[key] = (own, off)
        if len(todo) < 2:  # nothing to share
            return
        ivs = [self.table[["counter", "t0", "t1"]] if own else self._shift(off) for own, off in todo.values()]
        for (key, (own, _)), tab in zip(todo.items(), window_tables(self.campaign, ivs, self.exclude)):
            if own:
                self._cands = tab
            else:
                self._shifted[key] = tab

    def values(self, c: Candidate) -> np.ndarray:
        """A candidate's value per window, at its own alignment (`offset_s` parameter)."""
        return values(c, self.at(c.parameters.get("offset_s", self.offset), (c,)))


def _replay(ctx: _Ctx, offset: float) -> _Windows:
    key = round(float(offset), 6)
    if key in ctx.cache:
        return ctx.cache[key]
    d = ctx.cfg.discovery
    N = len(ctx.info)
    L = ctx.cfg.analysis.window_revs
    theta = jnp.asarray(np.tile([offset, L, 0.0], (N, 1)), jnp.float32)
    model = dict(params=jax.tree.map(lambda a: jnp.asarray(a[ctx.counter_fold]), ctx.replay_params),
                 idx=jnp.asarray(np.tile(input_index(d.database, len(DB_INPUTS[d.database])), (N, 1))))
    rep = jax.device_get(_replay_all(model, ctx.recs, theta, settings=ctx.settings))
    W = rep.time.shape[1]
    # Input windows in record time: measured window edges (revolutions) -> time -> − offset.
    a = np.asarray(ctx.recs.rev_start)[:, None] + d.hop_revs * np.arange(W)[None, :]
    t0 = np.zeros((N, W))
    t1 = np.zeros((N, W))
    for i in range(N):
        m = np.asarray(ctx.batch.mask[i])
        rev, t = np.asarray(ctx.batch.rev[i])[m], np.asarray(ctx.batch.time[i])[m]
        t0[i], t1[i] = np.interp(a[i], rev, t) - offset, np.interp(a[i] + L, rev, t) - offset
    ii, kk = np.nonzero(np.asarray(rep.weight) > 0)
    tab = pd.DataFrame({
        "counter": ctx.info.index.to_numpy()[ii], "condition": ctx.info.condition.to_numpy()[ii],
        "maneuver": ctx.info.maneuver.to_numpy()[ii], "window": kk, "time_s": rep.time[ii, kk],
        "t0": t0[ii, kk], "t1": t1[ii, kk], "measured_g": rep.measured[ii, kk], "weight": rep.weight[ii, kk],
        **{f: rep.features[ii, kk, j] for j, f in enumerate(FEATURES)}, "i": ii, "k": kk,
    })
    out = _Windows(tab, (N, W), d.exclude_channels, ctx.campaign, offset=float(offset))
    ctx.cache[key] = out
    return out


def _fill_leading(y, valid):
    """Windows before a counter's first valid one take its value (a lag starts at rest)."""
    first = np.argmax(valid, axis=-1)
    idx = np.maximum(np.arange(y.shape[-1])[None, :], first[:, None])
    return np.take_along_axis(y, np.broadcast_to(idx, y.shape), axis=-1)


def _grid(win: _Windows):
    """The (N, W) layout of a window table: row/column of each window, a `to_grid`
    function (values per window -> (N, W), leading gaps filled), and increasing times."""
    N, W = win.shape
    i, k = win.table.i.to_numpy(), win.table.k.to_numpy()
    valid = np.zeros((N, W), bool)
    valid[i, k] = True

    def to_grid(v):
        g = np.zeros((N, W))
        g[i, k] = v
        return _fill_leading(g, valid)

    times = np.maximum.accumulate(to_grid(win.table.time_s.to_numpy()) + 1e-9 * np.arange(W), axis=1)
    return i, k, to_grid, times  # padding past the last window: increasing times


def _lag_windows(pred, win: _Windows, tau: float) -> np.ndarray:
    """A first-order lag of (S, n) window predictions along each counter's window times."""
    if tau <= 0:
        return pred
    i, k, to_grid, times = _grid(win)
    out = np.empty_like(pred)
    for s in range(pred.shape[0]):
        out[s] = np.asarray(_lag_grid(jnp.asarray(to_grid(pred[s])), jnp.asarray(times), tau))[i, k]
    return out


_lag_grid = jax.jit(jax.vmap(_lag, in_axes=(0, 0, None)))


def delag(y, time_s, counter, tau_s: float, span: int = 4) -> np.ndarray:
    """The input of a first-order lag whose output is `y`: u = y + τ·dy/dt per counter.

    dy/dt is a central difference over ±`span` windows (one-sided at a counter's ends): an
    8-revolution window series is smooth over that span, and a shorter difference would
    amplify the harmonic analysis' noise by τ/Δt.

    Args:
        y, time_s, counter: (n,) window values, their times, s, and the counter of each
            (windows of one counter in any order). tau_s: time constant, s (0: `y` itself).
        span: half-width of the difference, windows.

    Returns:
        (n,) the de-lagged series.
    """
    y, t = np.asarray(y, float), np.asarray(time_s, float)
    if tau_s <= 0:
        return y.copy()
    out = np.empty_like(y)
    for idx in pd.Series(np.arange(len(y))).groupby(np.asarray(counter)).indices.values():
        idx = idx[np.argsort(t[idx], kind="stable")]
        n = np.arange(len(idx))
        lo, hi = idx[np.maximum(n - span, 0)], idx[np.minimum(n + span, len(idx) - 1)]
        dt = t[hi] - t[lo]
        out[idx] = y[idx] + tau_s * np.divide(y[hi] - y[lo], dt, out=np.zeros(len(idx)), where=dt > 0)
    return out


def _inputs(model: Model, win: _Windows) -> np.ndarray:
    """The nets' columns: database inputs, extra inputs, then the gains' candidates."""
    x = win.table[list(model.inputs)].to_numpy(np.float64)
    if model.extra or model.gains:
        x = np.column_stack([x] + [win.values(c) for c in model.extra + model.gains])
    return x


def _terms(model: Model, value, fold) -> np.ndarray:
    """The additive effect terms of a model, (n,); `value(candidate)` gives its values."""
    out = np.zeros(len(fold))
    for c, coef in model.terms:
        out += coef[fold, 0] + coef[fold, 1] * value(c)
    return out


def predictions(ctx: _Ctx, model: Model, win: _Windows) -> np.ndarray:
    """(S, n) held-out predictions of every window (weight > 0), per seed."""
    fold = ctx.counter_fold[win.table.i.to_numpy()]
    pred = _predict(model.params, fold, _inputs(model, win))
    if model.terms:
        pred = pred + _terms(model, win.values, fold)[None]
    return _lag_windows(pred, win, model.lag_tau_s)


def metrics(pred, win: _Windows, full=None) -> dict:
    """Held-out metrics of (S, n) predictions on the fully weighted windows, median over seeds.

    rms_g: RMS of measured − predicted over the windows. peak_error_g: mean over counters of
    |predicted − measured peak|. phase_error_s: mean over transient-maneuver counters of
    |predicted − measured peak time|. ensemble_rms_g: the RMS of the ensemble's prediction
    (the median over seeds), which the confirmation measures: one net moves its RMS by a
    few percent by itself, the ensemble averages that out.
    """
    t = win.table
    full = (t.weight.to_numpy() >= 0.999) if full is None else full
    meas, time_s, ctr = t.measured_g.to_numpy()[full], t.time_s.to_numpy()[full], t.counter.to_numpy()[full]
    trans = t.maneuver.isin(TRANSIENT).to_numpy()[full]
    code = np.unique(ctr, return_inverse=True)[1]
    order = np.argsort(code, kind="stable")  # windows grouped by counter, in time order
    bounds = np.searchsorted(code[order], np.arange(code.max() + 1))
    ends = np.append(bounds[1:], len(order))
    mo, to, tr = meas[order], time_s[order], trans[order][bounds]
    t_m = to[[b + np.argmax(mo[b:e]) for b, e in zip(bounds, ends)]]
    per = []
    for p in np.atleast_2d(pred)[:, full]:
        po = p[order]
        peak_err = np.maximum.reduceat(po, bounds) - np.maximum.reduceat(mo, bounds)
        phase = np.abs(to[[b + np.argmax(po[b:e]) for b, e in zip(bounds, ends)]] - t_m)[tr]
        per.append((float(np.sqrt(np.mean((p - meas) ** 2))), float(np.mean(np.abs(peak_err))),
                    float(np.mean(phase)) if phase.size else 0.0))
    per = np.array(per)
    med = np.median(per, axis=0)
    ens = _rms_by_seed(np.median(np.atleast_2d(pred), axis=0)[None], win, full)[0]
    return dict(rms_g=float(med[0]), peak_error_g=float(med[1]), phase_error_s=float(med[2]), rms_by_seed=per[:, 0],
                ensemble_rms_g=float(ens))


# --------------------------------------------------------------------------- fits


# The least-squares residuals are module functions with their data in `args` (optimistix's
# fn(y, args)): a closure over the arrays would make them constants of the compiled solve, and
# XLA would compile a new solve (~3 s) for every candidate and every fit.
def _tau_residuals(log_tau, args):
    y, tg, i, k, target = args
    return _lag_grid(y, tg, jnp.exp(log_tau))[i, k] - target


def _band(theta, center, width):
    """A resonance band kept in its grid cell: centre within one width, width within a factor 2."""
    return center + width * jnp.tanh(theta[0]), width * 2.0 ** jnp.tanh(theta[1])


def _refine_residuals(theta, args):
    x, r, yhat, B, softness, center, width, operator, above = args  # operator, above: static
    if operator == "threshold":
        u = (x - theta[0]) if above else (theta[0] - x)
        column = softness * jax.nn.softplus(u / softness)
    else:
        c, w = _band(theta, center, width)
        column = yhat * jnp.exp(-0.5 * ((x - c) / w) ** 2)
    A = jnp.column_stack([B, column])
    coef = jnp.linalg.lstsq(A, r)[0]
    return r - A @ coef


def _fit_tau(yhat, meas, win: _Windows, full, taus, refine: bool = True) -> tuple[float, float]:
    """Time constant of a lag of the (ensemble) prediction that best fits the measured PVV:
    the best of `taus`, refined (if `refine`) by Levenberg–Marquardt in log τ. Returns (τ, SSE)."""
    sse = [float(np.sum((_lag_windows(yhat[None], win, t)[0][full] - meas[full]) ** 2)) for t in taus]
    t_best = float(taus[int(np.argmin(sse))])
    if not refine:
        return t_best, min(sse)
    i, k, to_grid, tg = _grid(win)
    args = (jnp.asarray(to_grid(yhat)), jnp.asarray(tg), jnp.asarray(i[full]), jnp.asarray(k[full]),
            jnp.asarray(meas[full]))
    sol = optx.least_squares(_tau_residuals, optx.LevenbergMarquardt(rtol=1e-6, atol=1e-9), jnp.log(t_best), args,
                             max_steps=64, throw=False)
    tau = float(jnp.exp(sol.value))
    fit = float(jnp.sum(_tau_residuals(sol.value, args) ** 2))
    # Within the grid's span: beyond it a lag only smooths the prediction flat.
    ok = np.isfinite(fit) and fit <= min(sse) and min(taus) <= tau <= max(taus)
    return (tau, fit) if ok else (t_best, min(sse))


def _lag_identified(tau: float, taus) -> bool:
    """Whether a fitted lag time constant measures a lag: inside the grid `taus`, not at its
    largest value, where the fit only asks for more smoothing (see `_confirm`)."""
    return 0.0 < tau < max(taus) - 1e-9


def _fit_offset(ctx: _Ctx, model: Model, with_lag: bool) -> Model:
    """The offset (grid over `offset_bounds`) and, with `with_lag`, the lag time constant
    (grid, then refined by LM at the best offset) that minimise the held-out window SSE of
    the ensemble median (without `with_lag`, of the model with its own lag)."""
    d = ctx.cfg.discovery
    if not d.calibrate_offset:
        offsets = np.array([d.offset_s])
    else:
        offsets = np.arange(d.offset_bounds[0], d.offset_bounds[1] + 1e-9, d.offset_step_s)
    best = (np.inf, 0.0, 0.0)
    for off in offsets:
        win = _replay(ctx, float(off))
        full = win.table.weight.to_numpy() >= 0.999
        meas = win.table.measured_g.to_numpy()
        yhat = np.median(predictions(ctx, model._replace(lag_tau_s=0.0) if with_lag else model, win), axis=0)
        if with_lag:
            tau, sse = _fit_tau(yhat, meas, win, full, d.lag_taus, refine=False)
        else:
            tau, sse = model.lag_tau_s, float(np.sum((yhat[full] - meas[full]) ** 2))
        if sse < best[0]:
            best = (sse, float(off), tau, yhat, meas, full)
    tau = best[2]
    if with_lag:
        win = _replay(ctx, best[1])
        tau = _fit_tau(best[3], best[4], win, best[5], sorted({tau, *d.lag_taus}))[0]
    return model._replace(offset_s=best[1], lag_tau_s=tau)


def _refine(c: Candidate, residual, cands: pd.DataFrame, prediction, base=None) -> Candidate:
    """Refine a knee, or a resonance's centre and width, by variable-projection least
    squares: residual ≈ b0 + base·β + b·candidate(θ) (for a resonance, a gain:
    b·prediction·band(θ)), (b0, β, b) solved inside, θ by LM. `base`: the selection's floor
    covariates on the same windows (a fit without them moves the knee or band to where the
    floor explains as much: measured, a band refined 267.5 → 264.2 rpm that the selection
    credited with a held-out gain of −0.10 against the grid's 0.08). A resonance stays in its
    grid cell: the centre within one grid width of the grid's (c0 + w0·tanh θ0), the width
    within a factor 2 (w0·2^tanh θ1); a band that walks further is another candidate, one the
    selection did not choose (a free fit moved 267.5 → 257.2 rpm, which did not confirm)."""
    if c.operator not in ("threshold", "resonance"):
        return c
    x = jnp.asarray(cands[f"x:{c.channels[0]}"].to_numpy())
    p = c.parameters
    # Standardised (float32 least squares).
    B = jnp.asarray(np.column_stack([np.ones(len(x)), *([] if base is None else [_standardise(np.asarray(base))])]))
    f32 = lambda v: jnp.asarray(v, jnp.float32)  # noqa: E731
    args = (x, jnp.asarray(residual), jnp.asarray(prediction), B, f32(p.get("softness", 1.0)),
            f32(p.get("center", 0.0)), f32(p.get("width", 1.0)), c.operator, bool(p.get("above", True)))
    th0 = jnp.array([p["knee"]]) if c.operator == "threshold" else jnp.zeros(2)
    sol = optx.least_squares(_refine_residuals, optx.LevenbergMarquardt(rtol=1e-6, atol=1e-10), th0, args,
                             max_steps=100, throw=False)
    th = np.asarray(sol.value)
    sse = lambda th: float(jnp.sum(_refine_residuals(th, args) ** 2))  # noqa: E731
    better = sse(sol.value) <= sse(th0)
    if not (np.all(np.isfinite(th)) and better):
        return c
    lo, hi = float(x.min()), float(x.max())
    if c.operator == "threshold":
        return replace(c, parameters={**p, "knee": float(np.clip(th[0], lo, hi))})
    center, width = (float(v) for v in _band(sol.value, p["center"], p["width"]))
    return replace(c, parameters={**p, "center": float(np.clip(center, lo, hi)), "width": width})


def _keep_better(grid: Candidate, refined: Candidate, win: _Windows, yhat, resid, rows, floor, folds: int, seed: int,
                 log=print) -> Candidate:
    """The refined candidate if the selection's design (its rows and floor covariates, the
    same folds) credits it with at least the grid candidate's held-out gain, else the grid's.
    `_refine` minimises the in-sample error, which a knee fitted to a few conditions can
    lower without predicting the others (measured: knees refined to a held-out gain of 0.027
    against the grid's 0.052, and 0.019 against 0.047)."""
    if refined.key == grid.key:
        return refined
    cols = np.column_stack([_selection_column(c, win.values(c), yhat)[rows] for c in (grid, refined)])
    g = gains(resid[rows], cols, win.table.condition.to_numpy()[rows], base=floor, folds=folds, seed=seed)
    if g[1] >= g[0]:
        return refined
    log(f"  {grid.name}: refined to {refined.name}, held-out gain {g[1]:.3f} < {g[0]:.3f}: kept")
    return grid


# --------------------------------------------------------------------------- the workflow


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


@dataclass
class Discovery:
    """The outcome of `discover` (`summary` turns it into data-contract §3).

    Attributes:
        campaign: path or name. database: the model's database.
        baseline, final: the baseline and the final (augmented) `Model`.
        before, after: their held-out metrics (`metrics`: medians over seeds, `rms_by_seed`
            per seed, `ensemble_rms_g` of the median prediction).
        effects: one dict per confirmed effect, ranked (see `summary`).
        rounds: every tried proposal (a table).
        localized: `residuals.localize` tables of the baseline.
        windows: the baseline replay windows with `predicted_before_g`, `predicted_after_g` and
            `effect_<rank>`, each effect's column as the selection saw it (a resonance times
            the prediction, a lag as the lagged minus the plain prediction).
        seconds: wall time per stage.
        residual: the first round's selection design (`Residual`), for `selection_gain`.
        lag_test: with `lag_test`, one row per ensemble of the test (`_lag_test`): tau_s,
            train_offset_s, offset_s (refitted), ensemble_rms_g, rms_g, peak_error_g,
            phase_error_s, role (reference or slow), drop (against the reference), chosen.
    """

    campaign: str
    database: str
    baseline: Model
    final: Model
    before: dict
    after: dict
    effects: list
    rounds: pd.DataFrame
    localized: dict
    windows: pd.DataFrame
    seconds: dict
    residual: Residual | None = None
    lag_test: pd.DataFrame | None = None


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
    folds = _train.condition_folds(db.condition, d.folds, d.split_seed, f"discovery.folds (campaign {source}, "
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
    batch = to_batch(campaign, STATE_CHANNELS, list(info.index))
    recs = prepare(batch)
    L = cfg.analysis.window_revs
    lo, hi = d.offset_bounds if d.calibrate_offset else (min(0.0, d.offset_s), max(0.0, d.offset_s))
    settings = make_settings(batch, max_window_revs=L, min_window_revs=L, hop_revs=d.hop_revs,
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
        f"({d.folds}-fold by condition x {d.seeds} seeds)")
    return _Ctx(campaign, cfg, db, db[list(DB_INPUTS[d.database])].to_numpy(np.float64), folds, info,
                np.array([fold_of[c] for c in info.condition]), batch, recs, settings,
                window_table(campaign, train_iv, d.exclude_channels), replay_params={})


def _train_model(ctx: _Ctx, model: Model, rows: str = "") -> dict:
    """Nets on the database inputs and the model's extra inputs, with its gains, trained on
    the peaks or the windows (`rows`, default the config's `train_rows`) minus its additive
    terms (per fold: each fold's terms were fitted without it). A model `through_lag` trains
    on the windows, the measured ones with the model's lag undone (`delag`)."""
    d = ctx.cfg.discovery
    if model.through_lag or (rows or d.train_rows) == "windows":  # every train_stride-th full window at the offset
        win = _replay(ctx, model.offset_s)
        t = win.table
        sel = (t.weight.to_numpy() >= 0.999) & (t.k.to_numpy() % d.train_stride == 0)
        x, value = _inputs(model, win)[sel], lambda c: win.values(c)[sel]
        y = t.measured_g.to_numpy()
        if model.through_lag:
            y = delag(y, t.time_s.to_numpy(), t.i.to_numpy(), model.lag_tau_s)
        y, folds = y[sel], ctx.counter_fold[t.i.to_numpy()[sel]]
    else:
        value = lambda c: values(c, ctx.train_table)  # noqa: E731
        x, y, folds = ctx.x_db, ctx.db[OUTPUT].to_numpy(np.float64), ctx.folds
        if model.extra or model.gains:
            x = np.column_stack([x] + [value(c) for c in model.extra + model.gains])
    if model.terms:
        y = np.stack([y - _terms(model, value, np.full(len(y), f)) for f in range(d.folds)])
    return fit_ensemble(x, y, folds, k=d.folds, seeds=d.seeds, hidden=d.hidden, train_cfg=ctx.cfg.train,
                        seed=ctx.cfg.seed, n_gain=len(model.gains))


def _fit_term(ctx: _Ctx, model: Model, c: Candidate, win: _Windows) -> np.ndarray:
    """Intercept and coefficient of an additive term on the residual of `model`, per fold,
    each fitted on the windows of the other folds' conditions (cross-fitting). (k, 2). With
    a lag in the model the term acts before it (`predictions`), so it is fitted lagged."""
    full = win.table.weight.to_numpy() >= 0.999
    fold = ctx.counter_fold[win.table.i.to_numpy()]
    r = win.table.measured_g.to_numpy() - np.median(predictions(ctx, model, win), axis=0)
    A = np.column_stack([np.ones(len(r)), _lag_windows(win.values(c)[None], win, model.lag_tau_s)[0]])
    out = np.zeros((ctx.cfg.discovery.folds, 2))
    for f in range(len(out)):
        rows = full & (fold != f)
        out[f] = np.linalg.lstsq(A[rows], r[rows], rcond=None)[0]
    return out


def _augment(ctx: _Ctx, model: Model, c: Candidate, how: str) -> Model:
    """The model with one more effect: an extra network input, a learned gain on the nets'
    output (`gain_apply`), or an additive term (fitted on the windows, the nets retrained on
    the corrected peaks, the term refitted)."""
    if how in ("input", "gain"):
        trial = model._replace(**({"extra": model.extra + (c,)} if how == "input" else {"gains": model.gains + (c,)}))
        return trial._replace(params=_train_model(ctx, trial))
    win = _replay(ctx, model.offset_s)
    first = model._replace(terms=model.terms + ((c, _fit_term(ctx, model, c, win)),))
    params = _train_model(ctx, first)
    refit = _fit_term(ctx, model._replace(params=params), c, win)
    return model._replace(params=params, terms=model.terms + ((c, refit),))


def _active_kinds(v, maneuver) -> list[str]:
    """The maneuver kinds where a column `v` (one value per window) is active: its mean squared
    deviation from its median over the windows of the kind is at least that over all windows."""
    dev = pd.Series((v - np.median(v)) ** 2, index=maneuver)
    by_kind = dev.groupby(level=0).mean()
    return sorted(by_kind.index[by_kind >= dev.mean()])


def _confirm(ctx: _Ctx, current: Model, trial: Model, c: Candidate, where: str, d) -> tuple[bool, dict]:
    """Whether a trial model confirms its effect: the held-out RMS of the ensemble's
    prediction (the median over seeds, whose residual the selection explained) drops by
    `min_shrink` where the effect acts and does not rise over all windows. Where it acts: the
    maneuver kind it was found in; for an effect found over all windows, the kinds where the
    candidate is active (`_active_kinds`; for a lag, the kinds that hold most of the change
    it makes), so that an effect of a few maneuver kinds is not diluted among all windows.

    The ensemble, not each seed: one net retrained on ~200 peaks moves its held-out RMS by
    ±8 % by itself (a seed's RMS is 0.045–0.052 g on the same world), so a median of per-seed
    shrinks still swings by a few percent, where the median prediction averages that out
    (a retrained placebo input moves it by < 2 %).

    A lag must also have a time constant inside `lag_taus`: at the largest the fit wants ever
    more smoothing, which damps the nets' over-response in transients whether or not the
    vibration lags (on benchmark worlds a 4 s lag lowers the window RMS 4–5 % without a lag
    or with the default 0.6 s one, 6–7 % with a 2 s one): a smoother, not a measured lag.

    Returns:
        (confirmed, dict of the trial's predictions and windows, metrics, shrinks, region,
        the ensemble's RMS over all windows before and after, and `why` it is not confirmed).
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
    why = ("" if local >= d.min_shrink and shrink > 0.0 else "too small a shrink")
    if c.operator == "lag" and not _lag_identified(trial.lag_tau_s, d.lag_taus):
        why = f"time constant at the grid's largest, {max(d.lag_taus):g} s: a smoother, not a lag"
    return not why, dict(pred=tpred, win=twin, metrics=metrics(tpred, twin), shrink=shrink, local=local,
                         region=region, judged_in=", ".join(kinds), ensemble=ens, why=why)


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


def _paired_errors(a: dict, b: dict) -> pd.DataFrame:
    """The squared errors of trials `a`'s and `b`'s ensembles (the median over seeds) on the
    windows both hold in full: counter, window, condition, maneuver, e2_a, e2_b."""
    def table(t):
        full = t["win"].table.weight.to_numpy() >= 0.999
        e2 = (np.median(t["pred"], axis=0) - t["win"].table.measured_g.to_numpy()) ** 2
        return t["win"].table.loc[full, ["counter", "window", "condition", "maneuver"]].assign(e2=e2[full])
    return table(a).merge(table(b), on=["counter", "window", "condition", "maneuver"], suffixes=("_a", "_b"))


def _paired_sign_flip(a: dict, b: dict, permutations: int, seed: int) -> tuple[float, float]:
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


def _floor_basis(win: _Windows, yhat, rows, floor, knots=(0.25, 0.5, 0.75)) -> np.ndarray:
    """Covariates for the error floor: the prediction, and each floor feature with hinges at
    interior quantiles (a piecewise-linear map of the model's own inputs; interior knots, so
    that a held-out condition at the edge of the data is not extrapolated by a steep hinge)."""
    cols = [yhat[rows]]
    for f in floor:
        x = win.cands[f"x:{f}"].to_numpy()[rows]
        cols.append(x)
        cols += [np.maximum(x - k, 0.0) for k in np.unique(np.quantile(x, knots)) if np.ptp(np.maximum(x - k, 0)) > 0]
    return np.column_stack(cols)


def knn_floor(features, residual, groups, k: int = 30, chunk: int = 1024) -> np.ndarray:
    """The residual a static map of these features leaves near each window: the mean
    residual of its `k` nearest windows (standardised features) among *other* conditions.

    A misfit that is a function of the model's own inputs (the map's error floor: too few
    peaks there, an extrapolation) reappears at the same inputs in other conditions, so this
    covariate absorbs it; a missing effect does not, unless it follows the inputs.

    Args:
        features: (n, d) the model's inputs per window. residual: (n,). groups: (n,) condition.

    Returns:
        (n,) the floor estimate.
    """
    X = np.asarray(features, float)
    sd = X.std(axis=0)
    X = (X - X.mean(axis=0)) / np.where(sd > 0, sd, 1.0)
    g = pd.factorize(np.asarray(groups))[0]
    out = np.empty(len(X))
    sq = np.sum(X * X, axis=1)
    for a in range(0, len(X), chunk):
        d2 = sq[a:a + chunk, None] + sq[None, :] - 2.0 * X[a:a + chunk] @ X.T
        d2[g[a:a + chunk, None] == g[None, :]] = np.inf
        kk = min(k, d2.shape[1] - 1)
        idx = np.argpartition(d2, kk, axis=1)[:, :kk]
        out[a:a + chunk] = residual[idx].mean(axis=1)
    return out


def _selection_column(c: Candidate, v, yhat) -> np.ndarray:
    """A candidate's column in the selection, from its values `v` per window: the values,
    for a resonance times the prediction `yhat` (a mode magnifies the response, so its
    residual is a·prediction·band: `gain_apply`)."""
    return v * yhat if c.operator == "resonance" else v


# Operators tried at `candidate_offsets_s` besides the model's offset: no fitted parameter.
_ALIGNED = ("input", "rate", "abs_rate", "window")


def _unaligned_key(c: Candidate) -> str:
    """A candidate's key without its alignment: one effect, whatever offset it was tried at."""
    return replace(c, parameters={k: v for k, v in c.parameters.items() if k != "offset_s"}).key


def _candidate_matrix(ctx: _Ctx, model: Model, win: _Windows, yhat, used_keys,
                      lags: bool = True) -> tuple[list[Candidate], np.ndarray, list[Candidate], np.ndarray]:
    """The round's candidates and their selection columns: the library at the model's offset
    and, for those without a fitted parameter, at `candidate_offsets_s`; without the effects
    named already (`used_keys`) and, unless `lags` and the model has none, the lags of the
    prediction. Static refinements of the model's own inputs (their knees and products, at
    its offset) are returned apart: the floor's business (`_propose`), not discoveries.

    Returns:
        (candidates, columns, own refinements, their columns); non-finite, constant and
        duplicate columns dropped.
    """
    d = ctx.cfg.discovery
    own = _determined(model.inputs)
    taken = tuple(model.inputs) + tuple(c.channels[0] for c in model.extra if c.operator == "input")
    # Candidates take the model's offset, recorded as their alignment: a term keeps it if a
    # later round moves the model's offset (`_Windows.values`). Those without a fitted
    # parameter are also tried at `candidate_offsets_s` (a transient's faster response).
    lib, cols, flib, fcols = [], [], [], []
    extra = sorted({round(float(o), 6) for o in d.candidate_offsets_s} - {round(float(model.offset_s), 6)})
    win.prefetch([model.offset_s, *extra])
    for off in [model.offset_s, *extra]:
        table = win.at(off)  # `win.cands` at the model's own offset (`win` is its replay)
        for c in library(table, model_inputs=taken, knee_quantiles=d.knee_quantiles):
            if off != model.offset_s and c.operator not in _ALIGNED:
                continue
            c = replace(c, parameters={**c.parameters, "offset_s": off})
            if c.operator in ("input", "threshold", "product") and set(c.channels) <= set(own):
                if c.operator != "input":
                    flib.append(c)
                    fcols.append(values(c, table))
                continue
            if _unaligned_key(c) in used_keys:
                continue
            lib.append(c)
            cols.append(_selection_column(c, values(c, table), yhat))
    C = np.column_stack(cols)
    if lags and model.lag_tau_s <= 0:
        lc, LC = _lag_candidates(yhat, win, d.lag_taus)
        lib, C = lib + lc, np.column_stack([C, LC])
    # Drop non-finite, constant and duplicate columns (e.g. |x| of a channel that is never negative).
    usable = lambda M: np.all(np.isfinite(M), axis=0) & (np.ptp(M, axis=0) > 0)  # noqa: E731
    ok = usable(C)
    _, first = np.unique(np.round(C[:, ok], 12), axis=1, return_index=True)
    keep = np.flatnonzero(ok)[np.sort(first)]
    F = np.column_stack(fcols) if fcols else np.empty((len(C), 0))
    fok = np.flatnonzero(usable(F))
    return [lib[j] for j in keep], C[:, keep], [flib[j] for j in fok], F[:, fok]


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


def _rms_by_seed(pred, win: _Windows, rows) -> np.ndarray:
    return np.sqrt(np.mean((pred[:, rows] - win.table.measured_g.to_numpy()[rows]) ** 2, axis=1))


def _floor(win: _Windows, yhat, resid, rows, own, groups, min_conditions: int = 40) -> np.ndarray:
    """The floor covariates of a selection: the prediction and the nearest-neighbour floor;
    with enough conditions also the piecewise-linear basis of the model's own inputs (in a
    maneuver kind of a dozen conditions its ~30 columns would fit the held-out folds'
    noise, not the floor)."""
    knn = knn_floor(win.cands.loc[rows, [f"x:{f}" for f in own]].to_numpy(), resid[rows], groups[rows])
    if len(set(groups[rows])) >= min_conditions:
        return np.column_stack([_floor_basis(win, yhat, rows, own), knn])
    return np.column_stack([yhat[rows], knn])


def _try_order(same) -> list:
    """The order in which to retrain the candidates a selection cannot tell apart ((column,
    gain), simplest first): the simplest (the one it names), then the one that explains
    most (a gain on the prediction, a resonance, can be a whole mode while simpler channels
    share its shadow; the retraining decides between them), then the others."""
    best = max(range(len(same)), key=lambda i: same[i][1])
    return [same[i] for i in [0] + ([best] if best else []) + [i for i in range(1, len(same)) if i != best]]


def _neighbour_cells(proposals, lib: list[Candidate], M, designs, resid, groups, d, seed: int) -> list:
    """The proposals with, after each resonance, the band of the adjacent grid cell (same
    channel and alignment) that the proposal's design credits with the larger held-out gain,
    if it gains `min_gain` and is not proposed already. A mode between two grid centres is
    shared by both cells, and which of the two the selection ranks first depends on how few
    windows reach the band; the retraining decides (measured: a mode at 273 rpm, the band at
    267.5 ranked first, gain 0.084, but −0.5 % retrained; the one at 270.7, gain 0.071, −22 % RMS).

    Args:
        proposals: `_propose`'s list of (where, column, `Selected`). lib: the candidate of each
            column of `M`. designs: `_propose`'s {where: (rows, floor covariates)}.

    Returns:
        The proposals, neighbours inserted (not counted against `d.proposals`).
    """
    taken = {j for _, j, _ in proposals}
    out = []
    for where, j, s in proposals:
        out.append((where, j, s))
        c = lib[j]
        if c.operator != "resonance":
            continue
        same = lambda o: (o.operator == c.operator and o.channels == c.channels  # noqa: E731
                          and o.parameters.get("offset_s") == c.parameters.get("offset_s"))
        near = [k for k, o in enumerate(lib) if k not in taken and same(o)
                and 0 < abs(o.parameters["center"] - c.parameters["center"]) <= 1.01 * c.parameters["width"]]
        if not near:
            continue
        rows, floor = designs[where]
        g = gains(resid[rows], M[:, near][rows], groups[rows], base=floor, folds=d.folds, seed=seed)
        top = int(np.argmax(g))
        if g[top] >= d.min_gain:
            taken.add(near[top])
            out.append((where, near[top], s._replace(index=near[top], gain=float(g[top]))))
    return out


def _probe_gains(ctx: _Ctx, model: Model, bands) -> np.ndarray:
    """The gains of nets trained with a learned gain on every band at once (`gain_apply`),
    median over folds and seeds: (len(bands),). The nets learn the response, the gains how
    much each band magnifies it; a mode is the band of the largest."""
    params = _train_model(ctx, model._replace(gains=model.gains + tuple(bands)))
    g = np.asarray(params["gain"])[..., len(model.gains):]
    return np.median(g.reshape(-1, len(bands)), axis=0)


def _resonance_probe(ctx: _Ctx, model: Model, proposals, lib: list[Candidate], M, designs, resid, groups, d,
                     seed: int, log) -> list:
    """`proposals` and, if none is a resonance, the rotor-speed band of the largest
    `_probe_gains` (the model's offset; a band not named already), for nets trained on the
    peaks (none for window nets: `Model.through_lag` or `train_rows = "windows"`). Its
    `Selected` carries the band's held-out gain as a column of the selection (usually ~0:
    what it explains is not proportional to the prediction) and no p-value: the retraining's
    confirmation decides."""
    if any(lib[j].operator == "resonance" for _, j, _ in proposals):
        return proposals
    if model.through_lag or d.train_rows == "windows":
        # Measured on peak nets only: on null worlds the forced band of the largest gain makes
        # their prediction worse. Nets trained on the windows under-predict the lowest rotor
        # speed, where the fewest conditions are, and a gain there corrects them out of
        # sample although the world has no mode (the long-lag worlds, after the lag test).
        log("resonance probe: skipped, the nets train on the windows (the probe is calibrated on peak nets)")
        return proposals
    bands = [(j, c) for j, c in enumerate(lib)
             if c.operator == "resonance" and c.parameters.get("offset_s") == model.offset_s]
    if not bands:
        return proposals
    g = _probe_gains(ctx, model, [c for _, c in bands])
    j = bands[int(np.argmax(g))][0]
    rows, floor = designs["all"]
    gain = _selection_gain(resid[rows], M[rows, j], groups[rows], base=floor, folds=d.folds, seed=seed)
    log("resonance probe: gains by band centre " + ", ".join(
        f"{c.parameters['center']:.1f} {v:+.2f}" for (_, c), v in zip(bands, g)) + f": proposes {lib[j].name}")
    return list(proposals) + [("all", j, _Selected(j, gain, float("nan"), float("nan"), source="probe"))]


def _probe_test(conf: dict, current: dict, c: Candidate, seed: int) -> tuple[float, float]:
    """The p-value and explained fraction of a probe's band (`_resonance_probe`), which the
    selection gives none, from its retraining. p: that the retrained ensemble predicts better
    than the current one by condition where the band acts (its value ≥ 0.5: a mode magnifies
    the conditions at its rotor speeds), one-sided sign flips. Reported, not required, like
    the lag test's: measured, the mode of the seeds + 2 resonance world scores 0.018 (0.013
    over all conditions), a band that confirmed at the threshold beside a sideslip effect
    0.802 (0.021 over all): at `alpha` = 0.01 it would reject both.

    Args:
        conf: `_confirm`'s (the trial's predictions and windows). current: the current
            model's predictions (`pred`) and windows (`win`). c: the band. seed: of the flips.

    Returns:
        (p, 1 − the trial's squared error / the current model's, over all windows).
    """
    both = _paired_errors(current, conf).merge(
        conf["win"].table[["counter", "window"]].assign(band=conf["win"].values(c)), on=["counter", "window"])
    return _sign_flip_p(both[both.band >= 0.5], _SIGN_FLIPS, seed), _explained(both)


def _propose(win: _Windows, yhat, resid, C, rows, own, floor_all, d, seed: int, complexity, keys,
             is_floor=None) -> tuple[list, list, dict]:
    """Significant candidates over all windows and, with `local_selection`, inside each
    maneuver kind where the residual concentrates (an effect of one kind is diluted among
    all windows) and that has `min_subset_conditions` conditions (with fewer, the floor
    covariates and the k-fold split cannot tell an effect from the floor). Bonferroni over
    the subsets; the permutations grow so that the corrected level can be reached.
    `floor_all`: the floor covariates of all the rows (`_floor`; a subset's are computed
    here). `complexity` (one per column of C) is for the selection's parsimony rule; `keys`
    (one per column) names the effect of each, so that one effect at two alignments is
    proposed once (at the better).

    `is_floor` marks the columns that refine the model's own inputs (`_candidate_matrix`): before
    any candidate is asked, the one with the largest held-out gain joins the floor
    covariates, while it gains `min_gain`, at most `floor_refinements` of them. A knee of the
    map's own inputs that ~200 peaks did not teach the nets is the map's floor, not a
    missing effect; left out, a channel that follows it (a stick, the shaft power) is named
    in its place. Never tested, never proposed: covariates (their permutations in the test's
    null would only inflate it).

    Returns:
        (proposals, absorbed, designs). proposals: list of (where, candidate column,
        `Selected`), most residual² explained first and, inside a selection, the candidates it
        cannot tell apart (`_try_order`); at most `d.proposals`, one per candidate. absorbed:
        list of (where, column, gain) of the floor columns that joined the floor. designs:
        {where: (rows, floor covariates with the absorbed columns)} of each selection.
    """
    groups = win.table.condition.to_numpy()
    kinds = win.table.maneuver.to_numpy()
    is_floor = np.zeros(C.shape[1], bool) if is_floor is None else np.asarray(is_floor, bool)
    subsets = [("all", rows)]
    r2 = resid[rows] ** 2
    for kind in sorted(set(kinds[rows])) if d.local_selection else ():
        sub = rows & (kinds == kind)
        # Kinds where the residual concentrates (share of residual² ≥ share of windows),
        # with conditions enough for the k-fold split.
        concentration = (np.sum(resid[sub] ** 2) / np.sum(r2)) / (np.sum(sub) / np.sum(rows))
        if concentration >= 1.0 and len(set(groups[sub])) >= d.min_subset_conditions:
            subsets.append((kind, sub))
    alpha = d.alpha / len(subsets)
    perms = max(d.permutations, int(np.ceil(1.0 / alpha)) - 1)
    found, absorbed, designs = [], [], {}
    for where, sub in subsets:
        Cs = C[sub]
        keep = np.flatnonzero(np.ptp(Cs, axis=0) > 0)
        floor = floor_all if where == "all" else _floor(win, yhat, resid, sub, own, groups)
        # The floor first: the static map of the model's own inputs is the null model, so
        # its refinements (the one with the largest held-out gain, while it gains `min_gain`)
        # join the floor covariates before any candidate is asked (never tested: covariates).
        for _ in range(d.floor_refinements):
            own_cols = keep[is_floor[keep]]
            if not len(own_cols):
                break
            g = gains(resid[sub], Cs[:, own_cols], groups[sub], base=floor, folds=d.folds, seed=seed)
            top = int(np.argmax(g))
            if g[top] < d.min_gain:
                break
            absorbed.append((where, int(own_cols[top]), float(g[top])))
            floor = np.column_stack([floor, Cs[:, own_cols[top]]])
            keep = keep[keep != own_cols[top]]
        keep = keep[~is_floor[keep]]
        designs[where] = (sub, floor)
        for s in forward_select(resid[sub], Cs[:, keep], groups[sub], base=floor, folds=d.folds, max_effects=1,
                                min_gain=d.min_gain, alpha=alpha, permutations=perms, seed=seed,
                                complexity=complexity[keep], parsimony=d.parsimony):
            amount = s.gain * float(np.sum(resid[sub] ** 2))
            s = s._replace(index=int(keep[s.index]),  # global columns
                           alternatives=tuple((int(keep[a]), g) for a, g in s.alternatives),
                           equivalents=tuple((int(keep[a]), g) for a, g in s.equivalents))
            found.append((amount, where, s))
    out, seen = [], set()
    for _, where, s in sorted(found, key=lambda f: -f[0]):
        for j, g in _try_order(s.equivalents or ((s.index, s.gain),)):
            if keys[j] not in seen:
                seen.add(keys[j])
                out.append((where, j, s._replace(index=j, gain=g)))
    return out[: d.proposals], absorbed, designs


def _choose(tries, noise: float, alpha: float) -> int:
    """Which confirmed try of a round is named. tries: (shrink, selection gain, p) of each, p
    the one-sided p-value that the try of the largest shrink predicts better than this one
    (`_paired_sign_flip` by condition; 1 for that try itself).

    The retraining decides first: the try that lowers the ensemble's RMS over all windows most
    (the same windows for every try). Tries it does not beat significantly (p ≥ `alpha`), or
    that come within `noise` of its shrink (a retrained placebo input moves the ensemble's RMS
    by < 2 %), are tied, and of those the one the selection credits with the largest held-out
    gain is named: one column against the same residual on every window is the finer
    comparison of two retrainings' noise (then the larger shrink). Measured: two proxies of a
    collective stall knee, retrained, lower the RMS 22.0 % (shaft power) and 17.1 % (the
    collective), p = 0.03 by condition: a tie the selection decides (the collective, 0.250 against 0.239).
    """
    best = max(sh for sh, _, _ in tries)
    tied = [i for i, (sh, _, p) in enumerate(tries) if sh >= best - noise or p >= alpha]
    return max(tied, key=lambda i: (tries[i][1], tries[i][0]))


def _public_parameters(c: Candidate) -> dict:
    p = dict(c.parameters)
    p.pop("softness", None)
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
        campaign = load_campaign(campaign, cfg.campaign.columns, cfg.analysis.window_revs)
    elif not isinstance(campaign, Campaign):
        raise TypeError(f"{caller}: campaign must be a Campaign or a campaign folder, got {type(campaign).__name__}")
    return campaign, cfg, name


def discover(campaign: Campaign | str | os.PathLike, cfg: ExperimentConfig | DiscoveryConfig = ExperimentConfig(), *,
             name: str = "", log=print, progress=None) -> Discovery:
    """Run the discovery workflow on a campaign (see the module docstring).

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
    d = cfg.discovery
    sec = {}
    t0 = time.perf_counter()
    ctx = _context(campaign, cfg, log)
    sec["prepare"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    params = _train_model(ctx, Model({}, tuple(DB_INPUTS[d.database])), rows="peaks")  # they calibrate the replay
    ctx.replay_params = params
    sec["train_baseline"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    model = _fit_offset(ctx, Model(params, tuple(DB_INPUTS[d.database])), with_lag=False)
    if d.train_rows == "windows":  # on the windows at the offset the peak nets calibrated
        t1 = time.perf_counter()
        model = model._replace(params=_train_model(ctx, model))
        sec["train_baseline"] += time.perf_counter() - t1
    lag = None
    if d.lag_test and d.max_effects > 0:
        t1 = time.perf_counter()
        lag = _lag_test(ctx, model.offset_s, log)
        sec["lag_test"] = time.perf_counter() - t1
        if lag["confirmed"]:  # the baseline is then the test's reference: before/after measures the lag
            model = lag["reference"]["model"]
    win = _replay(ctx, model.offset_s)
    full = win.table.weight.to_numpy() >= 0.999
    pred0 = predictions(ctx, model, win)
    before = metrics(pred0, win)
    sec["offset_and_replay"] = time.perf_counter() - t0
    log(f"baseline {d.database}: offset {model.offset_s:.2f} s, held-out RMS {before['rms_g']:.4f} g, peak error "
        f"{before['peak_error_g']:.4f} g, phase error {before['phase_error_s']:.2f} s")
    loc_windows = win.table.assign(database=d.database, predicted_g=np.median(pred0, axis=0))
    localized = localize(loc_windows[full])
    log("residual by maneuver (share of the squared residual): " + ", ".join(
        f"{k} {v:.0%}" for k, v in localized["maneuver"].share_sq.head(4).items()))

    baseline, current, pred, cur_metrics = model, model, pred0, before
    effects, rounds, used, first = [], [], set(), None
    t_explain = t_confirm = 0.0
    if lag is not None:
        row, effect = _lag_round(ctx, lag, current.inputs)
        rounds.append(row)
        if effect is not None:
            effects.append(effect)
            current, pred, cur_metrics = lag["slow"]["model"], lag["slow"]["pred"], lag["slow"]["metrics"]
    for rnd in range(d.max_effects - len(effects)):
        t0 = time.perf_counter()
        win = _replay(ctx, current.offset_s)
        full = win.table.weight.to_numpy() >= 0.999
        yhat = np.median(pred, axis=0)
        resid = win.table.measured_g.to_numpy() - yhat
        # A lag test that ran is the lag's judge: its trainings through the lag are the finer
        # test, and a lag of the prediction that a round confirms after it rejected one is a
        # smoother of the nets' transients (measured on a null world: τ 2.1 s, −2.9 %).
        lib, C, flib, F = _candidate_matrix(ctx, current, win, yhat, used, lags=lag is None)
        sel_rows = full & (win.table.k.to_numpy() % d.selection_stride == 0)
        own = floor_features(current.inputs)
        groups = win.table.condition.to_numpy()
        floor = _floor(win, yhat, resid, sel_rows, own, groups)
        both, M = lib + flib, np.column_stack([C, F])
        proposals, absorbed, designs = _propose(win, yhat, resid, M, sel_rows, own, floor, d,
                                                seed=cfg.seed + rnd, complexity=np.array([c.complexity for c in both]),
                                                keys=[_unaligned_key(c) for c in both],
                                                is_floor=np.arange(len(both)) >= len(lib))
        lib = both  # proposals and their runners-up index both
        proposals = _neighbour_cells(proposals, lib, M, designs, resid, groups, d, seed=cfg.seed + rnd)
        if d.resonance_probe:
            proposals = _resonance_probe(ctx, current, proposals, lib, M, designs, resid, groups, d, cfg.seed + rnd,
                                         lambda m: log(f"round {rnd + 1}: {m}"))
        if rnd == 0:  # the selection's design: its floor with the refinements it took over all windows
            taken = [M[sel_rows, j] for where, j, _ in absorbed if where == "all"]
            first = Residual(resid, sel_rows, np.column_stack([floor, *taken]) if taken else floor,
                             groups, d.folds, cfg.seed)
        floor_terms = "; ".join(f"{lib[j].name} in {where} ({g:.3f})" for where, j, g in absorbed)
        if absorbed:
            log(f"round {rnd + 1}: the floor takes {floor_terms}")
        t_explain += time.perf_counter() - t0
        log(f"round {rnd + 1}: {len(lib) - len(flib)} candidates, {len(proposals)} proposed: "
            + (", ".join(f"{lib[j].name} in {where} (p={s.p_value:.4f}, gain {s.gain:.3f})"
                         for where, j, s in proposals) or "none")
            + "".join(f"; {len(s.equivalents)} equivalent to the best in {where}: "
                      + ", ".join(lib[a].name for a, _ in s.equivalents[:10]) for where, _, s in proposals[:1]))
        confirmed = []
        tried = set()
        for where, j, s in proposals:
            t0 = time.perf_counter()
            rows, fl = designs[where]
            refined = _keep_better(lib[j], _refine(lib[j], resid[rows], win.at(
                lib[j].parameters.get("offset_s", win.offset))[rows], yhat[rows], base=fl), win, yhat, resid,
                rows, fl, d.folds, cfg.seed + rnd, log)
            used.add(_unaligned_key(lib[j]))
            if refined.key in tried:  # two grid knees refined to the same one: retrained already
                log(f"  {lib[j].name}: refined to {refined.name}, tried already")
                continue
            tried.add(refined.key)
            modes = {"lag": ("lag",), "resonance": ("gain",)}.get(
                refined.operator, ("additive", "input") if d.augment == "auto" else (d.augment,))
            alts = "; ".join(f"{lib[a].name} ({g:.3f})" for a, g in s.alternatives)
            for mode in modes:
                c = refined
                if mode == "lag":
                    trial = _fit_offset(ctx, current, with_lag=True)
                    c = replace(c, parameters={"tau_s": trial.lag_tau_s})
                else:
                    trial = _augment(ctx, current, c, mode)
                    if trial.terms and trial.terms[-1][0] is c:
                        c = replace(c, parameters={**c.parameters,
                                                   "coefficient": float(np.median(trial.terms[-1][1][:, 1]))})
                    if mode == "gain":
                        c = replace(c, parameters={**c.parameters,
                                                   "gain": float(np.median(trial.params["gain"][..., -1]))})
                ok, conf = _confirm(ctx, current, trial, c, where, d)
                p_value, explained = s.p_value, s.explained_fraction
                if s.source == "probe":  # no selection p: its retraining's, by condition
                    p_value, explained = _probe_test(conf, dict(pred=pred, win=win), c, cfg.seed + rnd)
                t_confirm += time.perf_counter() - t0
                t0 = time.perf_counter()
                rounds.append(dict(round=rnd + 1, where=where, candidate=c.key, name=c.name, operator=c.operator,
                                   channels=",".join(c.channels), augment=mode, p_value=p_value, cv_gain=s.gain,
                                   runners_up=alts, explained_fraction=explained,
                                   rms_before_g=cur_metrics["rms_g"], rms_after_g=conf["metrics"]["rms_g"],
                                   ensemble_rms_before_g=conf["ensemble"][0], ensemble_rms_after_g=conf["ensemble"][1],
                                   floor_terms=floor_terms, shrink=conf["shrink"], judged_in=conf["judged_in"],
                                   region_shrink=conf["local"], confirmed=ok, why_not=conf["why"],
                                   p_best_better=np.nan, chosen=False))
                log(f"  {c.name} ({mode}): held-out RMS {cur_metrics['rms_g']:.4f} -> {conf['metrics']['rms_g']:.4f} "
                    f"g (median over seeds); ensemble's {conf['ensemble'][0]:.4f} -> {conf['ensemble'][1]:.4f} g, "
                    f"shrink {conf['shrink']:+.1%} (all), {conf['local']:+.1%} "
                    f"({conf['judged_in']}): "
                    f"{'confirmed' if ok else 'not confirmed (' + conf['why'] + ')'}")
                if ok:  # "auto" tries both ways and keeps the better
                    confirmed.append((conf["shrink"], len(rounds) - 1, where,
                                      s._replace(p_value=p_value, explained_fraction=explained), c, trial, conf))
        if not confirmed:
            break
        top = max(confirmed, key=lambda t: t[0])[-1]
        ps = [1.0 if t[-1] is top else _paired_sign_flip(t[-1], top, _SIGN_FLIPS, cfg.seed + rnd)[0] for t in confirmed]
        for t, p in zip(confirmed, ps):
            rounds[t[1]]["p_best_better"] = p
        k = _choose([(t[0], t[3].gain, p) for t, p in zip(confirmed, ps)], d.shrink_noise, d.alpha)
        _, row, where, s, c, trial, conf = confirmed[k]
        effects.append(dict(rank=len(effects) + 1, round=rnd + 1, name=c.name, operator=c.operator,
                            channels=list(c.channels) or list(current.inputs), parameters=_public_parameters(c),
                            explained_fraction=s.explained_fraction, p_value=s.p_value, region=conf["region"],
                            key=c.key, candidate=c, found_in=where))
        rounds[row]["chosen"] = True
        current, pred, cur_metrics = trial, conf["pred"], conf["metrics"]
    sec["explain"], sec["confirm"] = t_explain, t_confirm

    # Before and after on the final model's windows (the same counters and windows; the
    # baseline re-predicted there if the offset moved).
    win = _replay(ctx, current.offset_s)
    final_pred = predictions(ctx, current, win)
    base_win = _replay(ctx, baseline.offset_s)
    after = metrics(final_pred, win)
    table = base_win.table.assign(predicted_before_g=np.median(pred0, axis=0))
    table = table.merge(win.table[["counter", "window"]].assign(predicted_after_g=np.median(final_pred, axis=0)),
                        on=["counter", "window"], how="left")
    yb = np.median(pred0, axis=0)
    for e in effects:  # each effect's column as the selection saw it, for its partial-dependence plot
        c = e["candidate"]
        if c.operator == "lag":
            table[f"effect_{e['rank']}"] = _lag_windows(yb[None], base_win, c.parameters["tau_s"])[0] - yb
        else:
            table[f"effect_{e['rank']}"] = _selection_column(c, base_win.values(c), yb)
    log(f"final: {len(effects)} effect(s); held-out RMS {before['rms_g']:.4f} -> {after['rms_g']:.4f} g")
    return Discovery(name or str(campaign.source), d.database, baseline, current, before, after, effects,
                     pd.DataFrame(rounds), localized, table, sec, first, None if lag is None else lag["table"])


def summary(res: Discovery) -> dict:
    """The data-contract §3 summary (`discovery.json`)."""
    m = lambda x: {k: round(float(x[k]), 6) for k in ("rms_g", "peak_error_g", "phase_error_s")}  # noqa: E731
    effects = []
    for e in res.effects:
        effects.append({k: e[k] for k in ("rank", "name", "operator", "channels")}
                       | {"parameters": {k: (round(v, 6) if isinstance(v, float) else v)
                                         for k, v in e["parameters"].items()},
                          "explained_fraction": round(float(e["explained_fraction"]), 4),
                          "p_value": round(float(e["p_value"]), 4),
                          "region": {k: (round(v, 6) if isinstance(v, float) else v) for k, v in e["region"].items()}})
    return {
        "campaign": res.campaign,
        "baseline": {"database": res.database, "metrics": m(res.before)},
        "effects": effects,
        "augmented": {"added": [e["name"] for e in res.effects], "metrics": m(res.after)},
        "gap_shrink": round(1.0 - res.after["rms_g"] / res.before["rms_g"], 4),
    }
