"""Sweeps: many nets (databases × architectures × seeds × folds) trained in one program.

Nets of one depth share a compiled program: hidden layers are allocated at the widest
architecture of the sweep and masked (`networks`), and the inputs of db1-db3 (6, 8 and 7)
are padded to 8 with an input mask. The stacked nets are vmapped; when more than one JAX
device exists the net axis is sharded across them (`jax.sharding`). Training runs in
chunks of `chunk_evals` evaluations; between chunks finished nets leave the batch, which
shrinks to the next power of two, so the cost follows the nets' own step counts rather
than the slowest net's.

The shell around it (`run_sweep`) is resumable: the parameters of each finished net are
written to `params/<net_id>.npz`, then the result rows of the nets that finished together
to one file in `parts/`, each under a temporary name and renamed (a net counts as done
once its row is in a part), so a sweep killed at any point and run again with the
same config trains only the missing nets, keeps every finished one, and leaves no
duplicate row and no half-written file. `results.parquet` gathers the parts at the end.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from functools import partial
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from .._strict import to_dict
from ..analysis.databases import DB_INPUTS, OUTPUT
from ..config import ExperimentConfig, config_hash
from ..data.fingerprint import tables_fingerprint
from ..io import claim_folder, write_config
from ..realtime.npnet import read_npz
from . import train as _train
from .networks import architecture_name, mlp_apply, mlp_init, n_weights, rbf_apply, rbf_fit, scaling

__all__ = [
    "N_INPUTS",
    "SWEEP_AXES",
    "collect",
    "databases_fingerprint",
    "heldout_models",
    "load_params",
    "net_table",
    "run_sweep",
    "save_params",
    "stack_data",
    "sweep_settings",
    "train_nets",
]

N_INPUTS = max(len(v) for v in DB_INPUTS.values())  # every database padded to this many inputs


# --------------------------------------------------------------------------- planning


def databases_fingerprint(dbs: dict, databases) -> str:
    """Content hash (16 hex digits) of the named database tables: the data a sweep's nets
    are trained on, which changes whenever the campaign's content changes what they hold."""
    return tables_fingerprint({db: dbs[db] for db in databases})


# The sweep's axes: they decide which nets exist, not how each is trained, so a sweep grows
# (or narrows) in its folder; every other setting is the folder's own.
SWEEP_AXES = ("databases", "hidden", "centers", "seeds", "test_folds")


def sweep_settings(cfg: ExperimentConfig) -> dict:
    """The settings that decide how each net of a sweep is trained: what its folder is
    claimed for (`io.claim_folder`). The axes (`SWEEP_AXES`) are not among them."""
    campaign = {k: v for k, v in to_dict(cfg.campaign).items() if k != "path"}  # the content counts, not where
    sweep = {k: v for k, v in to_dict(cfg.sweep).items() if k not in SWEEP_AXES}
    return dict(sweep=sweep, train=to_dict(cfg.train), analysis=to_dict(cfg.analysis), campaign=campaign,
                seed=cfg.seed)


def net_table(cfg: ExperimentConfig, data: str = "") -> pd.DataFrame:
    """One row per net of the sweep, with a stable id: the same config and data (the
    `databases_fingerprint`) give the same ids, and nothing else does."""
    sw, tr = cfg.sweep, cfg.train
    archs = sw.hidden if sw.family == "mlp" else tuple((c,) for c in sw.centers)
    rows = []
    for db in sw.databases:
        for hidden in archs:
            for seed in range(sw.seeds):
                for fold in sw.fold_list:
                    key = dict(db=db, family=sw.family, hidden=list(hidden), seed=seed, fold=fold, k=sw.folds,
                               split_seed=sw.split_seed, train=to_dict(tr), analysis=to_dict(cfg.analysis),
                               campaign=sweep_settings(cfg)["campaign"], exp_seed=cfg.seed, data=data)
                    net_id = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]
                    rows.append(dict(net_id=net_id, database=db, family=sw.family, hidden="-".join(map(str, hidden)),
                                     architecture=architecture_name(len(DB_INPUTS[db]), hidden) if sw.family == "mlp"
                                     else f"rbf-{hidden[0]}", depth=len(hidden), seed=seed, test_fold=fold,
                                     optimizer="adam" if sw.family == "mlp" else "kmeans+lstsq"))
    return pd.DataFrame(rows)


def stack_data(dbs: dict, databases, folds: int, split_seed: int):
    """Per-database arrays padded to `N_INPUTS` inputs.

    Returns:
        dict db -> (x (n, N_INPUTS), y (n,), in_mask (N_INPUTS,), fold of each row (n,)).
    """
    out = {}
    for db in databases:
        df = dbs[db]
        cols = list(DB_INPUTS[db])
        x = np.zeros((len(df), N_INPUTS), np.float32)
        x[:, : len(cols)] = df[cols].to_numpy(np.float32)
        mask = (np.arange(N_INPUTS) < len(cols)).astype(np.float32)
        fold = _train.condition_folds(df.condition, folds, split_seed, f"sweep.folds ({db})")
        out[db] = (x, df[OUTPUT].to_numpy(np.float32), mask, fold)
    return out


# --------------------------------------------------------------------------- core


def stack_trees(trees):
    """One PyTree whose leaves are the given trees' leaves stacked on a new leading axis (NumPy)."""
    return jax.tree.map(lambda *a: np.stack([np.asarray(v) for v in a]), *trees)


def _take(tree, idx):
    return jax.tree.map(lambda a: a[idx], tree)


def _bucket(n: int, multiple: int) -> int:
    b = 1 << max(0, math.ceil(math.log2(max(n, 1))))
    return max(multiple, -(-b // multiple) * multiple)


def _sharded(state, consts, data, n_dev):
    """Shard the net axis (axis 1 of the (groups, nets, ...) layout) over the devices;
    the groups' data are replicated."""
    if n_dev <= 1:
        return state, consts, data
    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    mesh = Mesh(np.array(jax.devices()), ("nets",))
    nets = NamedSharding(mesh, PartitionSpec(None, "nets"))
    return (jax.device_put(state, nets), jax.device_put(consts, nets),
            jax.device_put(data, NamedSharding(mesh, PartitionSpec())))


def _inner(f):
    return jax.vmap(f, in_axes=(0, 0, None))  # the nets of a group share its data


@partial(jax.jit, static_argnames=("cfg", "apply"))
def _init_chunk(train_params, consts, data, cfg, apply):
    return jax.vmap(_inner(lambda p, c, d: _train.init_state({**c, **p}, d, cfg, apply)))(train_params, consts, data)


@partial(jax.jit, static_argnames=("cfg", "chunk_evals", "apply"))
def _run_chunk(state, consts, data, cfg, chunk_evals, apply):
    run = _inner(lambda s, c, d: _train.run(s, c, d, cfg, chunk_evals, apply))
    new = jax.vmap(run)(state, consts, data)
    return new, jax.vmap(jax.vmap(lambda s: _train.done(s, cfg)))(new)


@partial(jax.jit, static_argnames=("apply",))
def predict_many(params, x, apply=mlp_apply):
    """Predictions of stacked nets (N, ...) on stacked inputs (N, n, d) -> (N, n)."""
    return jax.vmap(apply)(params, x)


def train_nets(params, data: _train.Data, group, cfg, *, chunk_evals: int = 8, on_done=None, apply=mlp_apply):
    """Train a stack of nets (leading axis N) to completion, with compaction.

    Nets that train on the same data (same database and split) form a group, and the
    data enter once per group: the compiled step is vmapped over groups and, inside, over
    the nets of a group with the data shared, so a layer of all the nets of a group is one
    large matrix product rather than N small ones.

    Args:
        params: stacked parameters (N, ...).
        data: `Data` of each group, stacked (G, ...).
        group: (N,) group index of each net.
        cfg: `TrainConfig`. chunk_evals: evaluations per chunk.
        on_done: callback(indices, fits, seconds) for nets that just finished (host arrays).

    Returns:
        Stacked `Fit` of all nets (host arrays), in input order.
    """
    group = np.asarray(group)
    n, n_groups = group.size, jax.tree.leaves(data)[0].shape[0]
    consts = {k: v for k, v in params.items() if k not in _train.TRAINABLE}
    n_dev = jax.device_count()
    state = None
    active = np.arange(n)
    spent = np.zeros(n)
    # Batch sizes are powers of two, at least the first chunk's (up to 8, not rounded up):
    # few shapes, so few compilations, and no group of 3 or 4 nets (discovery's seeds)
    # padded to 4 or 8 (the padded nets are computed and thrown away).
    largest = np.bincount(group, minlength=n_groups).max()
    least = min(_bucket(8, n_dev), -(-largest // n_dev) * n_dev)
    while active.size:
        # (G, M) table of net indices: each group's active nets, padded with repeats
        per = [active[group[active] == g] for g in range(n_groups)]
        most = max(len(a) for a in per)
        width = least if most <= least else _bucket(most, n_dev)
        table = np.stack([np.resize(a if len(a) else np.flatnonzero(group == g)[:1], width) for g, a in enumerate(per)])
        real = np.stack([np.arange(width) < len(a) for a in per])
        t0 = time.perf_counter()
        c = _take(consts, table)
        if state is None:
            st = _init_chunk({k: v for k, v in _take(params, table).items() if k in _train.TRAINABLE}, c, data, cfg,
                             apply)
        else:
            st = _take(state, table)
        new, fin = _run_chunk(*_sharded(st, c, data, n_dev), cfg, chunk_evals, apply)
        fin, new = _to_host((fin, new))
        dt = time.perf_counter() - t0
        ids, fin = table[real], fin[real]
        spent[ids] += dt / ids.size
        if state is None:  # allocate the full state once, from the first chunk's layout
            state = jax.tree.map(lambda a: np.zeros((n,) + a.shape[2:], a.dtype), new)
        state = jax.tree.map(lambda full, part: _scatter(full, ids, part[real]), state, new)
        finished = ids[fin]
        if on_done is not None and finished.size:
            fits = _train.result(_take(state, finished), _take(consts, finished))
            on_done(finished, jax.tree.map(np.asarray, fits), spent[finished])
        active = np.setdiff1d(active, finished)
    return jax.tree.map(np.asarray, _train.result(state, consts))


def _barrier(name: str):
    """Wait for every process of a multi-process run (nothing to wait for in one process)."""
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices(name)


def _to_host(tree):
    """Host copies of (possibly sharded) arrays; across hosts (`jax.distributed`) every
    process gathers the whole batch."""
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        return jax.tree.map(np.asarray, multihost_utils.process_allgather(tree, tiled=True))
    return jax.tree.map(np.asarray, tree)


def _scatter(full, idx, part):
    full = np.array(full, copy=True)
    full[idx] = part
    return full


# --------------------------------------------------------------------------- files


def save_params(path, params: dict, meta: dict) -> Path:
    """Save parameters as `.npz` (no pickle), written atomically; `meta` is stored as JSON."""
    path = Path(path)
    flat = {"/".join(str(getattr(k, "key", getattr(k, "idx", k))) for k in kp): np.asarray(v)
            for kp, v in jax.tree_util.tree_flatten_with_path(params)[0]}
    flat["__meta__"] = np.array(json.dumps(meta))
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez(tmp, **flat)
    tmp.replace(path)
    return path


def load_params(path) -> tuple[dict, dict]:
    """Load parameters saved by `save_params` (with `allow_pickle=False`)."""
    return read_npz(path)


def _split_sizes(data, sw) -> tuple[int, int]:
    """Largest train and validation row counts over databases and folds (common padding)."""
    n_tr = n_va = 0
    for _, _, _, folds in data.values():
        for f in range(sw.folds):
            w_tr, w_va, _ = _train.split_masks(folds, f, sw.folds)
            n_tr, n_va = max(n_tr, int(w_tr.sum())), max(n_va, int(w_va.sum()))
    return n_tr, n_va


def _atomic_parquet(df: pd.DataFrame, path: Path):
    tmp = path.with_name(path.name + ".tmp")
    df.to_parquet(tmp, index=False)
    tmp.replace(path)


def run_sweep(cfg: ExperimentConfig, dbs: dict, out: Path, *, progress=None, log=print) -> pd.DataFrame:
    """Train every net of `cfg.sweep` not yet finished in `out`; return the rows of its nets
    (`out/results.parquet` holds every net the folder has: a sweep grows there).

    Args:
        cfg: experiment config (sweep, train, analysis).
        dbs: databases (`build_databases`).
        out: sweep folder (created; reused to resume). It belongs to this config's sweep
            settings and data (`io.claim_folder`): other settings are refused there.
        progress: optional tqdm-like factory `progress(total=, initial=)`.
    """
    data_key = databases_fingerprint(dbs, [db for db in DB_INPUTS if db in dbs])
    writer = jax.process_index() == 0  # across processes (`jax.distributed`), process 0 writes
    if writer:
        out = claim_folder(out, sweep_settings(cfg), data_key)
        write_config(cfg, out / "config.toml")  # what `export` and `replay` read the sweep's settings from
        (out / "parts").mkdir(parents=True, exist_ok=True)
        (out / "params").mkdir(exist_ok=True)
    _barrier("pvvjax sweep folder claimed")  # every process then sees the same finished nets
    out = Path(out)
    nets = net_table(cfg, data_key)
    done_ids = set(collect(out).get("net_id", pd.Series(dtype=str)))
    todo = nets[~nets.net_id.isin(done_ids)].reset_index(drop=True)
    log(f"sweep: {len(nets)} nets, {len(nets) - len(todo)} already finished, {len(todo)} to train")
    data = stack_data(dbs, cfg.sweep.databases, cfg.sweep.folds, cfg.sweep.split_seed)
    bar = progress(total=len(nets), initial=len(nets) - len(todo)) if progress else None
    chash = config_hash(cfg, data_key)
    sw = cfg.sweep
    # One program per depth: on CPU a training step costs about the same for 30 nets as for
    # 300 (kernel overheads dominate), so fewer, larger batches beat less padding.
    groups = [g for _, g in todo.groupby("depth", sort=True)] if sw.family == "mlp" else [todo]
    for group in groups:
        if group.empty:
            continue
        group = group.reset_index(drop=True)
        if sw.family == "rbf":
            if writer:  # fitted on the host: one process does it
                _run_rbf(group, data, dbs, cfg, out, chash, bar)
            continue
        depth = int(group.depth.iloc[0])
        max_hidden = tuple(int(max(int(h.split("-")[i]) for h in group.hidden)) for i in range(depth))
        keys = sorted(set(zip(group.database, group.test_fold)))
        n_tr, n_va = _split_sizes(data, sw)
        gdata = []
        for db, fold in keys:
            x, y, in_mask, folds = data[db]
            w_tr, w_va, _ = _train.split_masks(folds, fold, sw.folds)
            gdata.append(_train.make_data(x, y, w_tr, w_va, n_tr, n_va))
        params = []
        for r in group.itertuples():
            x, y, in_mask, folds = data[r.database]
            w_tr, _, _ = _train.split_masks(folds, r.test_fold, sw.folds)
            sc = scaling(x[w_tr > 0], y[w_tr > 0], in_mask)
            hidden = tuple(int(v) for v in r.hidden.split("-"))
            params.append(mlp_init(jax.random.key(r.seed), N_INPUTS, hidden, max_hidden=max_hidden, in_mask=in_mask,
                                   scale=sc))
        gid = np.array([keys.index((r.database, r.test_fold)) for r in group.itertuples()])

        def on_done(idx, fits, seconds, group=group):
            if writer:
                _finish(group.iloc[idx], fits, seconds, data, dbs, cfg, out, chash)
            if bar is not None:
                bar.update(len(idx))

        train_nets(stack_trees(params), stack_trees(gdata), gid, cfg.train, chunk_evals=sw.chunk_evals, on_done=on_done)
    if bar is not None:
        bar.close()
    _barrier("pvvjax sweep trained")  # process 0 has written every part file
    results = collect(out)
    if writer:
        _atomic_parquet(results, out / "results.parquet")
    return results[results.net_id.isin(nets.net_id)].reset_index(drop=True) if len(results) else results


def collect(out: Path) -> pd.DataFrame:
    """All finished result rows of a sweep folder."""
    parts = sorted((Path(out) / "parts").glob("*.parquet"))
    if not parts:
        return pd.DataFrame()
    return pd.concat([pd.read_parquet(p, columns=None) for p in parts], ignore_index=True)


def _finish(rows: pd.DataFrame, fits, seconds, data, dbs, cfg, out: Path, chash: str, apply=mlp_apply):
    """Write the parameters and result rows of nets that just finished (one part file)."""
    failed = np.asarray(fits.failed_step)
    for j, r in enumerate(rows.itertuples()):
        if failed[j] >= 0:
            raise _train.TrainingError(
                f"net {r.database} {r.architecture} seed {r.seed} fold {r.test_fold} ({r.net_id}): training loss "
                f"not finite or diverging at step {int(failed[j])}; lower train.learning_rate or check the data")
    x = np.stack([data[db][0] for db in rows.database])
    preds = np.asarray(predict_many(fits.params, x, apply))
    out_rows = []
    for j, r in enumerate(rows.itertuples()):
        p = jax.tree.map(lambda a: a[j], fits.params)
        out_rows.append(_net_row(r, p, preds[j], float(seconds[j]), int(fits.best_step[j]), int(fits.steps[j]), data,
                                 dbs, cfg, out, chash))
    _atomic_parquet(pd.DataFrame(out_rows), out / "parts" / f"{rows.net_id.iloc[0]}-{len(rows)}.parquet")


def _net_row(r, p, pred, seconds, best_step, steps, data, dbs, cfg, out, chash) -> dict:
    """Save one net's parameters and return its result row."""
    x, y, in_mask, folds = data[r.database]
    w_tr, w_va, w_te = _train.split_masks(folds, r.test_fold, cfg.sweep.folds)
    row = {k: v for k, v in r._asdict().items() if k != "Index"}
    for split, w in (("train", w_tr), ("val", w_va), ("test", w_te)):
        for k, v in _train.masked_metrics(pred, y, w).items():
            row[f"{split}_{k}"] = v
    n_in = len(DB_INPUTS[r.database])
    hidden = [int(v) for v in r.hidden.split("-")]
    row.update(best_step=best_step, steps=steps, wall_s=seconds, config_hash=chash, n_inputs=n_in,
               n_weights=n_weights(n_in, hidden) if r.family == "mlp" else hidden[0] * (n_in + 2) + 1,
               predictions=json.dumps(np.round(pred, 6).tolist()),
               conditions=json.dumps(dbs[r.database].condition.tolist()),
               split=json.dumps(np.where(w_te > 0, "test", np.where(w_va > 0, "val", "train")).tolist()))
    meta = dict(net_id=r.net_id, database=r.database, architecture=r.architecture, family=r.family,
                inputs=list(DB_INPUTS[r.database]), seed=int(r.seed), test_fold=int(r.test_fold))
    save_params(out / "params" / f"{r.net_id}.npz", jax.tree.map(np.asarray, p), meta)
    return row


def _run_rbf(group, data, dbs, cfg, out, chash, bar):
    for r in group.itertuples():
        x, y, in_mask, folds = data[r.database]
        w_tr, _, _ = _train.split_masks(folds, r.test_fold, cfg.sweep.folds)
        t0 = time.perf_counter()
        sel = w_tr > 0
        p = jax.tree.map(np.asarray, rbf_fit(jax.random.key(r.seed), x[sel], y[sel], int(r.hidden), in_mask=in_mask))
        pred = np.asarray(rbf_apply(p, x))
        row = _net_row(r, p, pred, time.perf_counter() - t0, 0, 0, data, dbs, cfg, out, chash)
        _atomic_parquet(pd.DataFrame([row]), out / "parts" / f"{r.net_id}-1.parquet")
        if bar is not None:
            bar.update(1)


def heldout_models(out: Path, database: str, conditions, architecture: str | None = None) -> dict:
    """For each condition, the nets of a sweep that held it out (its test fold), stacked
    over seeds: the models a replay of that condition's counters should use.

    Args:
        out: sweep folder (`run_sweep`).
        database: "db1", "db2" or "db3".
        conditions: (N,) condition of each counter to replay.
        architecture: e.g. "6-10-5-1" (needed only if the sweep trained several).

    Returns:
        dict(params=(N, seeds, ...) stacked parameters, idx=(N, inputs) input indices
        (`replay.input_index`)), a per-counter model batch for `calibration`.
    """
    from ..replay.quasistatic import input_index

    res = collect(out)
    if res.empty:
        raise FileNotFoundError(f"{out}: no finished nets (run the sweep first)")
    sel = res[res.database == database]
    if architecture is not None:
        sel = sel[sel.architecture == architecture]
    if sel.empty:
        raise ValueError(f"{out}: no nets for database {database!r}"
                         + (f" and architecture {architecture!r}" if architecture else ""))
    archs = sorted(set(sel.architecture))
    if len(archs) > 1:
        raise ValueError(f"{out}: {database} has several architectures {archs}; choose one")
    fold_of = {}
    for r in sel.itertuples():
        for c, s in zip(json.loads(r.conditions), json.loads(r.split)):
            if s == "test":
                fold_of[c] = int(r.test_fold)
    missing = sorted({c for c in conditions if c not in fold_of})
    if missing:
        raise ValueError(f"{out}: conditions {missing[:5]} are not held out by any {database} net of the sweep")
    by_fold = {}
    for fold, g in sel.sort_values("seed").groupby("test_fold"):
        by_fold[int(fold)] = stack_trees([load_params(Path(out) / "params" / f"{nid}.npz")[0] for nid in g.net_id])
    params = stack_trees([by_fold[fold_of[c]] for c in conditions])
    idx = np.broadcast_to(input_index(database, N_INPUTS), (len(conditions), N_INPUTS))
    return dict(params=jax.tree.map(jnp.asarray, params), idx=jnp.asarray(idx))
