"""Sums over rows whose bits do not depend on how many nets are batched together.

XLA's reductions choose their vectorisation from the whole array's shape, so the same net's
sum over its rows can round differently in a batch of 8 nets and in a batch of 64. Training
sums over rows twice: the loss, and (through broadcasting) the gradient of every bias. Here
both are pairwise trees of elementwise adds, which round the same way in any batch: on one
device a net trains to the same bits alone, in a group, after compaction or after a resume.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp


def pairwise_sum(v, axis: int = -1):
    """Sum of `v` over `axis` as a balanced tree of elementwise adds (zero-padded to a power
    of two), the same bits whatever the other axes hold."""
    v = jnp.moveaxis(v, axis, -1)
    n = v.shape[-1]
    m = 1 << max(0, (n - 1).bit_length())
    if m > n:
        v = jnp.concatenate([v, jnp.zeros(v.shape[:-1] + (m - n,), v.dtype)], axis=-1)
    while v.shape[-1] > 1:
        half = v.shape[-1] // 2
        v = v[..., :half] + v[..., half:]
    return v[..., 0]


def add_bias(z, b):
    """z (..., k) + b (k,), whose gradient in b sums the rows with `pairwise_sum` (only the
    bias is a custom rule: forward-mode derivatives in the inputs, as calibration takes
    them, see a plain add)."""
    return z + _broadcast_rows(b, z.shape)


@partial(jax.custom_vjp, nondiff_argnums=(1,))
def _broadcast_rows(b, shape):
    return jnp.broadcast_to(b, shape)


def _broadcast_rows_fwd(b, shape):
    return jnp.broadcast_to(b, shape), None


def _broadcast_rows_bwd(shape, _, g):
    return (pairwise_sum(g.reshape(-1, g.shape[-1]), axis=0),)


_broadcast_rows.defvjp(_broadcast_rows_fwd, _broadcast_rows_bwd)
