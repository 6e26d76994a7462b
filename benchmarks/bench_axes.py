"""The three axes' 1/rev, N/rev and 2N/rev in one windowed pass (`analysis.analyze_axes`)
against what a user would otherwise run: the one-axis analysis once per axis and harmonic
(`analysis.analyze`, nine passes), on the embedded campaign. Compiled programs are warmed up
first; the median of repeats is reported. Usage: python benchmarks/bench_axes.py"""

from __future__ import annotations

import platform
import time

import jax
import numpy as np

from pvvjax.analysis import AXES, STATE_CHANNELS, analyze, analyze_axes
from pvvjax.data.batch import to_batch
from pvvjax.data.campaign import load_campaign
from pvvjax.synth import cached_campaign

HARMONICS = (1, 4, 8)


def _median_s(fn, repeats: int = 5) -> float:
    jax.block_until_ready(fn())  # compile
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main():
    campaign = load_campaign(cached_campaign())
    three = to_batch(campaign, STATE_CHANNELS, axis=AXES)
    ones = {a: to_batch(campaign, STATE_CHANNELS, axis=a) for a in AXES}
    one_pass = _median_s(lambda: analyze_axes(three, HARMONICS, 8.0).amplitude)
    nine = _median_s(lambda: [analyze(ones[a], 8.0, harmonic=k).amplitude for a in AXES for k in HARMONICS])
    samples = int(np.asarray(three.mask).sum())
    print(f"machine: {platform.machine()}, {jax.device_count()} {jax.default_backend()} device(s); "
          f"{len(three.counters)} counters, {samples / 1e6:.2f} M samples, 3 axes x harmonics {HARMONICS}")
    print(f"one pass (analyze_axes): {one_pass:.3f} s; nine one-axis passes (analyze): {nine:.3f} s; "
          f"ratio {nine / one_pass:.1f}x")


if __name__ == "__main__":
    main()
