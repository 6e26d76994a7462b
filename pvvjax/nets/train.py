"""Full-batch training of the networks, with splits by flight condition.

Every row of a database is a flight condition, so a split is a partition of conditions;
rows are never split. `condition_folds` assigns each condition to one of k folds; for fold
f the test set is fold f, the validation set (early stopping) is fold f+1, and the rest
trains. Across the k folds every condition is predicted exactly once by a net that never
saw it: the held-out predictions of the correlation plots.

Data enter as full arrays with 0/1 row weights (train, validation, test), so nets trained
on different splits, databases and seeds have the same shapes and vmap together. The
training settings a user changes (learning rate, weight decay, step budget, patience,
divergence factor) enter as arrays too (`Hyper`), so one compiled trainer serves every value
and nets with different settings train side by side; only `eval_every`, the length of the
inner scan, is part of the program.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .._arguments import ArgumentError, number
from ._sums import pairwise_sum
from .networks import mlp_apply

__all__ = ["TRAINABLE", "Data", "Fit", "Hyper", "TrainState", "TrainingError", "condition_folds", "descend", "done",
           "fit", "hyper", "init_state", "make_data", "masked_metrics", "optimizer", "result", "run", "split_masks"]


class TrainingError(RuntimeError):
    """A net whose loss became NaN or diverged."""


class Fit(NamedTuple):
    """Result of training one net (a batch of nets when vmapped).

    Attributes:
        params: parameters at the best validation RMS.
        best_step: step of the best validation RMS.
        best_val_rms: validation RMS at that step, g.
        steps: steps run.
        failed_step: first step with a non-finite or diverging loss (-1: none).
    """

    params: dict
    best_step: jax.Array
    best_val_rms: jax.Array
    steps: jax.Array
    failed_step: jax.Array


def condition_folds(conditions, k: int, seed: int, name: str = "k") -> np.ndarray:
    """Fold index (0..k-1) of each row, assigned per condition in a seeded random order
    (`name`: the setting k came from, for the error)."""
    number("condition_folds", name, k, whole=True)
    number("condition_folds", "seed", seed, at_least=0, whole=True)
    conditions = np.asarray(conditions)
    uniq = np.unique(conditions)
    if k < 3 or k > len(uniq):
        raise ArgumentError(f"{name} = {k}: a k-fold split by condition needs 3 <= k <= the number of conditions "
                         f"({len(uniq)})")
    order = np.random.default_rng(seed).permutation(len(uniq))
    fold_of = {c: i % k for i, c in zip(range(len(uniq)), uniq[order])}
    return np.array([fold_of[c] for c in conditions])


def split_masks(folds: np.ndarray, test_fold: int, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(train, validation, test) 0/1 row weights for one outer fold."""
    test = folds == test_fold
    val = folds == (test_fold + 1) % k
    return (~test & ~val).astype(np.float32), val.astype(np.float32), test.astype(np.float32)


TRAINABLE = ("layers", "centers", "log_width", "w", "b", "gain", "response", "rnn")  # masks and scalings never train


def _split(params: dict) -> tuple[dict, dict]:
    return ({k: v for k, v in params.items() if k in TRAINABLE},
            {k: v for k, v in params.items() if k not in TRAINABLE})


def _per_output(w, pred):
    """Row weights (n,) broadcast over a multi-output net's outputs (n, k)."""
    return jnp.broadcast_to(w.reshape(w.shape + (1,) * (pred.ndim - w.ndim)), pred.shape) if pred.ndim > w.ndim else w


def _wmse(pred, y, w, y_scale):  # over every row (and every window of a sequence model's rows, every output)
    w = _per_output(w, pred)
    return pairwise_sum((w * ((pred - y) / y_scale) ** 2).reshape(-1)) / jnp.maximum(pairwise_sum(w.reshape(-1)), 1.0)


def _wrms(pred, y, w):
    w = _per_output(w, pred)
    return jnp.sqrt(pairwise_sum((w * (pred - y) ** 2).reshape(-1)) / jnp.maximum(pairwise_sum(w.reshape(-1)), 1.0))


class Hyper(NamedTuple):
    """A net's training settings as arrays: traced, so changing one compiles nothing, and
    nets with different settings train in one batch (stack them on a leading axis).

    Attributes:
        learning_rate: AdamW step size (float32).
        weight_decay: decoupled weight decay (float32; 0: plain Adam).
        max_steps: optimizer steps at most (int32).
        patience: evaluations without a better validation RMS before stopping (int32).
        divergence_factor: a training loss above this multiple of the initial loss is
            divergence (float32).
    """

    learning_rate: jax.Array
    weight_decay: jax.Array
    max_steps: jax.Array
    patience: jax.Array
    divergence_factor: jax.Array


def hyper(cfg, learning_rate=None, weight_decay=None) -> Hyper:
    """A `TrainConfig`'s settings as a `Hyper` (NumPy scalars; `learning_rate` and
    `weight_decay`, when given, replace the config's: a sweep's per-net axes)."""
    lr = cfg.learning_rate if learning_rate is None else learning_rate
    wd = cfg.weight_decay if weight_decay is None else weight_decay
    return Hyper(np.float32(lr), np.float32(wd), np.int32(cfg.max_steps), np.int32(cfg.patience),
                 np.float32(cfg.divergence_factor))


def optimizer(learning_rate=0.0, weight_decay=0.0) -> optax.GradientTransformation:
    """AdamW whose step size and weight decay live in its state, not in the program
    (`optax.inject_hyperparams`): its `update` reads them from the state `init` made, so
    one compiled step serves every value. A zero weight decay adds `0 * w`, which leaves
    Adam's update unchanged."""
    return optax.inject_hyperparams(optax.adamw)(learning_rate=learning_rate, weight_decay=weight_decay)


class TrainState(NamedTuple):
    """Everything a net's training needs to continue (vmap it over nets)."""

    opt: tuple  # (weights, AdamW state with its step size and weight decay)
    best: dict  # weights at the best validation RMS
    best_val: jax.Array
    best_step: jax.Array
    step: jax.Array
    since: jax.Array  # evaluations since the last improvement
    failed: jax.Array  # first step with a non-finite or diverging loss, -1: none
    limit: jax.Array  # loss above which training counts as diverging
    max_steps: jax.Array  # the net's step budget (`Hyper`)
    patience: jax.Array  # evaluations without improvement before it stops (`Hyper`)


class Data(NamedTuple):
    """One net's training and validation rows (padded rows carry weight 0).

    Only these rows are computed in a training step (test rows never enter), so the
    cost follows the training set, not the database.
    """

    x: jax.Array  # (n_train, d)
    y: jax.Array  # (n_train,) or (n_train, n_out)
    w: jax.Array  # (n_train,) 0/1
    x_val: jax.Array  # (n_val, d)
    y_val: jax.Array
    w_val: jax.Array


def make_data(x, y, w_train, w_val, n_train: int | None = None, n_val: int | None = None) -> Data:
    """Select a split's rows (NumPy, outside jit), padded to `n_train`/`n_val` rows."""
    x, y = np.asarray(x, np.float32), np.asarray(y, np.float32)

    def take(w, n):
        idx = np.flatnonzero(np.asarray(w) > 0)
        n = len(idx) if n is None else n
        if n < len(idx):
            raise ValueError(f"{len(idx)} rows do not fit in {n}")
        pad = np.full(n - len(idx), idx[0] if len(idx) else 0)
        sel = np.concatenate([idx, pad]).astype(int)
        return x[sel], y[sel], (np.arange(n) < len(idx)).astype(np.float32)

    return Data(*take(w_train, n_train), *take(w_val, n_val))


def descend(loss, params, opt_state, optimizer: optax.GradientTransformation, steps: int, *args):
    """`steps` steps of an optax optimizer on `loss(params, *args)`, as one scan: every
    training in pvvjax takes its gradient steps here.

    Returns:
        (params, optimizer state, (steps,) the loss before each step).
    """
    value_and_grad = jax.value_and_grad(loss)

    def step(carry, _):
        p, s = carry
        value, g = value_and_grad(p, *args)
        upd, s = optimizer.update(g, s, p)
        return (optax.apply_updates(p, upd), s), value

    (params, opt_state), values = jax.lax.scan(step, (params, opt_state), None, length=steps)
    return params, opt_state, values


def init_state(params: dict, data: Data, hp: Hyper, apply=mlp_apply) -> TrainState:
    """Initial training state of one net (`hp`: its `Hyper`, traced)."""
    t, const = _split(params)
    loss0 = _wmse(apply(params, data.x), data.y, data.w, const["y_scale"])
    opt = (t, optimizer(jnp.asarray(hp.learning_rate, jnp.float32), jnp.asarray(hp.weight_decay, jnp.float32)).init(t))
    zero = jnp.zeros((), jnp.int32)
    val0 = _wrms(apply(params, data.x_val), data.y_val, data.w_val)
    return TrainState(opt, t, val0, zero, zero, zero, jnp.full((), -1, jnp.int32),
                      hp.divergence_factor * (loss0 + 1e-12), jnp.asarray(hp.max_steps, jnp.int32),
                      jnp.asarray(hp.patience, jnp.int32))


@jax.jit  # one program per shape, inside another program or not
def done(state: TrainState) -> jax.Array:
    """Whether training stops: the step budget is spent, validation stopped improving for
    `patience` evaluations, or the loss went non-finite."""
    return (state.step >= state.max_steps) | (state.since >= state.patience) | (state.failed >= 0)


def run(state: TrainState, const: dict, data: Data, eval_every: int, max_evals=None, apply=mlp_apply) -> TrainState:
    """Continue training one net for at most `max_evals` evaluations (None: until done).

    Each evaluation follows `eval_every` optimizer steps (static: the inner scan's length);
    the weights of the best validation RMS are kept, and training stops after the state's
    patience in evaluations without improvement, at its step budget, or at the first
    non-finite or diverging loss. Only weights and biases train: masks and scalings
    (`const`) are constants.
    """
    full = lambda t: {**const, **t}  # noqa: E731
    loss_fn = lambda t: _wmse(apply(full(t), data.x), data.y, data.w, const["y_scale"])  # noqa: E731

    def cond(c):
        st, n = c
        ok = ~done(st)
        return ok if max_evals is None else ok & (n < max_evals)

    def body(c):
        st, n = c
        t, s, losses = descend(loss_fn, *st.opt, optimizer(), eval_every)
        o, bad = (t, s), jnp.any(~jnp.isfinite(losses) | (losses > state.limit))
        stp = st.step + eval_every
        val = _wrms(apply(full(o[0]), data.x_val), data.y_val, data.w_val)
        bad = bad | ~jnp.isfinite(val)
        better = (val < st.best_val) & ~bad
        best = jax.tree.map(lambda new, old: jnp.where(better, new, old), o[0], st.best)
        return st._replace(opt=o, best=best, best_val=jnp.where(better, val, st.best_val),
                           best_step=jnp.where(better, stp, st.best_step), step=stp,
                           since=jnp.where(better, 0, st.since + 1),
                           failed=jnp.where(bad & (st.failed < 0), stp, st.failed)), n + 1

    return jax.lax.while_loop(cond, body, (state, jnp.zeros((), jnp.int32)))[0]


def result(state: TrainState, const: dict) -> Fit:
    """The fit a finished state holds: the best-validation parameters (with the constant
    scalings) and where they were found."""
    return Fit({**const, **state.best}, state.best_step, state.best_val, state.step, state.failed)


def fit(params: dict, data: Data, cfg, apply=mlp_apply, hp: Hyper | None = None) -> Fit:
    """Train one net to completion (pure; jit and vmap it): the per-net reference of
    `batched.train_nets`. `cfg`: a `TrainConfig` (its `eval_every` is static); `hp`: the
    traced settings (default: the config's). See `run` and `make_data`."""
    _, const = _split(params)
    hp = hyper(cfg) if hp is None else hp
    return result(run(init_state(params, data, hp, apply), const, data, cfg.eval_every, apply=apply), const)


def masked_metrics(pred, y, w) -> dict:
    """RMS, max and 95th-percentile absolute error (g) over rows with weight > 0 (NumPy)."""
    pred, y, w = (np.asarray(v) for v in (pred, y, w))
    e = np.abs(pred - y)[w > 0]
    if e.size == 0:
        return dict(rms_g=np.nan, max_abs_g=np.nan, p95_abs_g=np.nan, n=0)
    return dict(rms_g=float(np.sqrt(np.mean(e**2))), max_abs_g=float(e.max()),
                p95_abs_g=float(np.percentile(e, 95)), n=int(e.size))
