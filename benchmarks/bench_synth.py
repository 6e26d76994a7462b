"""Time to generate and write the default synthetic campaign (goal: under 60 s on 2 cores),
and to load it back. Usage: python benchmarks/bench_synth.py"""

from __future__ import annotations

import platform
import tempfile
import time
from pathlib import Path

from pvvjax.data.campaign import load_campaign
from pvvjax.synth import SynthConfig, generate, write_synthetic


def main():
    cfg = SynthConfig()
    t0 = time.perf_counter()
    counters, records, _ = generate(cfg)
    t_gen = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        folder, _ = write_synthetic(Path(tmp) / "campaign", cfg)
        t_write = time.perf_counter() - t0
        size = sum(p.stat().st_size for p in folder.rglob("*")) / 1e6
        t0 = time.perf_counter()
        camp = load_campaign(folder)
        t_load = time.perf_counter() - t0
    samples = sum(len(r) for r in records.values())
    print(f"machine: {platform.machine()}; {len(camp.conditions())} conditions, {len(counters)} counters, "
          f"{samples / 1e6:.2f} M samples, {size:.0f} MB of Parquet")
    print(f"generate in memory: {t_gen:.1f} s; generate + write: {t_write:.1f} s; load + validate: {t_load:.1f} s")


if __name__ == "__main__":
    main()
