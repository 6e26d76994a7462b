"""Networks as pure functions of parameter PyTrees: multi-layer perceptrons and
radial-basis-function networks, with input and output scaling stored in the parameters.

Parameters are plain dicts of arrays, so they jit, vmap and differentiate, and they save
to `.npz` without pickle (`pvvjax.io`). A network takes inputs in physical units and
returns peak PVV in g.

Architectures of different widths share one compiled program by padding: every hidden
layer is allocated at a maximum width and carries a 0/1 mask of its active units, and
the input layer carries a mask of the active inputs (so databases with 6, 7 and 8 inputs
stack into one array). A masked unit outputs exactly 0, so it contributes nothing to the
output and receives no gradient: the padded net computes what its unpadded twin computes.
"""

from __future__ import annotations

from typing import Sequence

import jax
import jax.numpy as jnp
import numpy as np

__all__ = [
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
        x: (n, d) inputs. y: (n,) outputs. in_mask: (d,) active inputs (default all).

    Returns:
        dict with x_shift, x_scale (d,), y_shift, y_scale ().
    """
    x, y = jnp.asarray(x), jnp.asarray(y)
    in_mask = jnp.ones(x.shape[-1], x.dtype) if in_mask is None else jnp.asarray(in_mask, x.dtype)
    sd = jnp.std(x, axis=0)
    return dict(
        x_shift=jnp.mean(x, axis=0) * in_mask,
        x_scale=jnp.where((sd > 0) & (in_mask > 0), sd, 1.0),
        y_shift=jnp.mean(y),
        y_scale=jnp.maximum(jnp.std(y), 1e-6),
    )


def mlp_init(key, n_in: int, hidden: Sequence[int], *, max_hidden: Sequence[int] | None = None,
             in_mask=None, scale: dict | None = None) -> dict:
    """Initialise an MLP n_in-hidden...-1 (tanh hidden layers, linear output).

    Args:
        key: PRNG key.
        n_in: number of inputs (allocated; `in_mask` says which are active).
        hidden: active widths of the hidden layers, e.g. (10, 5) for the paper's 6-10-5-1.
        max_hidden: allocated widths (default `hidden`): pad to share a compiled program.
        in_mask: (n_in,) 0/1 active inputs (default all).
        scale: output of `scaling` (default identity).

    Returns:
        Parameter dict: layers (tuple of {w, b}), masks (tuple of (width,) hidden-unit
        masks), in_mask, and the scaling entries.
    """
    max_hidden = tuple(max_hidden or hidden)
    if len(max_hidden) != len(hidden) or any(h > m for h, m in zip(hidden, max_hidden)):
        raise ValueError(f"hidden {tuple(hidden)} does not fit in max_hidden {max_hidden}")
    sizes = (n_in, *max_hidden, 1)
    keys = jax.random.split(key, len(sizes) - 1)
    in_mask = jnp.ones(n_in) if in_mask is None else jnp.asarray(in_mask, jnp.float32)
    # Glorot-uniform on the *active* fan-in/fan-out, so padding does not change the init.
    fan = (float(jnp.sum(in_mask)), *map(float, hidden), 1.0)
    layers = []
    for i, k in enumerate(keys):
        lim = np.sqrt(6.0 / (fan[i] + fan[i + 1]))
        layers.append(dict(w=jax.random.uniform(k, (sizes[i], sizes[i + 1]), minval=-lim, maxval=lim),
                           b=jnp.zeros(sizes[i + 1])))
    masks = tuple((jnp.arange(m) < h).astype(jnp.float32) for h, m in zip(hidden, max_hidden))
    scale = scale or dict(x_shift=jnp.zeros(n_in), x_scale=jnp.ones(n_in), y_shift=jnp.zeros(()),
                          y_scale=jnp.ones(()))
    return dict(layers=tuple(layers), masks=masks, in_mask=in_mask, **scale)


def mlp_apply(params: dict, x):
    """Evaluate an MLP. x: (..., n_in) in physical units -> (...,) peak PVV, g."""
    h = (x - params["x_shift"]) / params["x_scale"] * params["in_mask"]
    layers = params["layers"]
    for layer, mask in zip(layers[:-1], params["masks"]):
        h = jnp.tanh(h @ layer["w"] + layer["b"]) * mask
    out = (h @ layers[-1]["w"] + layers[-1]["b"])[..., 0]
    return out * params["y_scale"] + params["y_shift"]


def mlp_pad(params: dict, max_hidden: Sequence[int], n_in: int | None = None) -> dict:
    """The same network allocated at larger widths (and inputs): zero weights, masked units."""
    layers, masks = params["layers"], params["masks"]
    n_in0 = layers[0]["w"].shape[0]
    n_in = n_in or n_in0
    sizes = (n_in, *max_hidden, 1)
    new_layers = []
    for i, layer in enumerate(layers):
        w = jnp.zeros((sizes[i], sizes[i + 1])).at[: layer["w"].shape[0], : layer["w"].shape[1]].set(layer["w"])
        b = jnp.zeros(sizes[i + 1]).at[: layer["b"].shape[0]].set(layer["b"])
        new_layers.append(dict(w=w, b=b))
    new_masks = tuple(jnp.zeros(m).at[: mk.shape[0]].set(mk) for mk, m in zip(masks, max_hidden))
    pad_in = n_in - n_in0
    return dict(layers=tuple(new_layers), masks=new_masks,
                in_mask=jnp.concatenate([params["in_mask"], jnp.zeros(pad_in)]),
                x_shift=jnp.concatenate([params["x_shift"], jnp.zeros(pad_in)]),
                x_scale=jnp.concatenate([params["x_scale"], jnp.ones(pad_in)]),
                y_shift=params["y_shift"], y_scale=params["y_scale"])


def n_weights(n_in: int, hidden: Sequence[int]) -> int:
    """Weights and biases of an MLP n_in-hidden...-1."""
    sizes = (n_in, *hidden, 1)
    return int(sum(a * b + b for a, b in zip(sizes[:-1], sizes[1:])))


def architecture_name(n_in: int, hidden: Sequence[int]) -> str:
    """The paper's notation, e.g. '6-10-5-1'."""
    return "-".join(str(int(v)) for v in (n_in, *hidden, 1))


# --------------------------------------------------------------------------- RBF


def rbf_fit(key, x, y, n_centers: int, *, kmeans_steps: int = 30, width_factor: float = 2.0,
            ridge: float = 1e-3, in_mask=None) -> dict:
    """A Moody-Darken radial-basis-function network: k-means centres in scaled input space,
    widths of `width_factor` times the distance to the nearest other centre (so that
    neighbouring units overlap), and output weights by
    (ridge-regularised) linear least squares. Pure and jittable (n_centers static).

    Returns:
        Parameter dict: centers (m, d), log_width (m,), w (m,), b (), in_mask and scaling.
    """
    x, y = jnp.asarray(x, jnp.float32), jnp.asarray(y, jnp.float32)
    sc = scaling(x, y, in_mask)
    in_mask = jnp.ones(x.shape[1]) if in_mask is None else jnp.asarray(in_mask, jnp.float32)
    z = (x - sc["x_shift"]) / sc["x_scale"] * in_mask
    idx = jax.random.choice(key, x.shape[0], (n_centers,), replace=False)
    c = z[idx]

    def step(c, _):
        d2 = jnp.sum((z[:, None, :] - c[None]) ** 2, -1)
        assign = jax.nn.one_hot(jnp.argmin(d2, 1), n_centers)
        counts = assign.sum(0)
        new = (assign.T @ z) / jnp.maximum(counts, 1.0)[:, None]
        return jnp.where(counts[:, None] > 0, new, c), None

    c, _ = jax.lax.scan(step, c, None, length=kmeans_steps)
    dc = jnp.sqrt(jnp.sum((c[:, None] - c[None]) ** 2, -1) + jnp.eye(n_centers) * 1e9)
    width = width_factor * jnp.maximum(jnp.min(dc, 1), 1e-3)
    params = dict(centers=c, log_width=jnp.log(width), w=jnp.zeros(n_centers), b=jnp.zeros(()), in_mask=in_mask, **sc)
    phi = _rbf_features(params, x)
    design = jnp.concatenate([phi, jnp.ones((x.shape[0], 1))], 1)
    t = (y - sc["y_shift"]) / sc["y_scale"]
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


def rbf_apply(params: dict, x):
    """Evaluate an RBF network. x: (..., d) physical units -> (...,) peak PVV, g."""
    out = _rbf_features(params, x) @ params["w"] + params["b"]
    return out * params["y_scale"] + params["y_shift"]


def apply_for(params: dict):
    """The evaluation function of a parameter dict: `mlp_apply` or `rbf_apply` (by its keys,
    so it works on stacked parameters and under jit)."""
    if "layers" in params:
        return mlp_apply
    if "centers" in params:
        return rbf_apply
    raise ValueError(f"not network parameters (keys {sorted(params)})")
