"""Many nets trained in one loop that stays on the device.

Nets that train on the same data (one database and split) form a group; the batch is a
(G, W) table of G groups with W nets each (a group with fewer nets repeats them). The step
is vmapped over groups and, inside, over the nets of a group with the data shared, so a
layer of a group's nets is one large matrix product rather than W small ones. When more
than one JAX device exists the net axis is sharded across them.

A segment (`train.run` vmapped) trains on the device until every net has stopped (budget,
patience or divergence, kept per net) or a number of evaluations has passed. Between
segments the host reads only the (G, W) stop flags. It pulls a net's parameters once, after
the net has stopped: at a checkpoint (`checkpoint_s`, counted in seconds, so a long sweep
can be killed and resumed), before compaction drops it, and at the end.

Compaction pays where a step costs in proportion to the nets in the batch (CPU): when the
nets still training fit in half the width, they are gathered on the device into a narrower
batch. Widths are powers of two and the rule depends only on which nets have stopped, so
a layout's program compiles once (per process, and on disk with `pvvjax sweep`) and every
later sweep or discovery round reuses it; halving the work of the remaining evaluations
pays for that compile after the first run. On an accelerator a step of thousands of small
nets costs about what a step of a few costs, so the batch keeps its layout and the loop
runs to the end (or the next checkpoint) in one call.

A net's arithmetic does not depend on its batch (`_sums`: the loss sums rows as a pairwise
tree and each bias sits inside its layer's matrix product; and a batch holds at least 2
nets per device and 2 rows), so on one device a net trains to the same bits alone, in any
group, compacted or resumed. (Sharded, XLA partitions the program into other arithmetic:
the same to float32 rounding.)
"""

from __future__ import annotations

import math
import time
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from ..interrupts import check_interrupt
from . import train as _train
from .networks import mlp_apply

__all__ = ["predict_many", "stack_trees", "train_nets"]


def stack_trees(trees):
    """One PyTree whose leaves are the given trees' leaves stacked on a new leading axis (NumPy)."""
    return jax.tree.map(lambda *a: np.stack([np.asarray(v) for v in a]), *trees)


@partial(jax.jit, static_argnames=("apply",))
def _predict(params, x, apply):
    return jax.vmap(apply)(params, x)


def predict_many(params, x, apply=mlp_apply):
    """Predictions of stacked nets (N, ...) on stacked inputs (N, n, d) -> (N, n), the same
    bits for a net whatever the others (a lone net is computed beside a copy: XLA compiles
    a batch of one to other arithmetic)."""
    n = jax.tree.leaves(params)[0].shape[0]
    if n == 1:
        params, x = jax.tree.map(lambda a: jnp.concatenate([a, a]), (params, x))
    return _predict(params, x, apply)[:n]


def _take(tree, idx):
    return jax.tree.map(lambda a: a[idx], tree)


def _bucket(n: int, multiple: int) -> int:
    b = 1 << max(0, math.ceil(math.log2(max(n, 1))))
    return max(multiple, -(-b // multiple) * multiple)


def _inner(f):
    return jax.vmap(f, in_axes=(0, 0, None))  # the nets of a group share its data


@partial(jax.jit, static_argnames=("apply",))
def _init(train_params, consts, hp, data, apply):
    init = jax.vmap(lambda p, c, h, d: _train.init_state({**c, **p}, d, h, apply), in_axes=(0, 0, 0, None))
    return jax.vmap(init)(train_params, consts, hp, data)


@partial(jax.jit, static_argnames=("eval_every", "apply"))
def _segment(state, consts, data, evals, eval_every, apply):
    """At most `evals` evaluations of every net of the (G, W) batch (a traced count: one
    program for any segment length); the nets' stop flags (G, W)."""
    run = _inner(lambda s, c, d: _train.run(s, c, d, eval_every, evals, apply))
    new = jax.vmap(run)(state, consts, data)
    return new, jax.vmap(jax.vmap(_train.done))(new)


_PROGRAMS: dict = {}  # compiled segments by layout


def _program(state, consts, data, evals, eval_every, apply):
    """The compiled segment for these shapes (compiled once per process; `pvvjax sweep`
    also keeps them on disk: `experiment.enable_compilation_cache`). The training settings
    are in the state, so they are not part of the key."""
    key = (eval_every, apply, jax.tree.structure((state, consts, data)),
           tuple((a.shape, a.dtype, getattr(a, "sharding", None)) for a in jax.tree.leaves((state, consts, data))))
    if key not in _PROGRAMS:
        _PROGRAMS[key] = _segment.lower(state, consts, data, evals, eval_every=eval_every, apply=apply).compile()
    return _PROGRAMS[key]


@jax.jit
def _regroup(tree, idx):
    """Entries idx (G, W') of each group's row of a (G, W, ...) batch, on the device."""
    rows = jnp.arange(idx.shape[0])[:, None]
    return jax.tree.map(lambda a: a[rows, idx], tree)


@jax.jit
def _fits(state, consts, g, w):
    """The `Fit`s of the batch entries (g[i], w[i]), on the device."""
    return _train.result(_take(state, (g, w)), _take(consts, (g, w)))


class _Placement:
    """Where the batch lives: sharded on the net axis over the devices, data replicated."""

    def __init__(self, n_dev: int):
        self.n_dev = n_dev
        if n_dev > 1:
            from jax.sharding import Mesh, NamedSharding, PartitionSpec

            mesh = Mesh(np.array(jax.devices()), ("nets",))
            self.nets = NamedSharding(mesh, PartitionSpec(None, "nets"))
            self.replicated = NamedSharding(mesh, PartitionSpec())

    def batch(self, tree):
        return tree if self.n_dev <= 1 else jax.device_put(tree, self.nets)

    def data(self, tree):
        return tree if self.n_dev <= 1 else jax.device_put(tree, self.replicated)


def _layout(per_group, width):
    """(G, width) table of entries (each group's, repeated to fill; a group with none holds
    entry 0) and which are the first copy of one."""
    table = np.stack([np.resize(a if len(a) else np.zeros(1, int), width) for a in per_group])
    real = np.stack([np.arange(width) < len(a) for a in per_group])
    return table, real


def _pull(state, consts, entries):
    """Host `Fit`s of the batch entries [(g, w), ...], gathered on the device (the count
    padded to a power of two, so that few programs compile)."""
    g, w = np.array(entries).T
    m = _bucket(len(g), 1)
    fits = _to_host(_fits(state, consts, np.resize(g, m), np.resize(w, m)))
    return jax.tree.map(lambda a: a[: len(g)], fits)


def train_nets(params, data: _train.Data, group, cfg, *, hyper: _train.Hyper | None = None, chunk_evals: int = 8,
               checkpoint_s: float | None = None, compact: bool | None = None, on_done=None, apply=mlp_apply):
    """Train a stack of nets (leading axis N) to completion in one on-device loop.

    Args:
        params: stacked parameters (N, ...).
        data: `Data` of each group, stacked (G, ...).
        group: (N,) group index of each net.
        cfg: `TrainConfig` (its `eval_every` is the one setting compiled into the program).
        hyper: each net's training settings, a `Hyper` of (N,) arrays (None: the config's
            for every net); traced, so nets of other learning rates, weight decays, budgets
            or patiences share the batch and the compiled program.
        chunk_evals: with compaction, evaluations between looks at the stop flags.
        checkpoint_s: hand finished nets to `on_done` at least this often, s (None: at the end).
        compact: gather the nets still training into a narrower batch when they fit in
            half of it (None: on CPU only).
        on_done: callback(indices, fits, seconds) for nets that finished since the last
            call (host arrays; `seconds`: each net's share of the wall time).

    Returns:
        Stacked `Fit` of all nets (host arrays), in input order.
    """
    group = np.asarray(group)
    n, n_groups = group.size, jax.tree.leaves(data)[0].shape[0]
    place = _Placement(jax.device_count())
    compact = jax.default_backend() == "cpu" if compact is None else compact
    per = [np.flatnonzero(group == g) for g in range(n_groups)]
    if n_groups == 1:  # XLA compiles a batch axis of one to other arithmetic: two rows of the same data
        per = [per[0][::2], per[0][1::2]] if per[0].size > 1 else [per[0], per[0][:0]]
        data = jax.tree.map(lambda a: jnp.concatenate([a, a]), data)
    # Widths are powers of two above the first layout's (at most 8, not rounded up, so a
    # group of 3 or 5 nets is not padded to 4 or 8): few shapes, so few compilations.
    # At least 2 nets per device and 2 rows: XLA compiles a batch axis of one to other
    # arithmetic (other last bits), and a lone net's repeat costs little.
    largest = max(len(a) for a in per)
    least = max(2 * place.n_dev, min(_bucket(8, place.n_dev), -(-largest // place.n_dev) * place.n_dev))

    def width(most):
        return least if most <= least else _bucket(most, place.n_dev)

    table, real = _layout(per, width(largest))
    consts = {k: v for k, v in params.items() if k not in _train.TRAINABLE}
    if hyper is None:
        hyper = jax.tree.map(lambda a: np.full(n, a), _train.hyper(cfg))
    c = place.batch(_take(consts, table))
    data = place.data(data)
    state = _init(place.batch({k: v for k, v in _take(params, table).items() if k in _train.TRAINABLE}), c,
                  place.batch(_take(jax.tree.map(np.asarray, hyper), table)), data, apply)
    ledger = _Ledger(n, on_done)
    total_evals = -(-int(np.max(hyper.max_steps)) // cfg.eval_every) + 1
    # Segments: `chunk_evals` while the batch may still narrow, else to the end or to the
    # next checkpoint.
    narrows = lambda: compact and table.shape[1] > least  # noqa: E731
    evals, last = (chunk_evals if narrows() or checkpoint_s is not None else total_evals), time.perf_counter()
    while True:
        program = _program(state, c, data, jnp.int32(evals), cfg.eval_every, apply)
        t0 = time.perf_counter()
        state, stop = program(state, c, data, jnp.int32(evals))
        ledger.stopped(table, real, _to_host(stop), time.perf_counter() - t0)
        check_interrupt()  # between segments: a Ctrl-C lost inside a finalizer stops here
        done = ledger.finished.all()
        due = done or (checkpoint_s is not None and time.perf_counter() - last >= checkpoint_s)
        keep = real & ~ledger.finished[table]
        shrink = compact and not done and width(keep.sum(1).max()) <= table.shape[1] // 2
        if due or shrink:
            ledger.pull(state, c, table)
        if due:
            last = ledger.report() or last
        if done:
            return ledger.fits()
        if shrink:
            idx, real = _layout([np.flatnonzero(k) for k in keep], width(keep.sum(1).max()))
            table = np.take_along_axis(table, idx, axis=1)
            state, c = place.batch(_regroup((state, c), jnp.asarray(idx)))
        if narrows():
            evals = chunk_evals
        elif checkpoint_s is None:
            evals = total_evals
        else:  # segments of about the checkpoint interval
            evals = int(min(total_evals, max(chunk_evals, evals * checkpoint_s / max(ledger.last_s, 1e-9))))


class _Ledger:
    """The host's account of a training: which nets stopped, where those not yet pulled sit
    in the batch, the fits pulled but not yet handed to `on_done`, and each net's seconds."""

    def __init__(self, n: int, on_done):
        self.finished, self.spent, self.on_done = np.zeros(n, bool), np.zeros(n), on_done
        self.unpulled, self.pending, self.pulled, self.last_s = [], [], [], 0.0

    def stopped(self, table, real, stop, seconds: float):
        """Record a segment: its stop flags (G, W) and wall time, shared by the nets it ran."""
        running = real & ~self.finished[table]
        self.spent[table[running]] += seconds / running.sum()
        new = running & stop
        self.finished[table[new]] = True
        self.unpulled += list(zip(*np.nonzero(new)))
        self.last_s = seconds

    def pull(self, state, consts, table):
        """Bring the fits of the stopped nets to the host (before the batch drops them)."""
        if self.unpulled:
            self.pending.append((table[tuple(np.array(self.unpulled).T)], _pull(state, consts, self.unpulled)))
            self.unpulled = []

    def report(self) -> float | None:
        """Hand the pulled fits to `on_done`; the time, or None if there was nothing."""
        if not self.pending:
            return None
        self.pulled += self.pending
        if self.on_done is not None:
            ids = np.concatenate([i for i, _ in self.pending])
            fits = jax.tree.map(lambda *a: np.concatenate(a), *[f for _, f in self.pending])
            self.on_done(ids, fits, self.spent[ids])
        self.pending = []
        return time.perf_counter()

    def fits(self):
        """Every net's `Fit`, stacked in input order."""
        ids = np.concatenate([i for i, _ in self.pulled])
        order = np.argsort(ids)
        return jax.tree.map(lambda *a: np.concatenate(a)[order], *[f for _, f in self.pulled])


def _to_host(tree):
    """Host copies of (possibly sharded) arrays; across hosts (`jax.distributed`) every
    process gathers the whole batch."""
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        return jax.tree.map(np.asarray, multihost_utils.process_allgather(tree, tiled=True))
    return jax.tree.map(np.asarray, tree)
