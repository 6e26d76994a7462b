"""O(1) `searchsorted` on a fixed, increasing, nearly uniform array.

`jnp.searchsorted` is a loop of ~log2(T) steps, and on CPU each step of an XLA loop costs
about a microsecond: several searches in a microsecond-scale function dominate it. A table
built once per record (the first index at or after each of a fine, uniform grid of values)
answers a search with two gathers and a few comparisons.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .data.batch import bucket_size

__all__ = ["Lookup", "make_lookup", "search"]


class Lookup(NamedTuple):
    """Search table of one increasing array xp (leading batch axes allowed).

    Attributes:
        origin: xp[0]. inv_step: 1 / grid step (half the smallest spacing of xp).
        table: (K,) first index i with xp[i] >= origin + k·step.
    """

    origin: jax.Array
    inv_step: jax.Array
    table: jax.Array


def make_lookup(xp) -> Lookup:
    """Table for `search` on xp (..., T), NumPy, run once (outside jit)."""
    xp = np.asarray(xp, np.float64)
    if xp.ndim > 1:
        parts = [make_lookup(row) for row in xp.reshape(-1, xp.shape[-1])]
        K = max(p.table.shape[0] for p in parts)
        table = np.stack([np.pad(np.asarray(p.table), (0, K - p.table.shape[0]), mode="edge") for p in parts])
        return Lookup(np.stack([p.origin for p in parts]).reshape(xp.shape[:-1]),
                      np.stack([p.inv_step for p in parts]).reshape(xp.shape[:-1]),
                      table.reshape(*xp.shape[:-1], K))
    d = np.diff(xp)
    if not (d > 0).all():
        raise ValueError("lookup table needs a strictly increasing array")
    step = 0.5 * float(d.min())
    K = bucket_size(int(np.ceil((xp[-1] - xp[0]) / step)) + 2)  # few table sizes, so few compiled programs
    table = np.searchsorted(xp, xp[0] + step * np.arange(K)).astype(np.int32)
    dt = np.float32
    return Lookup(np.asarray(xp[0], dt), np.asarray(1.0 / step, dt), table)


def search(lk: Lookup, xp, x):
    """`jnp.searchsorted(xp, x)` (side "left") through the table: exact, O(1) per query."""
    K = lk.table.shape[-1]
    T = xp.shape[-1]
    k = jnp.clip(jnp.floor((x - lk.origin) * lk.inv_step).astype(jnp.int32) - 1, 0, K - 1)
    i = lk.table[k]
    # From one grid step before x at most three samples can lie below x (steps are half the
    # smallest spacing; one more for float rounding of k). A loop rather than unrolled: its
    # result is materialised, whereas XLA would fuse the unrolled steps into every gather
    # that uses the index and redo them per gathered element.
    step = lambda _, i: i + (xp[jnp.minimum(i, T - 1)] < x) * (i < T)  # noqa: E731
    return jax.lax.fori_loop(0, 3, step, i, unroll=False)
