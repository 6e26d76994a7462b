"""Dynamic PVV models: a static map (the paper's MLP, on a database's inputs averaged over
each window) followed by a learned delay and a learned unit-gain second-order response, so
that in trimmed flight the model equals its static map and through a maneuver it lags,
overshoots and rings as the identified natural frequency and damping say.

Parameters are a flat dict as the static nets' (`nets.mlp_init`) plus `response`, the
`Response` module's variables; `dynamic_apply(params, x)` takes the sequence's times as the
inputs' last channel, so that `nets.train.fit` trains it as it trains a static net (records
as rows, windows along them, the mask as weights)."""

from __future__ import annotations

from functools import partial

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from ..nets.networks import mlp_apply
from .response import delayed, second_order

__all__ = ["Recurrent", "Response", "dynamic_apply", "dynamic_init", "identified", "rnn_apply", "rnn_init"]



class Response(nn.Module):
    """A delay and a unit-gain second-order response of a sequence `u` at times `t`.

    Params: `log_omega_n` (ω_n = exp, rad/s), `log_zeta` (ζ = exp, > 0) and `delay_raw`
    (delay = softplus, s, >= 0): unconstrained, so that gradient steps keep them physical.
    """

    omega_n: float = 2 * np.pi * 1.0
    zeta: float = 0.7
    delay_s: float = 0.1

    @nn.compact
    def __call__(self, u, t):
        log_w = self.param("log_omega_n", lambda key: jnp.log(jnp.float32(self.omega_n)))
        log_z = self.param("log_zeta", lambda key: jnp.log(jnp.float32(self.zeta)))
        raw = self.param("delay_raw", lambda key: jnp.log(jnp.expm1(jnp.float32(max(self.delay_s, 1e-6)))))
        return second_order(delayed(u, t, jax.nn.softplus(raw)), t, jnp.exp(log_w), jnp.exp(log_z))


def dynamic_init(static: dict, *, omega_n: float = 2 * np.pi * 1.0, zeta: float = 0.7, delay_s: float = 0.1) -> dict:
    """A dynamic model from a static net's parameters (`nets.mlp_init`, its scaling set) and
    the response's starting values (ω_n rad/s, ζ, delay s)."""
    response = Response(omega_n, zeta, delay_s).init(jax.random.key(0), jnp.zeros(2), jnp.arange(2.0))["params"]
    return {**static, "response": response}


@jax.jit  # one program per shape, inside another program or not
def dynamic_apply(params: dict, x):
    """PVV through time.

    Args:
        params: `dynamic_init`'s dict.
        x: (..., W, n_in + 1) the inputs averaged over each window, in physical units, then
            the window times, s (non-decreasing along W).

    Returns:
        (..., W) PVV, g.
    """
    static = {k: v for k, v in params.items() if k != "response"}
    return Response().apply({"params": params["response"]}, mlp_apply(static, x[..., :-1]), x[..., -1])


def identified(params: dict) -> dict:
    """The response's physical parameters: omega_n_rad_s, f_n_hz, zeta, delay_s and the
    equivalent time constant 2ζ/ω_n, s (the first-order lag a slow response resembles)."""
    r = jax.tree.map(lambda a: np.asarray(a, np.float64), params["response"])
    w, z = np.exp(r["log_omega_n"]), np.exp(r["log_zeta"])
    return dict(omega_n_rad_s=w, f_n_hz=w / (2 * np.pi), zeta=z, delay_s=np.logaddexp(0.0, r["delay_raw"]),
                tau_equivalent_s=2 * z / w)


class Recurrent(nn.Module):
    """A black-box sequence model: a GRU over the standardised window inputs (flax's
    `GRUCell`, scanned along the windows by `nn.RNN`), read out linearly to PVV."""

    hidden: int = 16

    @nn.compact
    def __call__(self, x):
        h = nn.RNN(nn.GRUCell(self.hidden))(x)
        return nn.Dense(1)(h)[..., 0]


@partial(jax.jit, static_argnames=("n_in", "hidden"))  # one program per size (eagerly: one per operation)
def rnn_init(key, n_in: int, hidden: int = 16, *, scale: dict | None = None) -> dict:
    """A recurrent model's parameters: `rnn` (the `Recurrent` module's variables, `hidden`
    GRU units) and the standardisation `scale` (`nets.scaling`; default identity)."""
    scale = scale or dict(x_shift=jnp.zeros(n_in), x_scale=jnp.ones(n_in), y_shift=jnp.zeros(()),
                          y_scale=jnp.ones(()))
    return {"rnn": Recurrent(hidden).init(key, jnp.zeros((1, 2, n_in)))["params"], **scale}


@jax.jit  # one program per shape, inside another program or not
def rnn_apply(params: dict, x):
    """PVV through time from a recurrent model.

    Args:
        params: `rnn_init`'s dict.
        x: (..., W, n_in) the inputs averaged over each window (and their rates), physical
            units; the recurrence runs along W from a zero state.

    Returns:
        (..., W) PVV, g.
    """
    hidden = params["rnn"]["GRUCell_0"]["hn"]["kernel"].shape[0]  # the allocation: apply checks the shapes
    z = (x - params["x_shift"]) / params["x_scale"]
    lead = z.shape[:-2]
    flat = z.reshape((-1,) + z.shape[-2:])
    out = Recurrent(hidden).apply({"params": params["rnn"]}, flat).reshape(lead + z.shape[-2:-1])
    return out * params["y_scale"] + params["y_shift"]
