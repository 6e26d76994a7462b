"""Sweep training and prediction speed: pvvjax vs scikit-learn, side by side.

384 nets = 3 databases x 16 architectures (n-W-5-1, W = 2, 4, ..., 32) x 8 seeds, trained
on fold 0 of a 5-fold split by condition of the embedded campaign. Both sides use the same
rows, the same input/output standardisation, full-batch Adam at the same learning rate
and the same early stopping (validation RMS every 50 steps, patience 10, at most 6000
steps), so both reach comparable validation RMS; the script prints both.

    pip install scikit-learn   # (make bench installs it)
    python benchmarks/bench_sweep.py [--sklearn-nets N]
"""

from __future__ import annotations

import os

# One XLA host device per core, so that the sweep's net axis is sharded over both cores
# (what `pvvjax sweep` does by default, `[sweep] cpu_devices`); set before JAX starts.
os.environ.setdefault("XLA_FLAGS", f"--xla_force_host_platform_device_count={os.cpu_count()}")

import argparse  # noqa: E402
import platform
import shutil
import tempfile
import time
import warnings
from pathlib import Path

import jax
import numpy as np

from pvvjax.analysis.databases import DB_INPUTS, build_databases
from pvvjax.config import ExperimentConfig, SweepConfig, TrainConfig
from pvvjax.data.campaign import load_campaign
from pvvjax.nets.networks import mlp_apply
from pvvjax.nets.sweep import load_params, run_sweep
from pvvjax.nets.train import condition_folds, split_masks
from pvvjax.realtime.npnet import NumpyNet
from pvvjax.synth import cached_campaign

TRAIN = TrainConfig(learning_rate=3e-3, max_steps=6000, eval_every=50, patience=10)
ARCHS = tuple((w, 5) for w in range(2, 34, 2))


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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sklearn-nets", type=int, default=384, help="train this many of the 384 with scikit-learn")
    args = ap.parse_args()
    import sklearn

    warnings.filterwarnings("ignore")
    dbs = build_databases(load_campaign(cached_campaign()))
    cfg = ExperimentConfig(sweep=SweepConfig(hidden=ARCHS, seeds=8, folds=5, test_folds=(0,)), train=TRAIN)
    print(f"JAX devices: {jax.device_count()} (XLA_FLAGS={os.environ.get('XLA_FLAGS', '')!r})")
    tmp = Path(tempfile.mkdtemp())
    try:
        jax.config.update("jax_compilation_cache_dir", str(tmp / "xla"))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
        times = []
        for run in ("cold", "warm"):  # warm: compiled programs come from the persistent cache
            t0 = time.perf_counter()
            res = run_sweep(cfg, dbs, tmp / run, log=lambda *a: None)
            times.append(time.perf_counter() - t0)
        n = len(res)
        order = res.sort_values(["database", "hidden", "seed"]).reset_index(drop=True)
        sk_val, sk_steps, t_sk = [], [], 0.0
        for r in order.head(args.sklearn_nets).itertuples():
            db = dbs[r.database]
            x = db[list(DB_INPUTS[r.database])].to_numpy(np.float64)
            y = db.peak_pvv_g.to_numpy(np.float64)
            tr, va, _ = (m > 0 for m in split_masks(condition_folds(db.condition, 5, 0), 0, 5))
            t0 = time.perf_counter()
            v, s = sklearn_net(x, y, tr, va, tuple(int(h) for h in r.hidden.split("-")), int(r.seed))
            t_sk += time.perf_counter() - t0
            sk_val.append(v)
            sk_steps.append(s)
        k = len(sk_val)
        t_sk_all = t_sk * n / k
        print(f"machine: {platform.machine()}, {jax.devices()[0].device_kind} x{jax.device_count()}, "
              f"jax {jax.__version__}, "
              f"scikit-learn {sklearn.__version__}")
        print(f"{n} nets; scikit-learn trained {k} of them one by one ({t_sk:.1f} s; x{n / k:.2f} for all)")
        print(f"{'':34s} {'time (s)':>9s} {'per net (ms)':>13s} {'steps/net':>10s} {'median val RMS (g)':>19s}")
        print(f"{'pvvjax sweep, cold (compiling)':34s} {times[0]:9.1f} {1e3 * times[0] / n:13.1f} "
              f"{res.steps.mean():10.0f} {res.val_rms_g.median():19.4f}")
        print(f"{'pvvjax sweep, warm (cached XLA)':34s} {times[1]:9.1f} {1e3 * times[1] / n:13.1f}")
        print(f"{'scikit-learn MLPRegressor':34s} {t_sk_all:9.1f} {1e3 * t_sk_all / n:13.1f} "
              f"{np.mean(sk_steps):10.0f} {np.median(sk_val):19.4f}")
        print(f"speed-up: {t_sk_all / times[0]:.1f}x cold, {t_sk_all / times[1]:.1f}x warm")

        # prediction latency and throughput, 6-10-5-1 on db1
        row = res[(res.database == "db1") & (res.hidden == "10-5")].iloc[0]
        params, meta = load_params(tmp / "warm" / "params" / f"{row.net_id}.npz")
        x1 = np.zeros(8, np.float32)
        x1[:6] = dbs["db1"][list(DB_INPUTS["db1"])].iloc[0].to_numpy(np.float32)
        f = jax.jit(mlp_apply)
        p_dev = jax.device_put(params)
        aot = f.lower(p_dev, x1).compile()  # ahead-of-time compiled: no tracing or cache lookup per call
        net = NumpyNet(params, meta)
        xn = x1[:6].astype(np.float64)
        reps = 20000

        def per_call(fn):
            fn()
            t0 = time.perf_counter()
            for _ in range(reps):
                fn()
            return (time.perf_counter() - t0) / reps

        t_jit = per_call(lambda: f(p_dev, x1).block_until_ready())
        t_aot = per_call(lambda: aot(p_dev, x1).block_until_ready())
        t_np = per_call(lambda: net.predict1(xn))
        t_np_call = per_call(lambda: net(xn))
        xb = np.tile(x1, (1_000_000, 1))
        xb_dev = jax.device_put(xb)
        f(p_dev, xb_dev).block_until_ready()
        t0 = time.perf_counter()
        for _ in range(5):
            f(p_dev, xb_dev).block_until_ready()
        per_s = 5 * len(xb) / (time.perf_counter() - t0)
        print(f"single prediction: jitted JAX {t_jit * 1e6:.1f} us, AOT-compiled JAX {t_aot * 1e6:.1f} us, "
              f"NumPy predict1 {t_np * 1e6:.1f} us, NumPy __call__ {t_np_call * 1e6:.1f} us; "
              f"batched (1e6 rows, jit): {per_s / 1e6:.1f} M predictions/s")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
