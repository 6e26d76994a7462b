"""The discovery's models: nets with an optional learned gain, trained k-fold by condition over
seeds; the replay windows every model is judged on; a model's predictions and metrics."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from ..analysis.databases import DB_INPUTS
from ..config import ExperimentConfig
from ..data.batch import bucket_size, pad_rows
from ..data.campaign import Campaign
from ..nets import train as _train
from ..nets.batched import stack_trees, train_nets
from ..nets.networks import mlp_apply, mlp_init, scaling
from ..replay.quasistatic import FEATURES, input_index
from ..replay.tables import replay_all
from .candidates import Candidate, values, window_table, window_tables
from .effects import lag as _first_order_lag

# Replay windows of the workflow start every revolution: fine enough to place a transient's peak.
HOP_REVS = 1.0

TRANSIENT = ("pullup", "pushover", "roll", "autorotation", "flare")
# The canonical inputs each derived feature is computed from (`features`): a derived feature
# belongs to a model's own inputs when they include all of these.
_DERIVED_FROM = {
    "advance_ratio": ("advance_ratio",), "mlf": ("mlf",),
    "thrust_coefficient": ("gross_weight_lb", "density_ratio", "rotor_rpm", "mlf"),  # with the MLF as load factor
    "blade_loading": ("gross_weight_lb", "density_ratio", "rotor_rpm", "mlf"),
}


# The campaign channels the two derived inputs are computed from (`features`).
_CHANNELS_OF = {"advance_ratio": ("airspeed_kt", "rotor_rpm"),
                "mlf": ("roll_angle_deg", "pitch_rate_dps", "airspeed_kt")}

# Campaign channels that the model's inputs determine exactly (airspeed = μ·ΩR).
_DETERMINED_BY = {"airspeed_kt": ("advance_ratio", "rotor_rpm")}


def floor_features(inputs) -> tuple[str, ...]:
    """The model's inputs and the derived features computed from them alone: a static map
    on these can express anything built from them, so a misfit in them is the map's error
    floor (too few peaks to learn it), not a missing effect."""
    return tuple(inputs) + tuple(k for k, src in _DERIVED_FROM.items() if k not in inputs and set(src) <= set(inputs))


def computable(inputs) -> frozenset[str]:
    """The channels and derived features that are functions of `inputs` alone: the inputs,
    the features computed from them (the advance ratio from airspeed and rotor speed, blade
    loading from weight, density, rotor speed and the MLF, ...) and the channels they
    determine (airspeed from the advance ratio and rotor speed), to a fixed point."""
    rules = [*_CHANNELS_OF.items(), *_DERIVED_FROM.items(), *_DETERMINED_BY.items()]
    have, grown = set(inputs), True
    while grown:
        new = {f for f, src in rules if f not in have and set(src) <= have}
        have |= new
        grown = bool(new)
    return frozenset(have)


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
    fits = train_nets(stack_trees(params), stack_trees(data), np.repeat(np.arange(k), seeds), train_cfg,
                      apply=gain_apply if n_gain else mlp_apply)
    if np.any(np.asarray(fits.failed_step) >= 0):
        raise _train.TrainingError("discovery: a net diverged; lower train.learning_rate")
    return jax.tree.map(lambda a: np.asarray(a).reshape((k, seeds) + a.shape[1:]), fits.params)


@partial(jax.jit, static_argnames=("apply",))
def _predict_folds(params, fold, x, apply):
    """(S, n): every fold's nets on every row, then each row's own fold taken (a mask, not a
    loop over folds, so one program serves every split of the rows)."""
    pred = jax.vmap(jax.vmap(apply, in_axes=(0, None)), in_axes=(0, None))(params, x)  # (k, S, n)
    return jnp.take_along_axis(pred, fold[None, None, :], axis=0)[0]


def _predict(params, fold, x) -> np.ndarray:
    """(S, n) predictions of each seed's net that held out each row's fold (rows padded to
    a `bucket_size` count: one compiled program per bucket)."""
    n = len(fold)
    m = bucket_size(n)
    apply = gain_apply if "gain" in params else mlp_apply
    out = _predict_folds(params, pad_rows(np.asarray(fold, np.int32), m), pad_rows(np.asarray(x, np.float32), m),
                         apply)
    return np.asarray(out, np.float64)[:, :n]


# --------------------------------------------------------------------------- model and replay


class Model(NamedTuple):
    """A model under discovery: nets, extra inputs, gains, offset and an optional lag.

    Attributes:
        params: nets (k, seeds, ...). inputs: database inputs. extra: candidates added as
        network inputs. gains: candidates whose learned gain multiplies the nets' output
        (`gain_apply`; the coefficients are in `params["gain"]`, in units of 1 / the
        candidate's `gain_unit` parameter, default 1: see `_columns`).
        offset_s: input-to-vibration offset, s. lag_tau_s: first-order lag of the replayed
        prediction, s (0: none). linear: candidates added as a linear term on the prediction,
        fitted to its residual out of fold by condition (`linear_shift`): the baseline's
        misfit, a function of its own inputs that more net inputs would only refit.
    """

    params: dict
    inputs: tuple[str, ...]
    extra: tuple[Candidate, ...] = ()
    offset_s: float = 0.0
    lag_tau_s: float = 0.0
    gains: tuple = ()
    linear: tuple = ()


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
    theta = np.tile(np.float32([offset, L, 0.0]), (N, 1))  # NumPy: no copy program per shape
    model = dict(params=jax.device_put(jax.tree.map(lambda a: np.asarray(a)[ctx.counter_fold], ctx.replay_params)),
                 idx=jax.device_put(np.tile(input_index(d.database, len(DB_INPUTS[d.database])), (N, 1))))
    rep = jax.device_get(replay_all(model, ctx.recs, theta, settings=ctx.settings))
    W = rep.time.shape[1]
    # Input windows in record time: measured window edges (revolutions) -> time -> − offset.
    a = np.asarray(ctx.recs.rev_start)[:, None] + HOP_REVS * np.arange(W)[None, :]
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


def window_layout(win: _Windows) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The (N, W) layout that `lagged_windows` lags along, as indices.

    Returns:
        src (N, W): 1 + the window (row of `win.table`) whose value each cell holds, 0 for
        none (a gap: value 0; a counter's leading cells hold its first window, so that the
        lag starts at rest). times (N, W): increasing cell times, s. i, k: (n,) the cell of
        each window.
    """
    i, k, to_grid, times = _grid(win)
    src = np.rint(to_grid(np.arange(1, len(i) + 1, dtype=float))).astype(np.int32)
    return src, times, i, k


_lag_rows = jax.vmap(_first_order_lag, in_axes=(0, 0, None))


@jax.jit  # one program per shape, inside another program or not
def lagged_windows(u, layout, tau_s):
    """u (..., n) per-window values lagged by a first-order lag of τ along each counter's
    windows (zero-order hold between window times), pure and differentiable in τ.
    layout: (src, times, i, k) from `window_layout`."""
    src, times, i, k = layout
    cells = jnp.where(src > 0, jnp.take(u, jnp.maximum(src - 1, 0), axis=-1), 0.0)
    lag = _lag_rows if u.ndim == 1 else jax.vmap(_lag_rows, in_axes=(0, None, None))
    return lag(cells, times, tau_s)[..., i, k]



def _lag_windows(pred, win: _Windows, tau: float) -> np.ndarray:
    """A first-order lag of (S, n) window predictions along each counter's window times."""
    if tau <= 0:
        return pred
    return np.asarray(lagged_windows(pred, window_layout(win), tau), dtype=np.asarray(pred).dtype)


_lag_grid = jax.jit(_lag_rows)


def _inputs(model: Model, win: _Windows) -> np.ndarray:
    """The nets' columns: database inputs, extra inputs, then the gains' candidates."""
    return _columns(win.table[list(model.inputs)].to_numpy(np.float64), model, win.values)


def _columns(x, model: Model, value) -> np.ndarray:
    """x beside the model's extra inputs and its gains' columns, `value(candidate)` each. A
    gain's column is its candidate times its `gain_unit` parameter (default 1), so that the
    nets learn the gain in steps of that unit (`DiscoveryConfig.gain_unit`)."""
    if not (model.extra or model.gains):
        return x
    return np.column_stack([x] + [value(c) for c in model.extra] + [_gain_unit(c) * value(c) for c in model.gains])


def _gain_unit(c: Candidate) -> float:
    """The unit a gain candidate's coefficient is learned in (`_columns`): 1 unless given."""
    return c.parameters.get("gain_unit", 1.0)


def predictions(ctx: _Ctx, model: Model, win: _Windows) -> np.ndarray:
    """(S, n) held-out predictions of every window (weight > 0), per seed."""
    fold = ctx.counter_fold[win.table.i.to_numpy()]
    pred = _predict(model.params, fold, _inputs(model, win))
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


def _rms_by_seed(pred, win: _Windows, rows) -> np.ndarray:
    return np.sqrt(np.mean((pred[:, rows] - win.table.measured_g.to_numpy()[rows]) ** 2, axis=1))
