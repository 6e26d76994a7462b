"""Per-frame latency of the C element beside the NumPy element, on the same nets and frames.

The db1 element of a sweep (every net of its best architecture, their median; the main job's
sweep has 20: 4 seeds x 5 folds), offset 0.66 s, 8-rev windows every revolution, the pull-up
11022 resampled to 1 kHz frames:

- the NumPy element (`VibrationElement.step`), timed per frame in Python;
- the C element (`pvvjax export --format c`) compiled with -O2 into a small host program that
  times each `pvv_step` with `clock_gettime` (the timer's own cost is printed beside it).

Both run the same frames; the C outputs are checked against the NumPy ones. Median, 99th
percentile and max per frame, and the ratio.

    python benchmarks/bench_c_element.py [--sweep runs/paper/sweep] [--pinned]
    python benchmarks/bench_c_element.py --dynamic runs/dynamic [--model dynamic]

Needs a sweep with db1 nets (`make demo` writes runs/paper/sweep) and a C compiler; with
`--dynamic`, the folder of `pvvjax dynamic` instead: its model's nets (every fold and seed),
windows and, for `dynamic`, its response.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from pvvjax.analysis.databases import DB_INPUTS
from pvvjax.config import load_config
from pvvjax.data.campaign import load_campaign
from pvvjax.dynamics.study import element_model
from pvvjax.nets import load_nets
from pvvjax.realtime import CHANNELS, NumpyNet, VibrationElement, c_compiler, write_c_element
from pvvjax.realtime.cexport import CSourceLimits
from pvvjax.synth import cached_campaign

HOST = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "pvv_element.h"

static pvv_element el;

static double ns(struct timespec a, struct timespec b) { return (b.tv_sec - a.tv_sec) * 1e9 + (b.tv_nsec - a.tv_nsec); }

int main(int argc, char **argv)
{
    long n, i, rep, reps = atol(argv[3]);
    FILE *f = fopen(argv[1], "rb");
    double *fr, *out;
    pvv_settings s = pvv_default_settings();
    struct timespec a, b, c, d;
    if (!f || fread(&n, sizeof n, 1, f) != 1) return 1;
    fr = malloc((size_t)n * 12 * sizeof(double));
    out = malloc((size_t)n * 4 * sizeof(double));
    if (fread(fr, sizeof(double), (size_t)n * 12, f) != (size_t)n * 12) return 1;
    fclose(f);
    if (pvv_init(&el, &s) != PVV_OK) return 2;
    for (rep = 0; rep < reps; rep++) {
        pvv_reset(&el);
        for (i = 0; i < n; i++) {
            pvv_output o;
            clock_gettime(CLOCK_MONOTONIC, &a);
            o = pvv_step(&el, fr[i * 12], fr[i * 12 + 1], fr + i * 12 + 2);
            clock_gettime(CLOCK_MONOTONIC, &b);
            clock_gettime(CLOCK_MONOTONIC, &c);
            clock_gettime(CLOCK_MONOTONIC, &d);  /* the timer alone, for scale */
            out[i * 4] = ns(a, b);  /* the last pass is kept: caches warm, as in a running simulator */
            out[i * 4 + 1] = o.pvv_g;
            out[i * 4 + 2] = o.shake_g;
            out[i * 4 + 3] = ns(c, d);
        }
    }
    f = fopen(argv[2], "wb");
    fwrite(out, sizeof(double), (size_t)n * 4, f);
    fclose(f);
    return 0;
}
"""


def _sweep_nets(sweep: Path) -> tuple[list, str]:
    """Every net of the db1 architecture that holds out best, and its name."""
    if not (sweep / "results.parquet").is_file():
        sys.exit(f"{sweep}: no sweep here; run `make demo` (writes runs/paper/sweep) or give --sweep")
    res = pd.read_parquet(sweep / "results.parquet")
    db1 = res[res.database == "db1"]
    arch = db1.groupby("architecture").test_rms_g.median().idxmin()
    ids = list(db1[db1.architecture == arch].sort_values(["test_fold", "seed"]).net_id)
    return [NumpyNet(p, m) for p, m in load_nets(sweep, ids, res)], arch


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sweep", default="runs/paper/sweep", help="sweep folder with db1 nets")
    ap.add_argument("--pinned", action="store_true", help="pin to one core (as a real-time host would)")
    ap.add_argument("--dynamic", default=None, help="a `pvvjax dynamic` folder: time its model's element instead")
    ap.add_argument("--model", default="dynamic", help="with --dynamic: which model (default: dynamic)")
    args = ap.parse_args()
    if args.pinned:
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    cc = c_compiler()
    if cc is None:
        sys.exit("no C compiler (set CC or install cc/gcc/clang)")
    if args.dynamic:
        em = element_model(Path(args.dynamic), load_config(Path(args.dynamic) / "config.toml"), args.model)
        nets = [NumpyNet(p, m) for p, m in em.nets]
        arch, inputs = f"{em.model} ({em.database})", list(em.nets[0][1]["inputs"])
        kw = dict(window_revs=em.window_revs, hop_revs=em.hop_revs, offset_s=em.offset_s, stick_offset_s=0.0)
        extra = {} if em.response is None else {"response": em.response}
    else:
        nets, arch = _sweep_nets(Path(args.sweep))
        inputs, kw, extra = list(DB_INPUTS["db1"]), dict(window_revs=8.0, hop_revs=1.0, offset_s=0.66,
                                                         stick_offset_s=0.0), {}

    camp = load_campaign(cached_campaign())
    rec = camp.records["11022"]
    t0, rev0 = rec.time_s.to_numpy(), np.unwrap(rec.azimuth_deg.to_numpy(), period=360.0)
    x0 = rec[list(CHANNELS)].to_numpy(float)
    t = np.arange(t0[0], t0[-1], 1e-3)
    az = np.mod(np.interp(t, t0, rev0), 360.0)
    x = np.stack([np.interp(t, t0, x0[:, c]) for c in range(x0.shape[1])], 1)
    compiler = subprocess.run([cc, "--version"], capture_output=True, text=True).stdout.splitlines()[0]
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores{' (pinned to one)' if args.pinned else ''}, "
          f"numpy {np.__version__}, {compiler}; element: {len(nets)} {arch} nets, {kw}{extra}, record 11022 at 1 kHz "
          f"({t.size} frames)")

    el = VibrationElement(nets, inputs, **kw, **extra)
    lat_np, ref = np.empty(t.size), np.empty((t.size, 2))
    clock = time.perf_counter_ns
    for i in range(t.size):
        s = clock()
        o = el.step(t[i], az[i], x[i])
        lat_np[i] = (clock() - s) / 1e3
        ref[i] = o.pvv_g, o.shake_g

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        lo = min(CSourceLimits().window_revs[0], kw["window_revs"])
        write_c_element(tmp, dict(inputs=inputs, aircraft=dict(blades=4), **kw, **extra), nets,
                        CSourceLimits(window_revs=(lo, CSourceLimits().window_revs[1])))
        (tmp / "host.c").write_text(HOST)
        subprocess.run([cc, "-std=c99", "-O2", "-o", str(tmp / "host"), str(tmp / "host.c"),
                        str(tmp / "pvv_element.c"), "-lm"], check=True)
        frames = np.concatenate([t[:, None], az[:, None], x], 1).astype(np.float64)
        with open(tmp / "frames.bin", "wb") as f:
            f.write(np.int64(t.size).tobytes() + frames.tobytes())
        subprocess.run([str(tmp / "host"), str(tmp / "frames.bin"), str(tmp / "out.bin"), "3"], check=True)
        out = np.fromfile(tmp / "out.bin").reshape(t.size, 4)
    lat_c, timer = out[:, 0] / 1e3, out[:, 3] / 1e3
    diff = np.abs(out[:, 1:3] - ref).max()

    def row(name, lat):
        p50, p99 = np.percentile(lat, [50, 99])
        return p50, f"{name}: median {p50:.3f} µs, 99th percentile {p99:.2f} µs, max {lat.max():.0f} µs per frame"

    (n50, text_np), (c50, text_c) = row("NumPy element", lat_np), row("C element (-O2)", lat_c)
    print(text_np)
    print(text_c + f" (the timer alone: median {np.median(timer) * 1e3:.0f} ns)")
    print(f"C / NumPy: {n50 / c50:.0f}x faster at the median; C equals NumPy to {diff:.1e} g (PVV, shake)")


if __name__ == "__main__":
    main()
