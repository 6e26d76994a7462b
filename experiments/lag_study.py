"""A lag tested with nets trained through it (`pvvjax.lag_study`), on benchmark worlds.

    python experiments/lag_study.py experiments/configs/discovery/benchmark.toml \
        --only long-lag,null-31,null-41,null-51 --seed-offsets 0,1,2 [--taus 1,2,3] [--out runs/lag-study]

Each world is generated as in the hidden-effect benchmark (`discovery_benchmark.py`) and
studied with the benchmark's [discovery] settings. Writes OUT/results.{parquet,csv}: every
trained ensemble of every world, and prints each world's best lag against its best reference.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd
from discovery_benchmark import scenario_configs

from pvvjax._strict import from_dict
from pvvjax.campaign import campaign_from_frames
from pvvjax.config import DiscoveryConfig, ExperimentConfig
from pvvjax.io import write_table
from pvvjax.lag_study import lag_study
from pvvjax.synth import generate


def _floats(s: str) -> tuple[float, ...]:
    return tuple(float(v) for v in s.split(",") if v)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("config")
    ap.add_argument("--only", default="long-lag,null-31,null-41,null-51", help="comma-separated scenario names")
    ap.add_argument("--seed-offsets", default="0")
    ap.add_argument("--taus", default="1,2,3")
    ap.add_argument("--reference-offsets", default="0,0.5")
    ap.add_argument("--out", default="runs/lag-study")
    a = ap.parse_args()
    names = a.only.split(",")
    tables = []
    for so in (int(v) for v in a.seed_offsets.split(",")):
        scenarios, overrides = scenario_configs(a.config, so)
        missing = set(names) - {s["name"] for s in scenarios}
        if missing:
            raise SystemExit(f"{a.config}: no scenario named {sorted(missing)}")
        for sc in (s for s in scenarios if s["name"] in names):
            print(f"== {sc['name']} (seed {sc['seed']})", flush=True)
            counters, records, _truth = generate(sc["synth"])  # the truth stays here
            cfg = ExperimentConfig(discovery=from_dict(DiscoveryConfig, {**overrides, "database": sc["database"]}))
            t = lag_study(campaign_from_frames(counters, records, source=sc["synth"].name), cfg,
                          taus=_floats(a.taus), reference_offsets=_floats(a.reference_offsets),
                          log=lambda m: print(m, flush=True))
            tables.append(t.assign(scenario=sc["name"], seed=sc["seed"]))
    df = pd.concat(tables, ignore_index=True)
    write_table(df, Path(a.out) / "results", cfg)
    lagged = df[df.tau_s > 0]
    best = lagged.loc[lagged.groupby(["scenario", "seed"]).ensemble_rms_g.idxmin()]
    ref = df[df.tau_s == 0].groupby(["scenario", "seed"]).ensemble_rms_g.min().rename("reference_rms_g")
    print(best.join(ref, on=["scenario", "seed"])[["scenario", "seed", "reference_rms_g", "tau_s", "offset_s",
                                                   "ensemble_rms_g", "drop"]].to_string(index=False))


if __name__ == "__main__":
    main()
