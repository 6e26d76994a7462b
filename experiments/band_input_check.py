"""Would `resonance_input` change a finished benchmark world?

The option adds one try per resonance band a round proposes: the band as an extra network
input beside its gain (`discovery._round._modes`). Every other try, and so every choice,
is the same unless one of those tries confirms. This retrains each band a world's rounds
tried (`rounds.csv`) as an input on the model that round started from (rebuilt from the
world's folder: `attributable_ensemble.rebuild`) and asks the workflow's first test
(`_confirm`); a world whose band inputs all fail it makes the same choices with the option,
without a whole re-run. The probe's test and the floor control, which come after, can only
reject more. `--verify` retrains each band's gain too, which must reproduce the shrink the
table's round measured.

    python experiments/band_input_check.py OUT --seed-offsets 0,1 [--only roll-rate] [--verify]

writes OUT/[seed+N/]band_input_check.csv.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).parent))
from attributable_ensemble import CONFIG, _save, named_candidate, rebuild  # noqa: E402
from discovery_benchmark import _campaign, scenario_config, scenario_configs  # noqa: E402

from pvvjax.discovery._confirm import _augment, _confirm  # noqa: E402
from pvvjax.discovery.candidates import Candidate, from_key  # noqa: E402
from pvvjax.io import read_table  # noqa: E402


def band_rows(folder: Path) -> pd.DataFrame:
    """The band tries of a finished discovery's rounds (one row per band and round)."""
    try:
        r = pd.read_csv(folder / "rounds.csv")
    except (FileNotFoundError, pd.errors.EmptyDataError):
        return pd.DataFrame(columns=["round", "proposal"])
    r = r[r.operator == "resonance"]
    if "proposal" not in r:  # a table before the column: the tried band without its gain's fit
        r = r.assign(proposal=[_without(from_key(k)).key for k in r.candidate])
    return r.drop_duplicates(["round", "proposal"])


# What a band's try adds to the proposal it tries: its gain's unit and fit.
_FITTED = ("gain", "gain_unit", "coefficient")


def _without(c: Candidate, names=_FITTED) -> Candidate:
    return Candidate(c.operator, c.channels, {k: v for k, v in c.parameters.items() if k not in names})


def _proposal(row) -> Candidate:
    """The band a row tried, at full precision where the table keeps its parameters."""
    if isinstance(getattr(row, "parameters", None), str):
        return _without(named_candidate(row))
    return from_key(row.proposal)


def check_world(sc: dict, overrides: dict, folder: Path, verify: bool, log=print) -> list[dict]:
    """Each band of the world's rounds as an input on its round's model, confirmed or not."""
    bands = band_rows(folder)
    if not len(bands):
        return []
    cfg = scenario_config(sc, overrides)
    starts = {}
    ctx = rebuild(_campaign(sc["synth"]), cfg, folder, log=lambda m: None,
                  each=lambda rnd, model: starts.setdefault(rnd, model))[0]
    out = []
    for b in bands.itertuples():
        current = starts[b.round]
        c = _proposal(b)
        ok, conf = _confirm(ctx, current, _augment(ctx, current, c, "input"), c, b.where, cfg.discovery)
        row = dict(scenario=sc["name"], seed=sc["seed"], round=b.round, band=c.name, proposal=b.proposal,
                   table_gain_shrink=b.shrink, table_gain_confirmed=b.confirmed, input_shrink=conf["shrink"],
                   input_region_shrink=conf["local"], input_confirmed=ok, why=conf["why"])
        if verify and b.augment == "gain":
            g = named_candidate(b)
            row["gain_shrink"] = _confirm(ctx, current, _augment(ctx, current, g, "gain"), g, b.where,
                                          cfg.discovery)[1]["shrink"]
        log(f"    round {b.round}, {c.name}: as an input {conf['shrink']:+.1%} (all), {conf['local']:+.1%} "
            f"({conf['judged_in']}): {'CONFIRMED' if ok else conf['why']}"
            + (f"; its gain {row['gain_shrink']:+.2%} (table {b.shrink:+.2%})" if "gain_shrink" in row else ""))
        out.append(row)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path, help="a benchmark output folder (discovery_benchmark.py --out)")
    ap.add_argument("--seed-offsets", default="0", help="comma-separated, as the benchmark's")
    ap.add_argument("--only", default="", help="comma-separated scenario names")
    ap.add_argument("--verify", action="store_true", help="retrain each band's gain too (the table's shrink)")
    args = ap.parse_args()
    only = {s for s in args.only.split(",") if s}
    rows = []
    for off in (int(v) for v in args.seed_offsets.split(",")):
        folder = args.out / (f"seed+{off}" if off else "")
        names = set(read_table(folder / "results.parquet")[0].scenario)
        scenarios, overrides = scenario_configs(CONFIG, off)
        for sc in scenarios:
            if sc["name"] not in names or (only and sc["name"] not in only):
                continue
            t0 = time.perf_counter()
            print(f"seed offset {off}, {sc['name']} (seed {sc['seed']})", flush=True)
            got = check_world(sc, overrides, folder / sc["name"], args.verify, log=lambda m: print(m, flush=True))
            print(f"  {len(got)} band(s), {time.perf_counter() - t0:.0f} s", flush=True)
            if got:
                _save(pd.DataFrame(got).assign(offset=off), folder / "band_input_check.csv")
            rows += [dict(r, offset=off) for r in got]
    df = pd.DataFrame(rows)
    if len(df):
        hit = df[df.input_confirmed]
        print(f"{len(df)} band tries in {df.groupby(['offset', 'scenario']).ngroups} worlds; as an input, the "
              f"shrink over all windows {df.input_shrink.min():+.1%} to {df.input_shrink.max():+.1%}; confirmed: "
              + (", ".join(f"{r.scenario} (+{r.offset}) round {r.round}" for r in hit.itertuples()) or "none"))


if __name__ == "__main__":
    main()
