"""Sweep training speed: pvvjax beside the framework's own ceiling, PyTorch and scikit-learn.

N nets = 3 databases x 16 architectures (n-W-5-1, W = 2, 4, ..., 32) x N/48 seeds, trained on
fold 0 of a 5-fold split by condition of the embedded campaign, at each size of --sizes:

- pvvjax: `run_sweep` as `pvvjax sweep` runs it (full-batch Adam at 3e-3, validation RMS every
  50 steps, patience 10, at most 6000 steps; one XLA host device per core on CPU), cold and
  warm (compiled programs from the disk cache); counted by the steps the nets actually ran;
- the bare JAX loop, the framework's ceiling: the same padded 32-5 nets, masks and rows, one
  jitted `lax.scan` of --peer-steps optax Adam steps under `vmap`, no stopping, no files;
- a PyTorch ensemble (batched matmuls, `torch.optim.Adam`, eager; `pip install torch`), the
  same nets, rows and steps;
- scikit-learn's `MLPRegressor`, one net at a time with the same stopping rule (the first
  --sklearn-nets nets of the smallest size).

All report net-steps per second; the bare loop and PyTorch start from the same weights and
print their median final training loss, which must agree. Then single-prediction latency.

With --learning-rates K, the same number of nets is also trained as a sweep over K learning
rates (3e-3 times 3^i, as seeds / K seeds each) in one call, warm after a cold run, beside the
single-rate sweep: its net-steps per second, and how many trainer programs each compiled (the
rates are data, so the count must not grow with K).

    python benchmarks/bench_sweep.py [--sizes 384,3072] [--peer-steps 2000] [--sklearn-nets 48] [--learning-rates 4]

On a GPU (`pip install "jax[cuda13]" torch`), the issue's sizes and its five-fold sweep:

    python benchmarks/bench_sweep.py --sizes 384,3072,24576 --sklearn-nets 0
    python benchmarks/bench_sweep.py --sizes 3072 --all-folds --sklearn-nets 0   # 15 360 nets
"""

from __future__ import annotations

import os

# One XLA host device per core, so that the sweep's net axis is sharded over both cores
# (what `pvvjax sweep` does by default, `[sweep] cpu_devices`); set before JAX starts.
os.environ.setdefault("XLA_FLAGS", f"--xla_force_host_platform_device_count={os.cpu_count()}")

import argparse  # noqa: E402
import platform  # noqa: E402
import shutil  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import optax  # noqa: E402

from pvvjax.analysis import DATABASES, DB_INPUTS, build_databases  # noqa: E402
from pvvjax.config import ExperimentConfig, SweepConfig, TrainConfig  # noqa: E402
from pvvjax.data.campaign import load_campaign  # noqa: E402
from pvvjax.nets import N_INPUTS, load_nets, mlp_apply, run_sweep, stack_data  # noqa: E402
from pvvjax.nets.train import condition_folds, split_masks  # noqa: E402
from pvvjax.realtime.npnet import NumpyNet  # noqa: E402
from pvvjax.synth import cached_campaign  # noqa: E402

TRAIN = TrainConfig(learning_rate=3e-3, max_steps=6000, eval_every=50, patience=10)
WIDTHS = tuple(range(2, 34, 2))
ARCHS = tuple((w, 5) for w in WIDTHS)


# --------------------------------------------------------------------------- the peers' problem


def peer_problem(dbs, n_nets: int, seed: int = 0) -> dict:
    """The nets and rows of the peers, as NumPy: (G=3 databases, M nets each) padded to 32-5
    hidden units with masks, each database's fold-0 training rows standardised and padded."""
    data = stack_data(dbs, DATABASES, 5, 0)
    rows = [split_masks(f, 0, 5)[0] > 0 for _, _, _, f in data.values()]
    n = max(int(r.sum()) for r in rows)
    X, Y, W = np.zeros((3, n, N_INPUTS), np.float32), np.zeros((3, n), np.float32), np.zeros((3, n), np.float32)
    for g, ((x, y, mask, _), r) in enumerate(zip(data.values(), rows)):
        xs = x[r]
        X[g, : r.sum()] = (xs - xs.mean(0)) / np.where(xs.std(0) > 0, xs.std(0), 1.0) * mask
        Y[g, : r.sum()] = (y[r] - y[r].mean()) / y[r].std()
        W[g, : r.sum()] = 1.0
    m = n_nets // 3
    rng = np.random.default_rng(seed)
    glorot = lambda *s: (rng.uniform(-1, 1, (3, m) + s) * np.sqrt(6.0 / sum(s))).astype(np.float32)  # noqa: E731
    width = np.resize(np.array(WIDTHS), m)
    params = dict(w1=glorot(N_INPUTS, 32), b1=np.zeros((3, m, 32), np.float32), w2=glorot(32, 5),
                  b2=np.zeros((3, m, 5), np.float32), w3=glorot(5), b3=np.zeros((3, m), np.float32))
    mask1 = (np.arange(32) < width[:, None]).astype(np.float32)[None].repeat(3, 0)
    return dict(params=params, mask1=mask1, x=X, y=Y, w=W)


def _loss_one(p, mask1, x, y, w):
    h = jnp.tanh(x @ p["w1"] + p["b1"]) * mask1
    h = jnp.tanh(h @ p["w2"] + p["b2"])
    return jnp.sum(w * (h @ p["w3"] + p["b3"] - y) ** 2) / jnp.sum(w)


def bare_jax(prob: dict, steps: int) -> tuple[float, float]:
    """The framework's ceiling: (seconds warm, median final loss)."""
    opt = optax.adam(TRAIN.learning_rate)
    grads = jax.vmap(jax.vmap(jax.value_and_grad(_loss_one), (0, 0, None, None, None)))  # nets in a group, groups

    @jax.jit
    def train(p, mask1, x, y, w):
        def step(carry, _):
            p, s = carry
            loss, g = grads(p, mask1, x, y, w)
            u, s = opt.update(g, s, p)
            return (optax.apply_updates(p, u), s), loss

        (p, _), losses = jax.lax.scan(step, (p, opt.init(p)), None, length=steps)
        return losses[-1]

    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    mesh = Mesh(np.array(jax.devices()), ("nets",))
    nets, rep = NamedSharding(mesh, PartitionSpec(None, "nets")), NamedSharding(mesh, PartitionSpec())
    args = (jax.device_put(prob["params"], nets), jax.device_put(prob["mask1"], nets),
            *jax.device_put((prob["x"], prob["y"], prob["w"]), rep))
    train(*args).block_until_ready()  # compile
    t0 = time.perf_counter()
    loss = np.asarray(train(*args))
    return time.perf_counter() - t0, float(np.median(loss))


def torch_ensemble(prob: dict, steps: int) -> tuple[float, float] | None:
    """A PyTorch batched ensemble: (seconds, median final loss), or None without torch."""
    try:
        import torch
    except ImportError:
        return None
    dev = "cuda" if torch.cuda.is_available() else "cpu"
    g, m = prob["mask1"].shape[:2]
    flat = lambda a: torch.tensor(a.reshape((g * m,) + a.shape[2:]), device=dev)  # noqa: E731
    p = {k: flat(v).requires_grad_() for k, v in prob["params"].items()}
    mask1 = flat(prob["mask1"])[:, None]
    per_net = lambda a: torch.tensor(a, device=dev).repeat_interleave(m, 0)  # noqa: E731
    x, y, w = per_net(prob["x"]), per_net(prob["y"]), per_net(prob["w"])
    opt = torch.optim.Adam(p.values(), lr=TRAIN.learning_rate)

    def step():
        opt.zero_grad(set_to_none=True)
        h = torch.tanh(torch.baddbmm(p["b1"][:, None], x, p["w1"])) * mask1
        h = torch.tanh(torch.baddbmm(p["b2"][:, None], h, p["w2"]))
        pred = torch.bmm(h, p["w3"][:, :, None])[..., 0] + p["b3"][:, None]
        loss = (w * (pred - y) ** 2).sum(1) / w.sum(1)
        loss.sum().backward()
        opt.step()
        return loss

    step()  # warm-up (allocations), then from the start
    for k, v in prob["params"].items():
        p[k].data.copy_(flat(v))
    opt = torch.optim.Adam(p.values(), lr=TRAIN.learning_rate)
    if dev == "cuda":
        torch.cuda.synchronize()
    t0 = time.perf_counter()
    for _ in range(steps):
        loss = step()
    if dev == "cuda":
        torch.cuda.synchronize()
    return time.perf_counter() - t0, float(loss.detach().median())


# --------------------------------------------------------------------------- pvvjax and scikit-learn


def pvvjax_sweep(dbs, n_nets: int, folder: Path, all_folds: bool = False, rates: int = 0):
    """(seconds, results, trainer programs lowered) of `run_sweep` over n_nets nets of fold 0
    (x5: every fold) into `folder`; with `rates`, over that many learning rates."""
    lrs = tuple(TRAIN.learning_rate * 3.0**i for i in range(rates))
    cfg = ExperimentConfig(sweep=SweepConfig(hidden=ARCHS, seeds=n_nets // 48 // max(rates, 1), folds=5,
                                             learning_rates=lrs, test_folds=() if all_folds else (0,)), train=TRAIN)
    lowered = []

    def listener(event, duration, fun_name="", **kw):
        if event == "/jax/core/compile/jaxpr_to_mlir_module_duration" and "_segment" in fun_name:
            lowered.append(fun_name)

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        t0 = time.perf_counter()
        res = run_sweep(cfg, dbs, folder, log=lambda *a: None)
        return time.perf_counter() - t0, res, len(lowered)
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)


def sklearn_net(x, y, tr, va, hidden, seed):
    from sklearn.neural_network import MLPRegressor

    xs, xsd = x[tr].mean(0), x[tr].std(0) + 1e-12
    ym, ysd = y[tr].mean(), y[tr].std()
    m = MLPRegressor(hidden_layer_sizes=hidden, activation="tanh", solver="adam",
                     learning_rate_init=TRAIN.learning_rate,
                     batch_size=int(tr.sum()), max_iter=TRAIN.eval_every, warm_start=True, tol=0.0,
                     n_iter_no_change=10**9, alpha=0.0, random_state=seed)
    best, since, steps = np.inf, 0, 0
    while steps < TRAIN.max_steps and since < TRAIN.patience:
        m.fit((x[tr] - xs) / xsd, (y[tr] - ym) / ysd)
        steps += TRAIN.eval_every
        v = np.sqrt(np.mean((m.predict((x[va] - xs) / xsd) * ysd + ym - y[va]) ** 2))
        best, since = (v, 0) if v < best else (best, since + 1)
    return best, steps


def sklearn_nets(dbs, res, k: int):
    """(seconds, steps, median validation RMS) of the first k nets of `res`, one by one."""
    order = res.sort_values(["database", "hidden", "seed"]).reset_index(drop=True)
    vals, steps, t = [], [], 0.0
    for r in order.head(k).itertuples():
        db = dbs[r.database]
        x = db[list(DB_INPUTS[r.database])].to_numpy(np.float64)
        y = db.peak_pvv_g.to_numpy(np.float64)
        tr, va, _ = (m > 0 for m in split_masks(condition_folds(db.condition, 5, 0), 0, 5))
        t0 = time.perf_counter()
        v, s = sklearn_net(x, y, tr, va, tuple(int(h) for h in r.hidden.split("-")), int(r.seed))
        t += time.perf_counter() - t0
        vals.append(v)
        steps.append(s)
    return t, int(np.sum(steps)), float(np.median(vals))


def prediction_latency(dbs, res, folder: Path):
    """Single-prediction latency of a 6-10-5-1 db1 net: jitted, AOT-compiled JAX and NumPy."""
    row = res[(res.database == "db1") & (res.hidden == "10-5")].iloc[0]
    [(params, meta)] = load_nets(folder, [row.net_id], res)
    x1 = np.zeros(8, np.float32)
    x1[:6] = dbs["db1"][list(DB_INPUTS["db1"])].iloc[0].to_numpy(np.float32)
    f = jax.jit(mlp_apply)
    p_dev = jax.device_put(params)
    aot = f.lower(p_dev, x1).compile()  # ahead-of-time compiled: no tracing or cache lookup per call
    net = NumpyNet(params, meta)
    xn = x1[:6].astype(np.float64)

    def per_call(fn, reps=20000):
        fn()
        t0 = time.perf_counter()
        for _ in range(reps):
            fn()
        return (time.perf_counter() - t0) / reps

    t_jit = per_call(lambda: f(p_dev, x1).block_until_ready())
    t_aot = per_call(lambda: aot(p_dev, x1).block_until_ready())
    t_np = per_call(lambda: net.predict1(xn))
    print(f"single prediction: jitted JAX {t_jit * 1e6:.1f} us, AOT-compiled JAX {t_aot * 1e6:.1f} us, "
          f"NumPy predict1 {t_np * 1e6:.1f} us")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="384", help="net counts, multiples of 96 (default: 384)")
    ap.add_argument("--peer-steps", type=int, default=2000, help="Adam steps of the bare loop and PyTorch")
    ap.add_argument("--sklearn-nets", type=int, default=48, help="nets scikit-learn trains (0: none)")
    ap.add_argument("--all-folds", action="store_true", help="pvvjax trains every fold of each size (x5 nets, "
                                                             "in one call): 3072 gives the issue's 15 360")
    ap.add_argument("--learning-rates", type=int, default=0, help="also a sweep of each size over this many "
                                                                  "learning rates (0: none)")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    if any(n % 96 for n in sizes):
        raise SystemExit("--sizes: multiples of 96 (3 databases x 16 widths x seeds, sharded over 2 devices)")
    warnings.filterwarnings("ignore")
    dbs = build_databases(load_campaign(cached_campaign()))
    try:
        import torch

        peers = f"torch {torch.__version__} ({torch.get_num_threads()} threads)"
    except ImportError:
        peers = "no torch"
    print(f"machine: {platform.machine()}, {jax.devices()[0].device_kind} x{jax.device_count()}, jax {jax.__version__}"
          f", {peers}; peers run {args.peer_steps} steps")
    print(f"{'nets':>6s} {'who':28s} {'seconds':>8s} {'net-steps':>10s} {'net-steps/s':>12s}  note")
    line = lambda n, who, t, ns, note="": print(f"{n:6d} {who:28s} {t:8.2f} {ns:10d} {ns / t:12.0f}  {note}")  # noqa
    tmp = Path(tempfile.mkdtemp())
    try:
        jax.config.update("jax_compilation_cache_dir", str(tmp / "xla"))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
        for i, n in enumerate(sizes):
            cold, res, progs = pvvjax_sweep(dbs, n, tmp / f"cold-{n}", args.all_folds)
            warm, res, _ = pvvjax_sweep(dbs, n, tmp / f"warm-{n}", args.all_folds)
            ns = int(res.steps.sum())
            n = len(res)
            line(n, "pvvjax sweep, cold", cold, ns, f"compiling ({progs} trainer programs)")
            line(n, "pvvjax sweep, warm", warm, ns, f"{ns / n:.0f} steps per net, median val RMS "
                                                    f"{res.val_rms_g.median():.4f} g")
            if args.learning_rates:
                k = args.learning_rates
                cold_k, _, progs_k = pvvjax_sweep(dbs, n, tmp / f"cold-{n}-lr", args.all_folds, rates=k)
                warm_k, res_k, _ = pvvjax_sweep(dbs, n, tmp / f"warm-{n}-lr", args.all_folds, rates=k)
                ns_k = int(res_k.steps.sum())
                line(len(res_k), f"pvvjax sweep, {k} rates, cold", cold_k, ns_k,
                     f"compiling ({progs_k} trainer programs)")
                best = res_k.groupby("learning_rate").val_rms_g.median()
                line(len(res_k), f"pvvjax sweep, {k} rates, warm", warm_k, ns_k,
                     f"{(ns_k / warm_k) / (ns / warm):.2f}x the single rate's net-steps/s; median val RMS by "
                     "rate " + ", ".join(f"{lr:g}: {v:.4f}" for lr, v in best.items()))
            prob = peer_problem(dbs, n)
            t, loss = bare_jax(prob, args.peer_steps)
            line(n, "bare JAX vmap + scan", t, n * args.peer_steps, f"median final loss {loss:.4f}")
            bare_rate = n * args.peer_steps / t
            got = torch_ensemble(prob, args.peer_steps)
            if got is not None:
                line(n, "PyTorch batched ensemble", got[0], n * args.peer_steps, f"median final loss {got[1]:.4f}")
            if i == 0 and args.sklearn_nets:
                t, steps, val = sklearn_nets(dbs, res, args.sklearn_nets)
                line(args.sklearn_nets, "scikit-learn, one by one", t, steps, f"median val RMS {val:.4f} g")
            print(f"{'':6s} where pvvjax's warm time goes: {ns / bare_rate:.2f} s of it is the nets' steps at the "
                  f"bare loop's rate; {warm - ns / bare_rate:.2f} s the rest (validation, stopped nets computed "
                  f"until the batch can halve, results and files)")
        prediction_latency(dbs, res, tmp / f"warm-{sizes[-1]}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
