"""Does the physics-shaped dynamic model's identified response tell a planted response from
the base world's own? (issue "Discovery on the dynamic model", first probe.)

For the drawn worlds of `research/configs/worlds.toml` (the tuning seeds only: rules are
chosen there), the nulls and the worlds of the response families (slow-lag: a second lag in
series with the base world's 0.6 s one; mode: a second-order response after the lags),
`pvvjax dynamic`'s comparison of the window map and the physics-shaped model on db1, split
by condition: each model's held-out window RMS and the response it identified (median over
folds x seeds, with its range). One row per world in `OUT/rows.csv` (resumable), beside the
planted parameter.

    python research/dynamic_response_probe.py [--out research/runs/dynamic-response] [--seeds 2]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import pandas as pd

from pvvjax.config import DynamicConfig, ExperimentConfig
from pvvjax.data.campaign import campaign_from_frames
from pvvjax.dynamics import run_comparison
from pvvjax.experiment import enable_compilation_cache
from pvvjax.synth import generate

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))
from benchmark_worlds import load_plan, worlds  # noqa: E402

RESPONSE_FAMILIES = ("slow-lag", "mode")
IDENTIFIED = ("f_n_hz", "zeta", "delay_s", "tau_equivalent_s", "tau_slow_pole_s")


def probe_world(world: dict, seeds: int, out: Path) -> dict:
    """One world's row: the two models' held-out RMS and the identified response."""
    counters, records, _ = generate(world["synth"])
    campaign = campaign_from_frames(counters, records, aircraft=world["synth"].aircraft_constants(),
                                    source=world["name"])
    cfg = ExperimentConfig(dynamic=DynamicConfig(models=("window_static", "dynamic"), seeds=seeds,
                                                 kind_holdout=False))
    t0 = time.perf_counter()
    table = run_comparison(campaign, cfg, out / world["name"], log=lambda *a: None).set_index("model")
    dyn, static = table.loc["dynamic"], table.loc["window_static"]
    truth = world["truth"] or {}
    row = dict(world=world["name"], seed=world["seed"], family=truth.get("effect", "null"),
               parameter=truth.get("parameter", ""), value=truth.get("value", float("nan")),
               conditions=len(campaign.conditions()), rms_static_g=static.rms_g, rms_dynamic_g=dyn.rms_g,
               shrink=1.0 - dyn.rms_g / static.rms_g, degenerate=dyn.degenerate, seconds=time.perf_counter() - t0)
    for k in IDENTIFIED:
        row.update({k: dyn[k], f"{k}_lo": dyn[f"{k}_lo"], f"{k}_hi": dyn[f"{k}_hi"]})
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default=str(HERE / "configs" / "worlds.toml"))
    ap.add_argument("--out", default=str(HERE / "runs" / "dynamic-response"))
    ap.add_argument("--seeds", type=int, default=2, help="initialisation seeds per fold")
    ap.add_argument("--limit", type=int, default=0, help="at most this many worlds (0: all)")
    args = ap.parse_args(argv)
    enable_compilation_cache()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows_path = out / "rows.csv"
    done = pd.read_csv(rows_path) if rows_path.exists() else pd.DataFrame(columns=["world"])
    todo = [w for w in worlds(load_plan(args.config)) if (w["truth"] is None or w["truth"]["effect"]
                                                          in RESPONSE_FAMILIES) and "also" not in (w["truth"] or {})]
    todo = [w for w in todo if w["name"] not in set(done.world)][: args.limit or None]
    for i, world in enumerate(todo):
        row = probe_world(world, args.seeds, out)
        done = pd.concat([done, pd.DataFrame([row])], ignore_index=True)
        done.to_csv(rows_path, index=False)
        print(f"[{i + 1}/{len(todo)}] {world['name']}: static {row['rms_static_g']:.4f} g, dynamic "
              f"{row['rms_dynamic_g']:.4f} g ({row['shrink']:+.1%}); f_n {row['f_n_hz']:.3f} Hz, ζ {row['zeta']:.2f}, "
              f"delay {row['delay_s']:.2f} s, τ_eq {row['tau_equivalent_s']:.2f} s; truth {row['parameter']} "
              f"{row['value']:.3g} ({row['seconds']:.0f} s)", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
