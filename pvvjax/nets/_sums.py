"""Sums over rows whose bits do not depend on how many nets are batched together.

XLA's reductions choose their vectorisation from the whole array's shape, so the same net's
sum over its rows can round differently in a batch of 8 nets and in a batch of 64. Training
sums over rows twice: the loss, and (through broadcasting) the gradient of every bias. Here
the loss is a pairwise tree of elementwise adds, and the bias sits inside the layer's matrix
product, whose contraction over the rows rounds the same way in any batch (as the weights'
gradient does): on one device a net trains to the same bits alone, in a group, after
compaction or after a resume.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp


@partial(jax.jit, static_argnames="axis")  # one program per shape, inside another program or not
def pairwise_sum(v, axis: int = -1):
    """Sum of `v` over `axis` as a balanced tree of elementwise adds (zero-padded to a power
    of two), the same bits whatever the other axes hold."""
    axis = axis % v.ndim
    n = v.shape[axis]
    m = 1 << max(0, (n - 1).bit_length())
    if m > n:
        pad = [(0, 0)] * v.ndim
        pad[axis] = (0, m - n)
        v = jnp.pad(v, pad)
    while v.shape[axis] > 1:
        half = v.shape[axis] // 2
        v = jax.lax.slice_in_dim(v, 0, half, axis=axis) + jax.lax.slice_in_dim(v, half, 2 * half, axis=axis)
    return jnp.squeeze(v, axis)


@jax.jit
def affine(h, w, b):
    """h @ w + b with the bias inside the matrix product ([h, 1] @ [w; b]), so that its
    gradient is a contraction over the rows like the weights', not a reduction."""
    ones = jnp.ones(h.shape[:-1] + (1,), h.dtype)
    return jnp.concatenate([h, ones], -1) @ jnp.concatenate([w, b[None]], 0)
