"""Sweeps: many nets (databases × architectures × learning rates × weight decays × seeds ×
folds) trained in one program.

Nets of one depth share a compiled program: hidden layers are allocated at the widest
architecture of the sweep and masked (`networks`), and the inputs of db1-db3 (6, 8 and 7)
are padded to 8 with an input mask. Learning rates and weight decays are data (`train.Hyper`),
so nets of every rate share the batch too. They train together in one on-device loop
(`batched.train_nets`).

The shell around it (`run_sweep`) is resumable. At every checkpoint (`sweep.checkpoint_s`)
and at the end, the nets that finished since the last one are written together: their
parameters stacked in one `params/<first net id>-<count>.npz`, then their result rows to
the part of the same name in `parts/`, each under a temporary name and renamed (a net counts
as done once its row is in a part). A sweep killed at any point and run again with the same
config trains only the missing nets to the same bits, keeps every finished one, and leaves
no duplicate row and no half-written file. `results.parquet` gathers the parts at the end.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import time
from pathlib import Path

import jax
import numpy as np
import pandas as pd

from .._strict import to_dict
from ..analysis.databases import DB_INPUTS, OUTPUT
from ..config import ExperimentConfig, config_hash
from ..data.fingerprint import tables_fingerprint
from ..interrupts import check_interrupt
from ..io import claim_folder, folder_kind, write_config
from ..realtime.npnet import read_npz, write_npz
from . import train as _train
from .batched import predict_many, stack_trees, train_nets
from .networks import architecture_name, mlp_apply, mlp_init, n_weights, rbf_apply, rbf_fit, scaling

__all__ = [
    "N_INPUTS",
    "SWEEP_AXES",
    "collect",
    "databases_fingerprint",
    "heldout_models",
    "load_nets",
    "load_params",
    "net_table",
    "run_sweep",
    "save_params",
    "stack_data",
    "sweep_settings",
]

N_INPUTS = max(len(v) for v in DB_INPUTS.values())  # every database padded to this many inputs


# --------------------------------------------------------------------------- planning


def databases_fingerprint(dbs: dict, databases) -> str:
    """Content hash (16 hex digits) of the named database tables: the data a sweep's nets
    are trained on, which changes whenever the campaign's content changes what they hold."""
    return tables_fingerprint({db: dbs[db] for db in databases})


# The sweep's axes: they decide which nets exist, not how each is trained, so a sweep grows
# (or narrows) in its folder; every other setting is the folder's own.
SWEEP_AXES = ("databases", "hidden", "centers", "seeds", "learning_rates", "weight_decays", "test_folds")
_NOT_RESULTS = ("checkpoint_s",)  # how often results are written, not what they are


# How a sweep folder is laid out and its nets computed: 2 = a parameter file per checkpoint,
# and a net's arithmetic independent of its batch (a folder of format 1 holds other bits);
# 3 = predictions, conditions and split as list columns at full precision, learning rate
# and weight decay per net (format 2 held them as JSON strings).
FOLDER_FORMAT = 3


def sweep_settings(cfg: ExperimentConfig) -> dict:
    """The settings that decide how each net of a sweep is trained: what its folder is
    claimed for (`io.claim_folder`), with the folder's `FOLDER_FORMAT`. The axes
    (`SWEEP_AXES`) are not among them."""
    campaign = {k: v for k, v in to_dict(cfg.campaign).items() if k != "path"}  # the content counts, not where
    sweep = {k: v for k, v in to_dict(cfg.sweep).items() if k not in SWEEP_AXES + _NOT_RESULTS}
    train = to_dict(cfg.train)
    for axis, name in (("learning_rates", "learning_rate"), ("weight_decays", "weight_decay")):
        if getattr(cfg.sweep, axis):  # an axis of the sweep, not a setting of its folder
            train.pop(name)
    return dict(sweep=sweep, train=train, analysis=to_dict(cfg.analysis), campaign=campaign,
                seed=cfg.seed, format=FOLDER_FORMAT)


def _train_axes(cfg: ExperimentConfig) -> list[tuple[float, float]]:
    """(learning rate, weight decay) of each point of the sweep's training axes."""
    lrs = cfg.sweep.learning_rates or (cfg.train.learning_rate,)
    wds = cfg.sweep.weight_decays or (cfg.train.weight_decay,)
    return [(float(lr), float(wd)) for lr in lrs for wd in wds]


def net_table(cfg: ExperimentConfig, data: str = "") -> pd.DataFrame:
    """One row per net of the sweep, with a stable id: the same config and data (the
    `databases_fingerprint`) give the same ids, and nothing else does."""
    sw = cfg.sweep
    archs = sw.hidden if sw.family == "mlp" else tuple((c,) for c in sw.centers)
    rates = _train_axes(cfg) if sw.family == "mlp" else [(np.nan, np.nan)]  # RBF nets are fitted, not trained
    campaign = sweep_settings(cfg)["campaign"]
    rows = []
    for db, hidden, (lr, wd), seed, fold in itertools.product(sw.databases, archs, rates, range(sw.seeds),
                                                              sw.fold_list):
        train = to_dict(cfg.train)
        if sw.family == "mlp":
            train.update(learning_rate=lr, weight_decay=wd)
        key = dict(db=db, family=sw.family, hidden=list(hidden), seed=seed, fold=fold, k=sw.folds,
                   split_seed=sw.split_seed, train=train, analysis=to_dict(cfg.analysis), campaign=campaign,
                   exp_seed=cfg.seed, data=data)
        rows.append(dict(net_id=hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16],
                         database=db, family=sw.family, hidden="-".join(map(str, hidden)),
                         architecture=architecture_name(len(DB_INPUTS[db]), hidden) if sw.family == "mlp"
                         else f"rbf-{hidden[0]}", depth=len(hidden), learning_rate=lr, weight_decay=wd, seed=seed,
                         test_fold=fold, optimizer="adam" if sw.family == "mlp" else "kmeans+lstsq"))
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


def _barrier(name: str):
    """Wait for every process of a multi-process run (nothing to wait for in one process)."""
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        multihost_utils.sync_global_devices(name)


# --------------------------------------------------------------------------- files


def save_params(path, params: dict, meta: dict) -> Path:
    """Save parameters (one net's, or nets stacked on a leading axis) as `.npz` (no
    pickle), written atomically; `meta` is stored as JSON."""
    write_npz(path, params, meta)
    return Path(path)


def load_params(path) -> tuple[dict, dict]:
    """Load parameters saved by `save_params` (with `allow_pickle=False`)."""
    return read_npz(path)


def load_nets(out, net_ids, results: pd.DataFrame | None = None) -> list[tuple[dict, dict]]:
    """One net's (parameters, metadata) for each net id of a sweep folder, read from the
    parameter files that hold them (each file once; `params_file` and `params_index` of
    the results table say where a net is). `results`: the folder's rows, if already read."""
    res = collect(out) if results is None else results
    where = res.set_index("net_id") if len(res) else None
    if where is not None and "params_file" not in where.columns:
        raise ValueError(f"{out}: written by an earlier pvvjax (a parameter file per net), which this one cannot "
                         "read; run the sweep again into a new folder (this one is left as it is)")
    missing = [i for i in net_ids if where is None or i not in where.index]
    if missing:
        raise KeyError(f"{out}: no finished net {missing[0]!r}")
    files = {}
    out_list = []
    for i in net_ids:
        name, j = where.at[i, "params_file"], int(where.at[i, "params_index"])
        if name not in files:
            files[name] = load_params(Path(out) / "params" / name)
        params, meta = files[name]
        out_list.append((jax.tree.map(lambda a: a[j], params), meta["nets"][j]))
    return out_list


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
        out = claim_folder(out, sweep_settings(cfg), data_key, kind="sweep")
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
            check_interrupt()  # before a checkpoint: an interrupted sweep writes nothing more
            if writer:
                _finish(group.iloc[idx], fits, seconds, data, dbs, cfg, out, chash)
            if bar is not None:
                bar.update(len(idx))

        hp = _train.hyper(cfg.train, group.learning_rate.to_numpy(np.float32),
                          group.weight_decay.to_numpy(np.float32))
        hp = jax.tree.map(lambda a: np.broadcast_to(a, len(group)), hp)
        train_nets(stack_trees(params), stack_trees(gdata), gid, cfg.train, hyper=hp, chunk_evals=sw.chunk_evals,
                   checkpoint_s=sw.checkpoint_s, on_done=on_done)
    if bar is not None:
        bar.close()
    _barrier("pvvjax sweep trained")  # process 0 has written every part file
    check_interrupt()
    results = collect(out)
    if writer:
        _atomic_parquet(results, out / "results.parquet")
    return results[results.net_id.isin(nets.net_id)].reset_index(drop=True) if len(results) else results


def finished_sweep(folder: str | Path) -> pd.DataFrame:
    """The results table of a finished sweep folder; otherwise an error that says what the
    folder is: missing, not a sweep's, or a sweep interrupted before it gathered its results
    (with the command that finishes it).

    Raises:
        FileNotFoundError: as above, naming the folder.
    """
    folder = Path(folder)
    if (folder / "results.parquet").is_file():
        return pd.read_parquet(folder / "results.parquet")
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such folder; give a sweep folder (`pvvjax sweep` and the main job "
                                "write OUT_DIR/NAME/sweep)")
    kind = folder_kind(folder)
    if kind not in (None, "", "sweep"):
        raise FileNotFoundError(f"{folder}: holds the results of `pvvjax {kind}`, not a sweep; give the folder "
                                "`pvvjax sweep` or the main job wrote (OUT_DIR/NAME/sweep)")
    if (folder / "config.toml").is_file() and (folder / "parts").is_dir():
        n = len(collect(folder))
        raise FileNotFoundError(f"{folder}: an unfinished sweep ({n} nets finished, its results not yet gathered): it "
                                f"was interrupted; run `pvvjax sweep {folder / 'config.toml'} --out {folder}` to "
                                "finish it")
    raise FileNotFoundError(f"{folder}: not a sweep folder (no results.parquet); give the folder `pvvjax sweep` or "
                            "the main job wrote (OUT_DIR/NAME/sweep)")


def collect(out: Path) -> pd.DataFrame:
    """All finished result rows of a sweep folder."""
    parts = sorted((Path(out) / "parts").glob("*.parquet"))
    if not parts:
        return pd.DataFrame()
    return pd.concat([pd.read_parquet(p, columns=None) for p in parts], ignore_index=True)


def _finish(rows: pd.DataFrame, fits, seconds, data, dbs, cfg, out: Path, chash: str, apply=mlp_apply):
    """Write the parameters (one file) and result rows (one part) of nets that finished
    together; the part last, since a net counts as done once its row is in a part."""
    failed = np.asarray(fits.failed_step)
    for j, r in enumerate(rows.itertuples()):
        if failed[j] >= 0:
            raise _train.TrainingError(
                f"net {r.database} {r.architecture} seed {r.seed} fold {r.test_fold} ({r.net_id}): training loss "
                f"not finite or diverging at step {int(failed[j])}; lower train.learning_rate or check the data")
    x = np.stack([data[db][0] for db in rows.database])
    preds = np.asarray(predict_many(fits.params, x, apply))
    _write_nets(rows, fits.params, preds, seconds, fits.best_step, fits.steps, data, dbs, cfg, out, chash)


def _write_nets(rows, params, preds, seconds, best_step, steps, data, dbs, cfg, out, chash):
    """Save stacked parameters of `rows`' nets as one file, then their rows as one part."""
    stem = f"{rows.net_id.iloc[0]}-{len(rows)}"
    out_rows, metas = [], []
    for j, r in enumerate(rows.itertuples()):
        row, meta = _net_row(r, preds[j], float(seconds[j]), int(best_step[j]), int(steps[j]), data, dbs, cfg,
                             chash)
        out_rows.append({**row, "params_file": f"{stem}.npz", "params_index": j})
        metas.append(meta)
    save_params(out / "params" / f"{stem}.npz", params, dict(nets=metas))
    _atomic_parquet(pd.DataFrame(out_rows), out / "parts" / f"{stem}.parquet")


def _net_row(r, pred, seconds, best_step, steps, data, dbs, cfg, chash) -> tuple[dict, dict]:
    """One net's result row and the metadata stored with its parameters."""
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
               predictions=np.asarray(pred, np.float64), conditions=dbs[r.database].condition.astype(str).tolist(),
               split=np.where(w_te > 0, "test", np.where(w_va > 0, "val", "train")).tolist())
    meta = dict(net_id=r.net_id, database=r.database, architecture=r.architecture, family=r.family,
                inputs=list(DB_INPUTS[r.database]), seed=int(r.seed), test_fold=int(r.test_fold))
    return row, meta


def _run_rbf(group, data, dbs, cfg, out, chash, bar):
    """RBF nets, fitted on the host one at a time; each architecture's written as one file."""
    for _, rows in group.groupby("hidden", sort=False):
        rows = rows.reset_index(drop=True)
        params, preds, seconds = [], [], []
        for r in rows.itertuples():
            x, y, in_mask, folds = data[r.database]
            w_tr, _, _ = _train.split_masks(folds, r.test_fold, cfg.sweep.folds)
            t0 = time.perf_counter()
            sel = w_tr > 0
            if int(r.hidden) > int(sel.sum()):
                raise ValueError(f"sweep.centers {int(r.hidden)}: more RBF centres than the {int(sel.sum())} training "
                                 f"rows of {r.database} fold {r.test_fold}; give at most {int(sel.sum())}")
            p = jax.tree.map(np.asarray, rbf_fit(jax.random.key(r.seed), x[sel], y[sel], int(r.hidden),
                                                 in_mask=in_mask))
            preds.append(np.asarray(rbf_apply(p, x)))
            params.append(p)
            seconds.append(time.perf_counter() - t0)
        zero = np.zeros(len(rows), int)
        _write_nets(rows, stack_trees(params), preds, seconds, zero, zero, data, dbs, cfg, out, chash)
        if bar is not None:
            bar.update(len(rows))


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
        for c, s in zip(r.conditions, r.split):
            if s == "test":
                fold_of[c] = int(r.test_fold)
    missing = sorted({c for c in conditions if c not in fold_of})
    if missing:
        raise ValueError(f"{out}: conditions {missing[:5]} are not held out by any {database} net of the sweep")
    by_fold = {}
    for fold, g in sel.sort_values("seed").groupby("test_fold"):
        by_fold[int(fold)] = stack_trees([p for p, _ in load_nets(out, list(g.net_id), res)])
    params = stack_trees([by_fold[fold_of[c]] for c in conditions])
    idx = np.broadcast_to(input_index(database, N_INPUTS), (len(conditions), N_INPUTS))
    return dict(params=jax.device_put(params), idx=jax.device_put(np.asarray(idx)))  # no copy program per shape
