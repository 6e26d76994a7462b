"""Replay and calibration speed: pvvjax vs the NumPy replay a user would otherwise write.

- One replay of the 37 s pull-up 11022 (11 840 samples, consecutive 8-rev windows, db1
  nets, median of 4 seeds): the jitted pvvjax replay against a NumPy loop over windows
  (np.searchsorted windows, mean removal, the 4/rev DFT coefficient, window means and the
  NumPy network evaluator). Both give the same PVV to ~1e-3 g (the NumPy windows are whole
  samples, pvvjax integrates the interpolant).
- Batched replays: every maneuver counter of the campaign at 16 offsets (vmapped).
- One calibration of offset and window length over all maneuvers (51 counters, db1, hop
  1 rev, Levenberg-Marquardt from a coarse grid), warm and cold, against the brute-force
  grid (0.1 s x 0.5 rev) that would otherwise locate the optimum.

    python benchmarks/bench_replay.py [--pinned]

`--pinned` first pins the process to one core (what a real-time host does): XLA then runs
small programs without handing work to a second thread, which costs tens of µs on CPU.
Needs the paper networks (experiments/paper_networks.py); falls back to RBF nets.
"""

from __future__ import annotations

import os
import sys

if "--pinned" in sys.argv:  # before JAX starts its thread pool
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from pvvjax.analysis.databases import DB_INPUTS, build_databases  # noqa: E402
from pvvjax.config import TRANSIENT_MANEUVERS  # noqa: E402
from pvvjax.data.campaign import load_campaign  # noqa: E402
from pvvjax.data.constants import KT_TO_FT_S, RPM_TO_RAD_S, UH60A  # noqa: E402
from pvvjax.nets import load_nets  # noqa: E402
from pvvjax.realtime.npnet import NumpyNet  # noqa: E402
from pvvjax.replay.calibration import Bounds, calibrate, cost_grid, group_members  # noqa: E402
from pvvjax.replay.quasistatic import make_settings, replay  # noqa: E402
from pvvjax.replay.tables import load_replay_set  # noqa: E402
from pvvjax.synth import cached_campaign  # noqa: E402

SWEEP = Path("runs/paper-networks/sweep")


def best(f, n, rep=7):
    f()
    times = []
    for _ in range(rep):
        t0 = time.perf_counter()
        for _ in range(n):
            f()
        times.append((time.perf_counter() - t0) / n)
    return min(times)


def numpy_replay(rec, nets, gw, sigma, tau, L):
    """The paper's replay in NumPy: consecutive L-rev windows of whole samples; inputs
    averaged over the window shifted τ seconds earlier; median of the nets."""
    t = rec["time_s"]
    rev = np.unwrap(np.deg2rad(rec["azimuth_deg"])) / (2 * np.pi)
    rev -= rev[0]
    n_win = int(rev[-1] // L)
    edges = np.searchsorted(rev, np.arange(n_win + 1) * L)
    meas = np.empty(n_win)
    x = np.empty((n_win, 6))
    for j in range(n_win):
        i0, i1 = edges[j], edges[j + 1]
        seg = rec["az_g"][i0:i1]
        psi = 2 * np.pi * rev[i0:i1]
        meas[j] = 2 * abs(np.mean((seg - seg.mean()) * np.exp(-4j * psi)))
        k0, k1 = np.searchsorted(t, [t[i0] - tau, t[i1 - 1] - tau])
        m = {c: rec[c][k0:k1 + 1].mean() for c in ("airspeed_kt", "rotor_rpm", "pitch_rate_dps", "roll_angle_deg",
                                                     "climb_rate_fpm")}
        v = m["airspeed_kt"] * KT_TO_FT_S
        mu = v / (m["rotor_rpm"] * RPM_TO_RAD_S * UH60A.rotor_radius_ft)
        mlf = (1 + np.deg2rad(m["pitch_rate_dps"]) * v / UH60A.g_ft_s2) / np.cos(np.deg2rad(m["roll_angle_deg"]))
        x[j] = (mu, gw, m["rotor_rpm"], sigma, mlf, m["climb_rate_fpm"])
    return meas, np.median(np.stack([net(x) for net in nets]), axis=0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--pinned", action="store_true", help="pin the process to one core first")
    args = ap.parse_args()
    camp = load_campaign(cached_campaign())
    ctr = camp.counters[camp.counters.maneuver.isin(TRANSIENT_MANEUVERS)]
    counters = list(ctr.index)
    if (SWEEP / "parts").is_dir():
        info, batch, recs, models = load_replay_set(camp, counters, SWEEP, ["db1"])
        source = "paper networks (held out, 4 seeds)"
    else:  # a stand-in with the same interface: RBF nets fitted to db1
        from pvvjax.analysis.databases import STATE_CHANNELS
        from pvvjax.data.batch import to_batch
        from pvvjax.nets.networks import rbf_fit
        from pvvjax.nets.sweep import stack_data
        from pvvjax.replay.quasistatic import input_index, prepare

        x, y, m, _ = stack_data(build_databases(camp), ["db1"], 5, 0)["db1"]
        p = jax.tree.map(lambda *a: jnp.stack(a), *[rbf_fit(jax.random.key(s), x, y, 20, in_mask=m) for s in range(4)])
        batch = to_batch(camp, STATE_CHANNELS, counters)
        recs = prepare(batch)
        models = {"db1": jax.tree.map(lambda a: jnp.broadcast_to(a, (len(counters), *a.shape)),
                                      dict(params=p, idx=jnp.asarray(input_index("db1"))))}
        source = "RBF stand-ins (no paper-networks sweep found)"
    model = models["db1"]
    i = counters.index("11022")
    m1, r1 = jax.tree.map(lambda a: a[i], (model, recs))
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores{' (pinned to one)' if args.pinned else ''}, "
          f"jax {jax.__version__}, numpy {np.__version__}; models: {source}")

    # ---- one replay
    s8 = make_settings(batch, max_window_revs=8.0, min_window_revs=8.0, offset_bounds=(0.0, 1.0))
    f = jax.jit(lambda m, r, tau, L: replay(m, r, tau, L, settings=s8).predicted)
    t_jax = best(lambda: f(m1, r1, 0.5, 8.0).block_until_ready(), 300)
    rec = {c: camp.records["11022"][c].to_numpy() for c in camp.records["11022"].columns}
    gw, sigma = float(camp.counters.loc["11022", "gross_weight_lb"]), float(camp.counters.loc["11022", "density_ratio"])
    nets = []
    if (SWEEP / "parts").is_dir():
        import pandas as pd

        res = pd.read_parquet(SWEEP / "results.parquet")
        cond = camp.counters.loc["11022", "condition"]
        held = [r.net_id for r in res[res.database == "db1"].itertuples()
                if dict(zip(r.conditions, r.split)).get(cond) == "test"]
        nets = [NumpyNet(p, m) for p, m in load_nets(SWEEP, held, res)]
        t_np = best(lambda: numpy_replay(rec, nets, gw, sigma, 0.5, 8.0), 20)
        meas_np, pred_np = numpy_replay(rec, nets, gw, sigma, 0.5, 8.0)
        rep = replay(m1, r1, 0.5, 8.0, settings=s8)
        w = np.flatnonzero(np.asarray(rep.weight)[: len(meas_np)] >= 0.999)  # same window index on both sides
        n = len(w)
        diff = max(np.abs(np.asarray(rep.measured)[w] - meas_np[w]).max(),
                   np.abs(np.asarray(rep.predicted)[w] - pred_np[w]).max())
        print(f"one replay of 11022 ({len(rec['time_s'])} samples, {n} windows, DB1 {DB_INPUTS['db1'][0]}...): "
              f"pvvjax {t_jax * 1e6:.1f} µs, NumPy {t_np * 1e6:.0f} µs: {t_np / t_jax:.0f}x "
              f"(max difference {diff:.1e} g)")
    else:
        print(f"one replay of 11022: pvvjax {t_jax * 1e6:.1f} µs")

    # ---- batched replays
    offs = jnp.linspace(0.0, 1.0, 16)
    fb = jax.jit(jax.vmap(jax.vmap(lambda m, r, tau: replay(m, r, tau, 8.0, settings=s8).predicted,
                                   in_axes=(0, 0, None)), in_axes=(None, None, 0)))
    t_b = best(lambda: fb(model, recs, offs).block_until_ready(), 3, rep=3)
    n_rep = len(counters) * len(offs)
    print(f"batched: {n_rep} replays ({len(counters)} counters x {len(offs)} offsets) in {t_b * 1e3:.1f} ms: "
          f"{n_rep / t_b:,.0f} replays/s ({t_b / n_rep * 1e6:.1f} µs each)")

    # ---- calibration
    settings = make_settings(batch, max_window_revs=16.0, min_window_revs=4.0, hop_revs=1.0, offset_bounds=(-1.0, 3.0))
    members, mask = group_members(np.zeros(len(counters), int))
    mesh = np.meshgrid(np.arange(-1, 3.01, 0.25), np.arange(4, 16.01, 2.0), indexing="ij")
    coarse = np.stack(mesh, -1).reshape(-1, 2)
    run = lambda: jax.block_until_ready(calibrate(model, recs, members, mask, jnp.array([0.0, 8.0, 0.0]),  # noqa: E731
                                                  coarse, free=("offset_s", "window_revs"), settings=settings,
                                                  bounds=Bounds(window_revs=(4.0, 16.0))))
    t0 = time.perf_counter()
    cal = run()
    cold = time.perf_counter() - t0
    warm = best(run, 1, rep=3)
    offsets, lengths = np.arange(-1, 3.01, 0.1), np.arange(4, 16.01, 0.5)
    grid = lambda: jax.block_until_ready(cost_grid(model, recs, members, mask, offsets, lengths,  # noqa: E731
                                                   settings=settings))
    t0 = time.perf_counter()
    g = np.asarray(grid())[0]
    grid_cold = time.perf_counter() - t0
    grid_warm = best(grid, 1, rep=1)
    j, k = np.unravel_index(g.argmin(), g.shape)
    print(f"calibration of offset and window length over {len(counters)} maneuver counters (db1, hop 1 rev): "
          f"warm {warm:.2f} s, cold {cold:.1f} s (with compilation); {int(cal.steps[0])} LM steps -> "
          f"offset {float(cal.theta[0, 0]):.3f} s, L {float(cal.theta[0, 1]):.2f} revs, cost {float(cal.cost[0]):.3f}")
    print(f"brute-force grid {len(offsets)} x {len(lengths)}: warm {grid_warm:.1f} s, cold {grid_cold:.1f} s -> "
          f"offset {offsets[k]:.1f} s, L {lengths[j]:.1f} revs, cost {g.min():.3f}; "
          f"gradient calibration {grid_warm / warm:.0f}x faster")


if __name__ == "__main__":
    main()
