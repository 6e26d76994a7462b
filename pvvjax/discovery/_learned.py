"""A lag learned inside one training: window nets with a first-order lag of learnable time
constant between their output and the measured PVV, fitted jointly by gradient.

The lag test's judge (`_lag._lag_test`). Choosing a lag between separate trainings (with and
without one) rests on the difference of two noisy trainings; learning τ inside one does not.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..nets import stack_trees
from ..nets.networks import mlp_apply, mlp_init, scaling
from ..nets.train import descend
from ._model import lagged_windows


def _loss(trainable, fixed, x, y, w, layout):
    net = {**fixed, "layers": trainable["layers"]}
    pred = lagged_windows(mlp_apply(net, x), layout, jnp.exp(trainable["log_tau"]))
    return jnp.sum(w * (pred - y) ** 2) / (jnp.sum(w) * fixed["y_scale"] ** 2)


def _fit_one(trainable, fixed, x, y, w, layout, steps: int, learning_rate: float):
    opt = optax.adam(learning_rate)
    return descend(_loss, trainable, opt.init(trainable), opt, steps, fixed, x, y, w, layout)[0]


_fit_all = jax.jit(jax.vmap(_fit_one, in_axes=(0, 0, None, None, 0, None, None, None)), static_argnums=(6, 7))


def fit_learned_lag(x, y, train_w, layout, folds: int, *, seeds: int, hidden, seed: int = 0, steps: int = 3000,
                    learning_rate: float = 0.01, tau0_s: float = 1.0) -> dict:
    """Nets and the time constant of a first-order lag between their output and `y`, fitted
    jointly (Adam on the mean squared error), for each fold × seed at once.

    Args:
        x: (n, d) inputs of every window of `layout`. y: (n,) measured PVV, g.
        train_w: (folds, n) training weight of each window per fold (0 for the held-out
            fold's windows, and for windows not trained on).
        layout: `window_layout` of the windows.
        seeds, hidden: nets per fold and their hidden widths. seed: the first seed.
        steps, learning_rate: Adam's. tau0_s: the time constant every fit starts from, s.

    Returns:
        dict: tau_s (folds, seeds) learned time constants; pred (folds, seeds, n) every
        window's lagged prediction by each net; nets (the parameters, stacked likewise).
    """
    # Host-side set-up in NumPy (eagerly, every JAX operation would compile a program).
    x, y = np.asarray(x, np.float32), np.asarray(y, np.float32)
    w = np.asarray(train_w, np.float32)
    nets = []
    for f in range(folds):
        on = w[f] > 0
        sc = scaling(x[on], y[on])
        nets += [mlp_init(jax.random.key(seed + s), x.shape[1], tuple(hidden), scale=sc) for s in range(seeds)]
    nets = stack_trees(nets)
    trainable = {"layers": nets.pop("layers"), "log_tau": np.full(folds * seeds, np.log(tau0_s), np.float32)}
    lay = tuple(np.asarray(a) for a in layout)
    out = _fit_all(trainable, nets, x, y, np.repeat(w, seeds, axis=0), lay, int(steps), float(learning_rate))
    nets = {**nets, "layers": out["layers"]}
    tau, pred = _predict_lagged(nets, x, lay, out["log_tau"])
    shape = (folds, seeds)
    return dict(tau_s=np.asarray(tau, np.float64).reshape(shape),
                pred=np.asarray(pred, np.float64).reshape(shape + (len(y),)),
                nets=jax.tree.map(lambda a: np.asarray(a).reshape(shape + a.shape[1:]), nets))


@jax.jit
def _predict_lagged(nets, x, layout, log_tau):
    """Every net's τ and lagged window predictions (nets and log τ stacked on the leading axis)."""
    tau = jnp.exp(log_tau)
    return tau, jax.vmap(lambda n, t: lagged_windows(mlp_apply(n, x), layout, t))(nets, tau)
