"""The paper's networks: multi-layer perceptrons and radial-basis-function networks, as flax
linen modules (`MLP`, `RBF`) applied as pure functions of a parameter PyTree, with the input
and output scaling stored beside the weights.

`mlp_apply(params, x)` and `rbf_apply(params, x)` apply the modules to a flat dict of arrays
(the trainable weights and the constants: masks and scalings), so parameters jit, vmap and
differentiate like any PyTree, stack over nets, and save to `.npz` without pickle
(`pvvjax.io`). A network takes inputs in physical units and returns peak PVV in g.

Architectures of different widths share one compiled program by padding: every hidden
layer is allocated at a maximum width and carries a 0/1 mask of its active units, and
the input layer carries a mask of the active inputs (so databases with 6, 7 and 8 inputs
stack into one array). A masked unit outputs exactly 0, so it contributes nothing to the
output and receives no gradient: the padded net computes what its unpadded twin computes.

An MLP may have several outputs (`n_out`), e.g. the N/rev of the three pilot-floor axes
from one flight state: its output scaling is then per output, and it returns (..., n_out).
"""

from __future__ import annotations

from functools import partial
from typing import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from .._arguments import number, refuse
from ..data.batch import bucket_size, pad_rows
from ._sums import affine

__all__ = [
    "MLP",
    "RBF",
    "apply_for",
    "architecture_name",
    "mlp_apply",
    "mlp_init",
    "mlp_pad",
    "n_weights",
    "rbf_apply",
    "rbf_fit",
    "scaling",
]


def scaling(x, y, in_mask=None):
    """Input/output standardisation from training data (masked inputs get shift 0, scale 1).

    Args:
        x: (n, d) inputs. y: (n,) outputs, or (n, k) for a net of k outputs.
        in_mask: (d,) active inputs (default all).

    Returns:
        dict with x_shift, x_scale (d,), y_shift, y_scale (() or (k,)).

    The rows are padded to a `bucket_size` count with weight 0, so one compiled program
    serves every training set of similar size.
    """
    x, y = np.asarray(x, np.float32), np.asarray(y, np.float32)
    in_mask = np.ones(x.shape[-1], np.float32) if in_mask is None else np.asarray(in_mask, np.float32)
    n = x.shape[0]
    m = bucket_size(n)
    w = (np.arange(m) < n).astype(np.float32)
    return _weighted_scaling(pad_rows(x, m), pad_rows(y, m), w, in_mask)


@jax.jit
def _weighted_scaling(x, y, w, in_mask):
    """`scaling` over the rows of weight w (0/1)."""
    n = jnp.maximum(jnp.sum(w), 1.0)
    mx = (w @ x) / n
    sd = jnp.sqrt((w @ (x - mx) ** 2) / n)
    if y.ndim == 1:
        my = jnp.sum(w * y) / n
        sy = jnp.sqrt(jnp.sum(w * (y - my) ** 2) / n)
    else:  # one scaling per output
        my = (w @ y) / n
        sy = jnp.sqrt((w @ (y - my) ** 2) / n)
    return dict(x_shift=mx * in_mask, x_scale=jnp.where((sd > 0) & (in_mask > 0), sd, 1.0), y_shift=my,
                y_scale=jnp.maximum(sy, 1e-6))


def mlp_init(key, n_in: int, hidden: Sequence[int], *, max_hidden: Sequence[int] | None = None,
             in_mask=None, scale: dict | None = None, n_out: int = 1) -> dict:
    """Initialise an MLP n_in-hidden...-n_out (tanh hidden layers, linear output).

    Args:
        key: PRNG key.
        n_in: number of inputs (allocated; `in_mask` says which are active).
        hidden: active widths of the hidden layers, e.g. (10, 5) for the paper's 6-10-5-1.
        max_hidden: allocated widths (default `hidden`): pad to share a compiled program.
        in_mask: (n_in,) 0/1 active inputs (default all).
        scale: output of `scaling` (default identity).
        n_out: outputs; 1 gives a net of output shape (...,), more (..., n_out).

    Returns:
        Parameter dict: layers (tuple of {w, b}), masks (tuple of (width,) hidden-unit
        masks), in_mask, and the scaling entries.
    """
    number("mlp_init", "n_in", n_in, at_least=1, whole=True)
    number("mlp_init", "n_out", n_out, at_least=1, whole=True)
    hidden = tuple(number("mlp_init", "hidden", h, at_least=1, whole=True) for h in _widths("hidden", hidden))
    max_hidden = tuple(number("mlp_init", "max_hidden", h, at_least=1, whole=True)
                       for h in _widths("max_hidden", max_hidden or hidden))
    # The constants on the host (NumPy: an XLA program per shape eagerly).
    in_mask = np.ones(n_in, np.float32) if in_mask is None else np.asarray(in_mask, np.float32)
    layers = _glorot_layers(key, n_in, tuple(hidden), max_hidden, in_mask, n_out)
    masks = tuple((np.arange(m) < h).astype(np.float32) for h, m in zip(hidden, max_hidden))
    return dict(layers=layers, masks=masks, in_mask=in_mask, **(scale or _identity_scaling(n_in, n_out)))


def _widths(name: str, v) -> tuple:
    """Hidden-layer widths as a tuple, or an `ArgumentError` naming `name`."""
    if isinstance(v, (str, bytes)) or not hasattr(v, "__iter__"):
        raise refuse("mlp_init", name, v, "a sequence of layer widths, e.g. (10, 5)")
    return tuple(v)


def _glorot_layers(key, n_in: int, hidden, max_hidden=(), in_mask=None, n_out: int = 1) -> tuple:
    """Layers {w, b} of an MLP allocated at `max_hidden`: Glorot-uniform on the *active*
    fan-in and fan-out (so padding does not change the draw), one key per layer split from
    `key`, zero biases."""
    max_hidden = tuple(max_hidden or hidden)
    if len(max_hidden) != len(hidden) or any(h > m for h, m in zip(hidden, max_hidden)):
        raise ValueError(f"hidden {tuple(hidden)} does not fit in max_hidden {max_hidden}")
    sizes = (n_in, *max_hidden, n_out)
    keys = jax.random.split(key, len(sizes) - 1)
    fan = (float(n_in if in_mask is None else np.sum(np.asarray(in_mask))), *map(float, hidden), float(n_out))
    layers = []
    for i, k in enumerate(keys):
        lim = np.sqrt(6.0 / (fan[i] + fan[i + 1]))
        layers.append(dict(w=jax.random.uniform(k, (sizes[i], sizes[i + 1]), minval=-lim, maxval=lim),
                           b=np.zeros(sizes[i + 1], np.float32)))
    return tuple(layers)


_SCALING = ("x_shift", "x_scale", "y_shift", "y_scale")


def _identity_scaling(n_in: int, n_out: int = 1) -> dict:
    y = () if n_out == 1 else (n_out,)
    return dict(x_shift=np.zeros(n_in, np.float32), x_scale=np.ones(n_in, np.float32), y_shift=np.zeros(y, np.float32),
                y_scale=np.ones(y, np.float32))


def _constants(module: nn.Module, names, defaults) -> dict:
    """The module's constants (masks, scalings); `defaults()`, called only to initialise
    them, gives their initial values."""
    return {k: module.variable("constants", k, lambda k=k: defaults()[k]).value for k in names}


def _variables(params: dict, trainable, constants) -> dict:
    """A flat parameter dict as the module's variables: "params" (trained) and "constants"."""
    return {"params": {k: params[k] for k in trainable}, "constants": {k: params[k] for k in constants}}


class MLP(nn.Module):
    """An MLP n_in-hidden...-n_out (tanh hidden layers, linear output) on standardised inputs.

    Variables: params `layers` ({w, b} per layer, allocated at `max_hidden`); constants
    `masks` (0/1 active units per hidden layer), `in_mask` (active inputs) and the scaling
    (`scaling`). A masked unit outputs exactly 0. `MLP(n_in, hidden, max_hidden).init(key, x)`
    draws the layers as `mlp_init` does, from the key linen derives for them.

    Attributes:
        n_in, hidden, max_hidden, n_out: the allocation and the active widths (for `init`
            only: `apply` takes the shapes from the variables).
    """

    n_in: int = 0
    hidden: tuple[int, ...] = ()
    max_hidden: tuple[int, ...] = ()
    n_out: int = 1

    @nn.compact
    def __call__(self, x):
        layers = self.param("layers", lambda key: _glorot_layers(key, self.n_in, self.hidden, self.max_hidden,
                                                                  n_out=self.n_out))
        alloc = self.max_hidden or self.hidden
        defaults = lambda: dict(  # noqa: E731
            masks=tuple((jnp.arange(m) < h).astype(jnp.float32) for h, m in zip(self.hidden, alloc)),
            in_mask=jnp.ones(self.n_in), **_identity_scaling(self.n_in, self.n_out))
        c = _constants(self, ("masks", "in_mask", *_SCALING), defaults)
        h = (x - c["x_shift"]) / c["x_scale"] * c["in_mask"]
        for layer, mask in zip(layers[:-1], c["masks"]):
            h = jnp.tanh(affine(h, layer["w"], layer["b"])) * mask
        out = affine(h, layers[-1]["w"], layers[-1]["b"])
        out = out[..., 0] if jnp.ndim(c["y_shift"]) == 0 else out  # one output: (...,)
        return out * c["y_scale"] + c["y_shift"]


@jax.jit  # one program per shape, inside another program or not
def mlp_apply(params: dict, x):
    """Evaluate an MLP (`MLP.apply` on a flat parameter dict as `mlp_init` makes it).
    x: (..., n_in) in physical units -> (...,) peak PVV, g ((..., n_out) for several outputs)."""
    layers = params["layers"]
    widths = tuple(int(layer["w"].shape[1]) for layer in layers[:-1])
    n_out = int(layers[-1]["w"].shape[1])
    module = MLP(int(layers[0]["w"].shape[0]), widths, widths, n_out)  # the allocation: apply checks the shapes
    return module.apply(_variables(params, ("layers",), ("masks", "in_mask", *_SCALING)), x)


def mlp_pad(params: dict, max_hidden: Sequence[int], n_in: int | None = None) -> dict:
    """The same network allocated at larger widths (and inputs): zero weights, masked units."""
    layers, masks = params["layers"], params["masks"]
    n_in0 = layers[0]["w"].shape[0]
    n_in = n_in or n_in0
    sizes = (n_in, *max_hidden, layers[-1]["w"].shape[1])
    def grown(a, shape, fill=0.0):  # on the host (NumPy: an XLA program per shape eagerly)
        a = np.asarray(a, np.float32)
        out = np.full(shape, fill, np.float32)
        out[tuple(slice(0, n) for n in a.shape)] = a
        return out

    new_layers = tuple(dict(w=grown(layer["w"], (sizes[i], sizes[i + 1])), b=grown(layer["b"], (sizes[i + 1],)))
                       for i, layer in enumerate(layers))
    new_masks = tuple(grown(mk, (m,)) for mk, m in zip(masks, max_hidden))
    return dict(layers=new_layers, masks=new_masks, in_mask=grown(params["in_mask"], (n_in,)),
                x_shift=grown(params["x_shift"], (n_in,)), x_scale=grown(params["x_scale"], (n_in,), 1.0),
                y_shift=params["y_shift"], y_scale=params["y_scale"])


def n_weights(n_in: int, hidden: Sequence[int], n_out: int = 1) -> int:
    """Weights and biases of an MLP n_in-hidden...-n_out."""
    sizes = (n_in, *hidden, n_out)
    return int(sum(a * b + b for a, b in zip(sizes[:-1], sizes[1:])))


def architecture_name(n_in: int, hidden: Sequence[int], n_out: int = 1) -> str:
    """The paper's notation, e.g. '6-10-5-1'."""
    return "-".join(str(int(v)) for v in (n_in, *hidden, n_out))


# --------------------------------------------------------------------------- RBF


def rbf_fit(key, x, y, n_centers: int, *, kmeans_steps: int = 30, width_factor: float = 2.0,
            ridge: float = 1e-3, in_mask=None) -> dict:
    """A Moody-Darken radial-basis-function network: k-means centres in scaled input space,
    widths of `width_factor` times the distance to the nearest other centre (so that
    neighbouring units overlap), and output weights by
    (ridge-regularised) linear least squares.

    One compiled program per `n_centers`, `kmeans_steps` and `bucket_size` of the rows: the
    rows are padded with weight 0 (a zero-weight row is no candidate centre, no member of a
    cluster and a zero row of the least squares), and the width factor and ridge are data.

    Returns:
        Parameter dict: centers (m, d), log_width (m,), w (m,), b (), in_mask and scaling.
    """
    x, y = np.asarray(x, np.float32), np.asarray(y, np.float32)
    in_mask = np.ones(x.shape[1], np.float32) if in_mask is None else np.asarray(in_mask, np.float32)
    n = x.shape[0]
    if n < n_centers:
        raise ValueError(f"{n_centers} RBF centres need at least as many training rows, got {n}")
    m = bucket_size(n)
    w = (np.arange(m) < n).astype(np.float32)
    return _rbf_fit(key, pad_rows(x, m), pad_rows(y, m), w, in_mask, np.float32(width_factor), np.float32(ridge),
                    n_centers=n_centers, kmeans_steps=kmeans_steps)


@partial(jax.jit, static_argnames=("n_centers", "kmeans_steps"))
def _rbf_fit(key, x, y, w, in_mask, width_factor, ridge, *, n_centers, kmeans_steps):
    """`rbf_fit` on the rows of weight w (0/1)."""
    sc = _weighted_scaling(x, y, w, in_mask)
    z = (x - sc["x_shift"]) / sc["x_scale"] * in_mask
    idx = jax.random.choice(key, x.shape[0], (n_centers,), replace=False, p=w / jnp.sum(w))
    c = z[idx]

    def step(c, _):
        d2 = jnp.sum((z[:, None, :] - c[None]) ** 2, -1)
        assign = jax.nn.one_hot(jnp.argmin(d2, 1), n_centers) * w[:, None]
        counts = assign.sum(0)
        new = (assign.T @ z) / jnp.maximum(counts, 1.0)[:, None]
        return jnp.where(counts[:, None] > 0, new, c), None

    c, _ = jax.lax.scan(step, c, None, length=kmeans_steps)
    dc = jnp.sqrt(jnp.sum((c[:, None] - c[None]) ** 2, -1) + jnp.eye(n_centers) * 1e9)
    width = width_factor * jnp.maximum(jnp.min(dc, 1), 1e-3)
    params = dict(centers=c, log_width=jnp.log(width), w=jnp.zeros(n_centers), b=jnp.zeros(()), in_mask=in_mask, **sc)
    phi = _rbf_features(params, x)
    design = jnp.concatenate([phi, jnp.ones((x.shape[0], 1))], 1) * w[:, None]
    t = (y - sc["y_shift"]) / sc["y_scale"] * w
    # Ridge least squares as ordinary least squares on [A; sqrt(ridge)·I] (SVD): the normal
    # equations of overlapping Gaussians are too ill-conditioned for float32.
    aug = jnp.concatenate([design, jnp.sqrt(ridge) * jnp.eye(n_centers + 1)], 0)
    # no truncation: the ridge regularises
    sol = jnp.linalg.lstsq(aug, jnp.concatenate([t, jnp.zeros(n_centers + 1)]), rcond=1e-7)[0]
    return {**params, "w": sol[:-1], "b": sol[-1]}


def _rbf_features(params, x):
    z = (x - params["x_shift"]) / params["x_scale"] * params["in_mask"]
    d2 = jnp.sum((z[..., None, :] - params["centers"]) ** 2, -1)
    return jnp.exp(-0.5 * d2 / jnp.exp(2 * params["log_width"]))


class RBF(nn.Module):
    """A radial-basis-function network: Gaussian units in standardised input space, a linear
    output layer. Variables: params `centers` (m, d), `log_width` (m,), `w` (m,), `b` ();
    constants `in_mask` and the scaling. Fitted by `rbf_fit` (k-means and least squares),
    not by gradient: `init` gives zeros of the right shapes.

    Attributes:
        n_centers, n_in: the units and inputs.
    """

    n_centers: int = 0
    n_in: int = 0

    @nn.compact
    def __call__(self, x):
        m, d = self.n_centers, self.n_in
        shapes = dict(centers=(m, d), log_width=(m,), w=(m,), b=())
        p = {k: self.param(k, lambda key, shape=shape: jnp.zeros(shape)) for k, shape in shapes.items()}
        p |= _constants(self, ("in_mask", *_SCALING), lambda: dict(in_mask=jnp.ones(d), **_identity_scaling(d)))
        out = _rbf_features(p, x) @ p["w"] + p["b"]
        return out * p["y_scale"] + p["y_shift"]


@jax.jit  # one program per shape, inside another program or not
def rbf_apply(params: dict, x):
    """Evaluate an RBF network (`RBF.apply` on `rbf_fit`'s parameter dict).
    x: (..., d) physical units -> (...,) peak PVV, g."""
    module = RBF(*map(int, params["centers"].shape))
    return module.apply(_variables(params, ("centers", "log_width", "w", "b"), ("in_mask", *_SCALING)), x)


def apply_for(params: dict):
    """The evaluation function of a parameter dict: `mlp_apply` or `rbf_apply` (by its keys,
    so it works on stacked parameters and under jit)."""
    if "layers" in params:
        return mlp_apply
    if "centers" in params:
        return rbf_apply
    raise ValueError(f"not network parameters (keys {sorted(params)})")
