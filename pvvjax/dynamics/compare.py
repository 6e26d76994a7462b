"""Training the PVV models of vibration through time side by side, on the same window
sequences and the same held-out splits, so that their comparison isolates what each adds:
more data (the static map on every window), state rates, dynamics (a delay and a
second-order response) or a black-box recurrence.

A split is a list of folds, each a (test, validation) pair of row masks; every model trains
one net per (fold, seed), all of them in one vmapped, jitted `nets.train.fit` (rows of other
folds carry weight 0, so every net has the same shapes), and a row's held-out prediction is
the mean over seeds of the nets that held it out.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import numpy as np

from ..data.batch import take_rows
from ..nets import stack_trees, train
from ..nets.networks import mlp_apply, mlp_init, scaling
from .models import dynamic_apply, dynamic_init, identified, rnn_apply, rnn_init
from .sequences import Sequences

__all__ = ["APPLY", "WITH_RATES", "Split", "Trained", "condition_split", "dynamic_model_init", "fit_peak_map",
           "fit_sequence_model", "heldout", "identified_table", "kind_split", "model_inputs", "offset_replay",
           "record_pieces", "recurrent_init", "split_problem", "static_init"]


class Split(NamedTuple):
    """Folds of a held-out split over a sequence's rows.

    Attributes:
        name: "condition" (k-fold by condition) or "maneuver" (one kind held out at a time).
        labels: (F,) what each fold holds out.
        test, val: (F, R) bool: each fold's held-out and early-stopping rows.
    """

    name: str
    labels: tuple[str, ...]
    test: np.ndarray
    val: np.ndarray


def condition_split(conditions, k: int, seed: int, key: str = "dynamic.folds") -> Split:
    """k folds by condition (`nets.condition_folds`): fold f holds out its conditions and
    stops early on fold f+1's (`key`: the setting k came from, for the error)."""
    folds = train.condition_folds(conditions, k, seed, name=key)
    test = np.stack([folds == f for f in range(k)])
    return Split("condition", tuple(str(f) for f in range(k)), test, np.roll(test, -1, axis=0))


def kind_split(conditions, maneuvers, k: int, seed: int) -> Split:
    """One fold per maneuver kind, holding out all of it; early stopping on one condition
    fold (of k) of the other kinds: how a model does on a kind it never saw."""
    folds = train.condition_folds(conditions, k, seed, name="dynamic.folds")
    maneuvers = np.asarray(maneuvers)
    kinds = tuple(sorted(set(maneuvers)))
    test = np.stack([maneuvers == m for m in kinds])
    return Split("maneuver", kinds, test, ~test & (folds == 0)[None, :])


def split_problem(split: Split) -> str:
    """Why a split cannot be trained and scored ("" when it can): a fold with no held-out,
    no training or no early-stopping row (a kind split of a campaign of one maneuver kind,
    or one whose early-stopping fold holds only the held-out kind)."""
    for label, test, val in zip(split.labels, split.test, split.val):
        train_rows = ~test & ~val
        for what, rows in (("held-out", test), ("training", train_rows), ("early-stopping", val)):
            if not rows.any():
                return (f"fold {str(label)!r} has no {what} condition ({len(split.labels)} fold(s) over "
                        f"{split.test.shape[1]} conditions)")
    return ""


class Trained(NamedTuple):
    """A model's nets of one split.

    Attributes:
        params: parameters stacked (F, S, ...) over folds and seeds.
        pred: (F, S, R, W) every net's prediction of every row, g.
        best_step, failed_step: (F, S) as `nets.Fit`.
    """

    params: dict
    pred: np.ndarray
    best_step: np.ndarray
    failed_step: np.ndarray


# Models that take the database inputs' rates beside them (`model_inputs`).
WITH_RATES = ("window_static_rates", "rnn")


def model_inputs(seq: Sequences, model: str) -> np.ndarray:
    """A model's inputs (R, W, C) from a sequence: the database inputs (window_static), with
    their rates (`WITH_RATES`), or followed by the window times (dynamic)."""
    plain = [i for i, n in enumerate(seq.names) if not n.startswith("d_")]
    if model == "window_static":
        return seq.inputs[..., plain]
    if model == "dynamic":
        return np.concatenate([seq.inputs[..., plain], seq.time[..., None]], axis=-1)
    if model in WITH_RATES:
        return seq.inputs
    raise ValueError(f"{model!r} is not a sequence model")


# The chunked training's bookkeeping, each one program per batch layout (eagerly, every
# leaf and operation would be a program of its own).
_done = jax.jit(jax.vmap(train.done))
_results = jax.jit(jax.vmap(train.result))


def fit_sequence_model(init: Callable, apply: Callable, x, y, mask, split: Split, seeds: int, cfg,
                       pointwise: bool = False, progress: Callable | None = None, chunk_evals: int = 10,
                       pieces: tuple[int, int] | None = None) -> Trained:
    """Train one net per (fold, seed) on window sequences, all in one vmapped program.

    Args:
        init: (key, scale, fold) -> parameters (`scale`: `nets.scaling` of the fold's
            training windows; a dynamic model may start from another model's fold nets).
        apply: (params, x (R, W, C)) -> (R, W) PVV, g.
        x: (R, W, C) inputs. y: (R, W) measured PVV, g. mask: (R, W) real windows.
        split: the folds. seeds: initialisation seeds per fold.
        cfg: `TrainConfig`.
        pointwise: `apply` maps each window on its own (a static map): train on the real
            windows alone, each a row of one window, instead of on padded records (the same
            loss; a record's padding is about half its windows).
        progress: called as `progress(step, best validation RMS (median over nets), nets
            still training)` after every `chunk_evals` evaluations (the training runs in
            chunks between these looks; the result is the same as in one).
        pieces: (length, burn-in) in windows: train a recurrent `apply` on pieces of the
            training records instead of whole ones (`record_pieces`): every real window is
            scored once, after at least `burn-in` windows of its record have warmed the
            state up (none at a record's start), so the recurrence walks `length` windows
            a step instead of the longest record, and padding is not computed. Validation
            and the returned predictions run on whole records.
    """
    x, y, mask = np.asarray(x, np.float32), np.asarray(y, np.float32), np.asarray(mask, bool)
    trains = [~split.test[f] & ~split.val[f] for f in range(len(split.labels))]
    if pointwise:  # rows: the real windows of each row set
        select = lambda rows: mask & rows[:, None]  # noqa: E731
        n_train = max(int(select(r).sum()) for r in trains)
        n_val = max(int(select(v).sum()) for v in split.val)
        rows_of = lambda rows, n: _windows(x, y, select(rows), n)  # noqa: E731
    else:
        n_train, n_val = max(int(r.sum()) for r in trains), max(int(v.sum()) for v in split.val)
        rows_of = lambda rows, n: _rows(x, y, mask, rows, n)  # noqa: E731
    train_of = lambda f, n: rows_of(trains[f], n)  # noqa: E731
    if pieces is not None and not pointwise:
        cut = [record_pieces(mask, rows, *pieces) for rows in trains]
        n_train = max(len(c[0]) for c in cut)
        train_of = lambda f, n: _pieces(x, y, mask, *cut[f], n, pieces[0])  # noqa: E731
    params, data = [], []
    for f, train_rows in enumerate(trains):
        sc = scaling(x[train_rows][mask[train_rows]], y[train_rows][mask[train_rows]])
        d = train_of(f, n_train) + rows_of(split.val[f], n_val)
        for s in range(seeds):
            params.append(init(jax.random.key(s), sc, (f, s)))
            data.append(train.Data(*d))
    res = _train_chunked(stack_trees(params), stack_trees(data), cfg, apply, progress, chunk_evals)
    pred = jax.jit(jax.vmap(apply, in_axes=(0, None)))(res.params, x)
    shape = (len(split.labels), seeds)
    reshape = lambda a: np.asarray(a).reshape(shape + np.shape(a)[1:])  # noqa: E731
    return Trained(jax.tree.map(reshape, res.params), reshape(pred), reshape(res.best_step),
                   reshape(res.failed_step))


def _train_chunked(params, data, cfg, apply, progress, chunk_evals: int) -> train.Fit:
    """Every net to completion (`nets.train.run`, vmapped), `chunk_evals` evaluations at a
    time, looking in between: `progress` sees the step and the best validation RMS, and
    once half the nets still in the batch have stopped, they leave it (the rest continue in
    a batch of the next power of two, padded with copies whose results are dropped), so
    that the work follows the nets still training. A net trains to the same numbers in any
    batch (`nets.train`: its sums do not depend on the batch)."""
    consts = {k: v for k, v in params.items() if k not in train.TRAINABLE}
    init = jax.jit(jax.vmap(lambda p, d, h: train.init_state(p, d, h, apply), in_axes=(0, 0, None)))  # h traced
    chunk = jax.jit(jax.vmap(lambda st, c, d: train.run(st, c, d, cfg.eval_every, chunk_evals, apply)))
    n = len(jax.tree.leaves(data)[0])
    state, live = init(params, data, train.hyper(cfg)), np.arange(n)  # live: which net each batch slot trains
    finished: dict = {}
    while len(live):
        state = chunk(state, consts, data)
        done = np.asarray(_done(state))[: len(live)]
        if progress is not None:
            progress(int(np.max(state.step)), float(np.median(np.asarray(state.best_val)[: len(live)])),
                     int((~done).sum()))
        if 2 * done.sum() < len(live) and not done.all():
            continue
        out = jax.tree.map(np.asarray, _results(state, consts))
        for slot in np.flatnonzero(done):
            finished[int(live[slot])] = jax.tree.map(lambda a, i=slot: a[i], out)
        keep = np.flatnonzero(~done)
        live = live[keep]
        if len(live):
            slots = np.concatenate([keep, np.full(_bucket(len(keep)) - len(keep), keep[0])])
            state, consts, data = take_rows((state, consts, data), slots)
    return stack_trees([finished[i] for i in range(n)])


def _bucket(n: int) -> int:
    """The batch size of `n` nets still training: the next power of two, at least 2 (XLA
    compiles a batch of one to other arithmetic)."""
    return max(2, 1 << max(0, (n - 1).bit_length()))


def _windows(x, y, select, n: int) -> tuple:
    """The selected windows as rows of one window each: (x (n, 1, C), y (n, 1), weights (n,
    1)), padded to n rows of weight 0."""
    r, w = np.nonzero(select)
    pad = n - len(r)
    r, w = np.concatenate([r, np.full(pad, r[0])]), np.concatenate([w, np.full(pad, w[0])])
    return x[r, w][:, None], y[r, w][:, None], (np.arange(n) < n - pad).astype(np.float32)[:, None]


def record_pieces(mask, rows, length: int, burn_in: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pieces of `length` windows that cover the chosen rows' real windows, each scored once.

    A record's first piece starts at its first window and scores all of its windows; each
    later piece starts `burn_in` windows before the first window it scores and scores the
    rest (`length - burn_in`), so that a recurrent state has run through the windows before
    it. A piece past a record's end is clipped to its last real window.

    Args:
        mask: (R, W) real windows. rows: (R,) the records to cut.
        length, burn_in: windows per piece and of its burn-in (0 <= burn_in < length).

    Returns:
        (row (P,), first window (P,), first scored window (P,)) of the P pieces.
    """
    if not 0 <= burn_in < length:
        raise ValueError(f"pieces of {length} windows with a burn-in of {burn_in}: need 0 <= burn-in < length")
    row, start, scored = [], [], []
    for r in np.flatnonzero(rows):
        n, a, w = int(mask[r].sum()), 0, 0
        while w < n:
            row.append(r), start.append(a), scored.append(w)
            w = a + length
            a = w - burn_in
    return np.asarray(row), np.asarray(start), np.asarray(scored)


def _pieces(x, y, mask, row, start, scored, n: int, length: int) -> tuple:
    """The pieces' (x, y, weights) (n, length, ...), padded to n pieces of weight 0; weight 1
    on the real windows a piece scores."""
    pad = n - len(row)
    row, start, scored = (np.concatenate([a, np.full(pad, a[0])]) for a in (row, start, scored))
    at = start[:, None] + np.arange(length)  # each piece's windows; past the padded width, the last one
    idx = np.minimum(at, x.shape[1] - 1)  # repeated, and scored once only (where `at` lies within it)
    w = mask[row[:, None], idx] & (at >= scored[:, None]) & (at < x.shape[1]) & (np.arange(n) < n - pad)[:, None]
    return x[row[:, None], idx], y[row[:, None], idx], w.astype(np.float32)


def _rows(x, y, mask, rows, n: int) -> tuple:
    """The chosen rows' (x, y, weights), padded to n rows of weight 0: only they are
    computed in training (a fold's other rows never enter its program)."""
    idx = np.flatnonzero(rows)
    sel = np.concatenate([idx, np.full(n - len(idx), idx[0])])
    w = mask[sel] & (np.arange(n) < len(idx))[:, None]
    return x[sel], y[sel], w.astype(np.float32)


def heldout(pred: np.ndarray, split: Split) -> np.ndarray:
    """(R, W) each row's prediction by the nets that held it out, the mean over seeds; NaN
    for a row no fold holds out."""
    mean = np.asarray(pred).mean(axis=1)  # (F, R, W)
    out = np.full(mean.shape[1:], np.nan)
    for f in range(mean.shape[0]):
        out[split.test[f]] = mean[f][split.test[f]]
    return out


def fit_peak_map(x, y, split: Split, seeds: int, hidden, cfg) -> Trained:
    """The paper's static map: an MLP per (fold, seed) trained on one peak per condition.

    Args:
        x: (R, C) the database inputs at each row's (condition's) peak window.
        y: (R,) the peak PVV, g; or (R, A): a net of A outputs (e.g. one per pilot-floor axis).
        split, seeds, cfg: as `fit_sequence_model`.
        hidden: hidden-layer widths.

    Returns:
        `Trained` whose `pred` is (F, S, R, 1) (or (F, S, R, 1, A)): the map at the peak inputs.
    """
    n_in = np.shape(x)[-1]
    n_out = 1 if np.ndim(y) == 1 else np.shape(y)[1]
    init = lambda key, sc, fs: mlp_init(key, n_in, tuple(hidden), scale=sc, n_out=n_out)  # noqa: E731
    return fit_sequence_model(init, mlp_apply, np.asarray(x)[:, None, :], np.asarray(y)[:, None],
                              np.ones((len(y), 1), bool), split, seeds, cfg)


def offset_replay(params, x_long, t_long, time, y, mask, split: Split, offsets) -> tuple[np.ndarray, np.ndarray]:
    """The quasi-static replay at the sequence's windows: each fold's peak map (mean over
    seeds) on the inputs averaged over its long windows (`[analysis] window_revs`), moved
    by an input-to-vibration offset, and interpolated to the short windows' centre times.
    The offset is calibrated per fold on a grid, by the window RMS on the fold's training
    and validation rows (never its held-out ones).

    Args:
        params: a `fit_peak_map` result's params (F, S, ...).
        x_long: (R, V, C) inputs over the long windows. t_long: (R, V) their centre times, s.
        time: (R, W) the sequence's window times, s. y: (R, W) measured PVV, g.
        mask: (R, W) the sequence's real windows.
        split: the folds. offsets: (G,) candidate offsets, s (> 0: the inputs lead).

    Returns:
        ((F, R, W) every fold's replay of every row at its offset, (F,) the offsets, s).
    """
    apply = jax.jit(jax.vmap(jax.vmap(mlp_apply, in_axes=(0, None)), in_axes=(0, None)))
    long = np.asarray(apply(params, np.asarray(x_long, np.float32)), np.float64).mean(axis=1)  # (F, R, V)
    offsets = np.asarray(offsets, float)
    out, chosen = np.empty((len(long),) + np.shape(time)), np.empty(len(long))
    for f in range(len(long)):
        rows = ~split.test[f]
        cand = np.stack([[np.interp(time[r] - o, t_long[r], long[f, r]) for r in range(len(time))]
                         for o in offsets])  # (G, R, W)
        err = ((cand - y)[:, rows] ** 2 * mask[rows]).sum(axis=(1, 2))
        g = int(np.argmin(err))
        out[f], chosen[f] = cand[g], offsets[g]
    return out, chosen


def identified_table(params: dict) -> dict:
    """The dynamic model's identified response per (fold, seed) (`identified`), with the
    slow pole's time constant: 1/(ω_n(ζ − √(ζ² − 1))) when overdamped, else 1/(ζω_n) (the
    envelope's)."""
    out = identified(params)
    w, z = out["omega_n_rad_s"], out["zeta"]
    over = z > 1
    slow = np.where(over, 1.0 / (w * (z - np.sqrt(np.where(over, z * z - 1, 0.0)))), 1.0 / (z * w))
    return {**out, "tau_slow_pole_s": slow}


def dynamic_model_init(n_in: int, hidden, dc) -> Callable:
    """`init` for `fit_sequence_model` of the dynamic model trained whole: an MLP on the
    fold's scaling of its `n_in` inputs (the last channel, the window times, is not an
    input of the map) and the response at `dc`'s start (`DynamicConfig` f_n_hz, zeta,
    delay_s)."""
    def init(key, sc, fs):
        sc = {**sc, "x_shift": sc["x_shift"][:n_in], "x_scale": sc["x_scale"][:n_in]}
        return dynamic_init(mlp_init(key, n_in, tuple(hidden), scale=sc), omega_n=2 * np.pi * dc.f_n_hz,
                            zeta=dc.zeta, delay_s=dc.delay_s)
    return init


def static_init(n_in: int, hidden) -> Callable:
    """`init` for `fit_sequence_model`: an MLP on the fold's scaling."""
    return lambda key, sc, fs: mlp_init(key, n_in, tuple(hidden), scale=sc)


def recurrent_init(n_in: int, hidden: int) -> Callable:
    """`init` for `fit_sequence_model`: a GRU model on the fold's scaling."""
    return lambda key, sc, fs: rnn_init(key, n_in, hidden, scale=sc)


APPLY = {"window_static": mlp_apply, "window_static_rates": mlp_apply, "dynamic": dynamic_apply, "rnn": rnn_apply}
