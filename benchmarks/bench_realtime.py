"""Real-time element latency and streaming throughput.

The db1 element of the paper networks (20 nets: 4 seeds × 5 folds, their median), offset
0.66 s, 8-rev windows updated every revolution, on the pull-up 11022:

- the exported NumPy element, one `step` per frame at 1 kHz (what a simulator host
  calls): median and 99th-percentile latency per frame;
- the jitted JAX `realtime.step` called once per frame (dispatch included);
- the JAX `realtime.stream` (one `lax.scan` over the record's 320 Hz frames): how many
  times faster than real time, in float32 and float64.

    python benchmarks/bench_realtime.py [--pinned]

Needs the paper networks (experiments/paper_networks.py).
"""

from __future__ import annotations

import os
import sys

if "--pinned" in sys.argv:  # before JAX starts its thread pool
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})

import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pvvjax.analysis.databases import DB_INPUTS  # noqa: E402
from pvvjax.data.campaign import load_campaign  # noqa: E402
from pvvjax.nets.sweep import load_nets  # noqa: E402
from pvvjax.realtime import jax_element as RT  # noqa: E402
from pvvjax.realtime.element import CHANNELS, VibrationElement  # noqa: E402
from pvvjax.realtime.npnet import NumpyNet  # noqa: E402
from pvvjax.synth import cached_campaign  # noqa: E402

SWEEP = Path("runs/paper-networks/sweep")
KW = dict(window_revs=8.0, hop_revs=1.0, offset_s=0.66)


def main():
    camp = load_campaign(cached_campaign())
    res = pd.read_parquet(SWEEP / "results.parquet")
    ids = list(res[res.database == "db1"].sort_values(["test_fold", "seed"]).net_id)
    plist = [p for p, _ in load_nets(SWEEP, ids, res)]
    rec = camp.records["11022"]
    t0, rev0 = rec.time_s.to_numpy(), np.unwrap(rec.azimuth_deg.to_numpy(), period=360.0)
    x0 = rec[list(CHANNELS)].to_numpy(float)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores{' (pinned to one)' if '--pinned' in sys.argv else ''}"
          f", jax {jax.__version__}, numpy {np.__version__}; element: {len(plist)} db1 nets, record 11022 "
          f"({t0[-1]:.1f} s)")

    # NumPy element at 1 kHz
    t = np.arange(t0[0], t0[-1], 1e-3)
    az = np.mod(np.interp(t, t0, rev0), 360.0)
    x = np.stack([np.interp(t, t0, x0[:, c]) for c in range(x0.shape[1])], 1)
    el = VibrationElement([NumpyNet(p) for p in plist], DB_INPUTS["db1"], **KW)
    lat = np.empty(t.size)
    clock = time.perf_counter_ns
    for i in range(t.size):
        s = clock()
        el.step(t[i], az[i], x[i])
        lat[i] = (clock() - s) / 1e3
    p50, p99 = np.percentile(lat, [50, 99])
    print(f"NumPy element, {t.size} frames at 1 kHz: median {p50:.1f} µs, 99th percentile {p99:.1f} µs, "
          f"max {lat.max():.0f} µs per frame ({p50 / 10:.2f} % of a 1 ms frame); "
          f"{(t[-1] - t[0]) / (lat.sum() / 1e6):.0f}x real time")

    # JAX: one jitted step per frame, and the whole record in one scan
    for dtype, x64 in (("float32", False), ("float64", True)):
        with jax.enable_x64(x64):
            ft = jnp.float64 if x64 else jnp.float32
            stacked = jax.tree.map(lambda *a: jnp.stack([jnp.asarray(v, ft if np.asarray(v).dtype.kind == "f"
                                                                     else None) for v in a]), *plist)
            spec = RT.make_spec(stacked, DB_INPUTS["db1"], **KW)
            s0 = RT.init(RT.capacity_for(8.0, 1.0, [0.66], 1000.0))
            step = jax.jit(RT.step, donate_argnums=1)  # the state is updated in place
            s = s0
            lat = np.empty(3000)
            for i in range(3000):
                c = clock()
                s, o = step(spec, s, t[i], az[i], x[i])
                o.pvv_g.block_until_ready()
                lat[i] = (clock() - c) / 1e3
            lat = lat[100:]
            T, AZ, X = (jnp.asarray(v, ft) for v in (t0, np.mod(rev0, 360.0), x0))
            s0 = RT.init(RT.capacity_for(8.0, 1.0, [0.66], 320.0), ft)
            jax.block_until_ready(RT.stream(spec, s0, T, AZ, X))
            best = 1e9
            for _ in range(5):
                c = time.perf_counter()
                jax.block_until_ready(RT.stream(spec, s0, T, AZ, X))
                best = min(best, time.perf_counter() - c)
            print(f"JAX {dtype}: jitted step per frame median {np.median(lat):.1f} µs, 99th percentile "
                  f"{np.percentile(lat, 99):.1f} µs; stream of {T.size} frames (320 Hz) {best * 1e3:.1f} ms: "
                  f"{t0[-1] / best:.0f}x real time")


if __name__ == "__main__":
    main()
