"""Exploratory: a lag learned inside one training, in place of the lag test's choice between
trainings (docs/discovery.md, "The lag test does not generalize").

Window nets (db inputs, every `--stride`-th replay window at a fixed input offset) are trained
with a first-order lag of learnable time constant τ between their output and the measured
PVV (zero-order hold between windows, by gradient through `jax.lax.scan`), beside the same
nets (same initialization) without the lag; k-fold by condition as discovery's. Prints the
learned τ (median and range over folds × seeds) and the held-out RMS of both ensembles.
A prototype for the next step of the lag test (its own small MLP and Adam loop, not
`train.fit_ensemble`), not part of the discovery workflow.

    python experiments/learned_lag_probe.py long-lag --seed-offset 5 --offsets 0,1
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import optax

sys.path.insert(0, str(Path(__file__).parent))
from discovery_benchmark import _campaign, scenario_configs  # noqa: E402

from pvvjax._strict import from_dict  # noqa: E402
from pvvjax.config import DiscoveryConfig, ExperimentConfig  # noqa: E402
from pvvjax.databases import DB_INPUTS  # noqa: E402
from pvvjax.discovery import Model  # noqa: E402
from pvvjax.discovery._confirm import _train_model  # noqa: E402
from pvvjax.discovery._model import _inputs, _replay  # noqa: E402
from pvvjax.discovery._workflow import _context  # noqa: E402

CONFIG = Path(__file__).parent / "configs" / "discovery" / "benchmark.toml"


def mlp_init(key, sizes):
    ps = []
    for a, b in zip(sizes[:-1], sizes[1:]):
        key, k = jax.random.split(key)
        ps.append((jax.random.normal(k, (a, b)) * np.sqrt(1.0 / a), jnp.zeros(b)))
    return ps


def mlp(ps, x):
    for w, b in ps[:-1]:
        x = jnp.tanh(x @ w + b)
    w, b = ps[-1]
    return (x @ w + b)[..., 0]


def lagged(u, dt, tau):
    """u (C, L) lagged along each row by a first-order lag τ (zero-order hold over dt)."""
    a = jnp.exp(-dt / tau)

    def step(prev, inp):
        nxt = inp[1] * prev + (1 - inp[1]) * inp[0]
        return nxt, nxt

    return jax.lax.scan(step, u[:, 0], (u.T, a.T))[1].T


def sequences(win, inputs, stride):
    """The full windows of each counter, every `stride`-th, in time order, padded: x (C, L, n)
    standardized, y (C, L), mask, dt (time step to the previous window), counter index."""
    t = win.table
    sel = (t.weight.to_numpy() >= 0.999) & (t.k.to_numpy() % stride == 0)
    x = _inputs(Model({}, inputs), win)[sel]
    x = (x - x.mean(0)) / (x.std(0) + 1e-9)
    y, ci, ts = t.measured_g.to_numpy()[sel], t.i.to_numpy()[sel], t.time_s.to_numpy()[sel]
    counters = np.unique(ci)
    n = max((ci == c).sum() for c in counters)
    X, Y, M, DT = (np.zeros((len(counters), n, x.shape[1])), np.zeros((len(counters), n)),
                   np.zeros((len(counters), n)), np.zeros((len(counters), n)))
    for r, c in enumerate(counters):
        rows = np.where(ci == c)[0]
        rows = rows[np.argsort(ts[rows])]
        X[r, :len(rows)], Y[r, :len(rows)], M[r, :len(rows)] = x[rows], y[rows], 1.0
        DT[r, 1:len(rows)] = np.diff(ts[rows])
    return X, Y, M, DT, counters


def probe(ctx, inputs, offset, stride, steps, seeds, folds):
    X, Y, M, DT, counters = sequences(_replay(ctx, offset), inputs, stride)
    fold = ctx.counter_fold[counters]
    mu, sd = Y[M > 0].mean(), Y[M > 0].std()
    X, Yn, Mj, DT = jnp.asarray(X), jnp.asarray((Y - mu) / sd), jnp.asarray(M), jnp.asarray(DT)
    opt = optax.adam(0.01)

    def predict(p):
        u = mlp(p["net"], X)
        return u if p["log_tau"] is None else lagged(u, DT, jnp.exp(p["log_tau"]))

    def loss(p, w):
        return jnp.sum((predict(p) - Yn) ** 2 * w) / jnp.sum(w)

    def fit(key, w, with_lag):  # the same initial nets with and without the lag (τ starts at 1 s)
        p = {"net": mlp_init(key, (X.shape[-1], 10, 5, 1)), "log_tau": jnp.log(1.0) if with_lag else None}
        st = opt.init(p)

        def body(c, _):
            p, st = c
            up, st = opt.update(jax.grad(loss)(p, w), st, p)
            return (optax.apply_updates(p, up), st), None

        return jax.lax.scan(body, (p, st), None, length=steps)[0][0]

    train = jax.jit(fit, static_argnums=2)
    taus, with_lag, without = [], np.zeros((seeds,) + Y.shape), np.zeros((seeds,) + Y.shape)
    for f in range(folds):
        w, held = Mj * jnp.asarray((fold != f)[:, None], jnp.float32), fold == f
        for s in range(seeds):
            key = jax.random.PRNGKey(100 * s + f)
            p, q = train(key, w, True), train(key, w, False)
            taus.append(float(jnp.exp(p["log_tau"])))
            with_lag[s, held], without[s, held] = np.asarray(predict(p))[held], np.asarray(predict(q))[held]
    m = M > 0
    rms = lambda P: float(np.sqrt(np.mean(((np.median(P, 0) * sd + mu) - Y)[m] ** 2)))  # noqa: E731
    return np.array(taus), rms(without), rms(with_lag)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenario", help="a scenario of the benchmark config")
    ap.add_argument("--seed-offset", type=int, default=0)
    ap.add_argument("--offsets", default="0", help="comma-separated input offsets, s")
    ap.add_argument("--stride", type=int, default=2)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--seeds", type=int, default=2)
    args = ap.parse_args()
    scs, overrides = scenario_configs(CONFIG, args.seed_offset)
    sc = next((s for s in scs if s["name"] == args.scenario), None)
    if sc is None:
        raise SystemExit(f"unknown scenario {args.scenario!r}; one of {', '.join(s['name'] for s in scs)}")
    cfg = ExperimentConfig(discovery=from_dict(DiscoveryConfig, {**overrides, "database": sc["database"]}))
    ctx = _context(_campaign(sc["synth"]), cfg, lambda m: None)
    inputs = tuple(DB_INPUTS[cfg.discovery.database])
    ctx.replay_params = _train_model(ctx, Model({}, inputs), rows="peaks")  # the replay's own nets
    for offset in (float(v) for v in args.offsets.split(",")):
        t0 = time.perf_counter()
        taus, r0, r1 = probe(ctx, inputs, offset, args.stride, args.steps, args.seeds, cfg.discovery.folds)
        print(f"{args.scenario} (seed {sc['seed']}) offset {offset:g} s: learned tau {np.median(taus):.2f} s "
              f"({taus.min():.2f}-{taus.max():.2f}); held-out ensemble RMS {r0:.4f} g without the lag, "
              f"{r1:.4f} g with it ({1 - r1 / r0:+.1%}); {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
