"""The discovery benchmark on worlds drawn at random (research/benchmark_worlds.py), run with
`pvvjax discover`'s defaults: what a user gets is what the table measures.

Each world is generated, its truth file written (the generator's ground truth, the draws and
the judged truth), and `discover` runs on the campaign alone. A world is scored against its
truth and the null world of its seed:

- right first: the first effect named as missing is the truth (the misfit's forms are named
  before any; on a two-effect world, the larger of the two: the one whose vibration differs
  more from the null's, RMS over every sample);
- both named (two-effect worlds): each truth among the named effects;
- clean (null worlds): nothing named;
- spurious: an effect named that no planted family accepts;
- attributable shrink: (before − after) / (before − the null's before) on the family's gap
  metric (the ensemble's held-out RMS, or the peak error for a lag or mode);
- parameter error: |fitted − true| / true of the first right effect's parameter.

    python research/world_benchmark.py research/configs/worlds.toml [--fresh] [--only a,b] [--out DIR]
        [--lane simulation] [--docs]   # also research/discovery-benchmark.md (fresh seeds only)

The db1 lane (the default) runs discovery from the db1 nets; the simulation lane from the
world's base law with its coefficients drawn wrong and its planted effects left out
(`world_truth.with_simulation`), given as a column with the channels that law takes: a lane
whose null worlds have nothing missing.

Resumes: a world whose row is in OUT/rows.csv is read back, not run again; OUT/provenance.json
keeps the commit and date the run started at.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import subprocess
import sys
import time
from datetime import date
from pathlib import Path

# The runs go side by side, a process per core: scikit-learn's trees on every core in each
# process oversubscribe the machine (OpenMP threads that spin) and the test stage of a
# 200-condition world took 224 s against 17 s alone.
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pvvjax.config import DiscoveryConfig, ExperimentConfig, from_dict  # noqa: E402
from pvvjax.data.campaign import campaign_from_frames  # noqa: E402
from pvvjax.discovery import discover, summary  # noqa: E402
from pvvjax.experiment import enable_compilation_cache  # noqa: E402
from pvvjax.io import markdown_table  # noqa: E402
from pvvjax.synth import generate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _research(name: str):
    """A script of research/ as a module (research/ is not a package)."""
    spec = importlib.util.spec_from_file_location(name, ROOT / "research" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # its dataclasses' annotations resolve in their module
    spec.loader.exec_module(mod)
    return mod


bw = _research("benchmark_worlds")
wt = _research("world_truth")


def matches(effect: dict, accept) -> bool:
    """Whether a named effect is one of the accepted operator[:channel] forms."""
    for a in accept:
        op, _, ch = a.partition(":")
        if effect["operator"] == op and (not ch or ch in effect["channels"]):
            return True
    return False


def effect_size(world: dict, family: str, null: dict) -> float:
    """RMS over every sample of the vertical acceleration that one family of a two-effect
    world adds to its base (the world with that family alone, minus the null world of its
    seed, `null` its records: counter -> time series): which of the two effects is the
    larger."""
    with_it = generate(world["alone"][family])[1]
    d = np.concatenate([(with_it[k].az_g - null[k].az_g).to_numpy() for k in with_it])
    return float(np.sqrt(np.mean(d**2)))


def run_world(world: dict, out: Path, cfg: ExperimentConfig | None = None, lane: str = "db1") -> dict:
    """Generate a world, write its truth file (the generator's truth, the draws, the judged
    truth and every discrepancy against db1 with its size and the world's floor:
    `world_truth.discrepancies`), run `discover` with the defaults (`cfg`: other settings,
    for the test suite's micro run only) and keep its baseline's windows (out-of-fold
    prediction, measured level, window edges: OUT/windows/<world>.parquet, what the oracle
    tests); the row of what scoring needs (the named effects as JSON, the metrics before and
    after, the floor, seconds, and the seconds of each stage of discovery as JSON)."""
    for sub in ("truth", "windows"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    counters, records, _ = generate(world["synth"])
    truth = {**bw.world_truth(world),
             "discrepancies": wt.discrepancies(world["synth"], records, world["drawn"], lane=lane)}
    if lane == "simulation":
        records = wt.with_simulation(world["synth"], records)
    (out / "truth" / f"{world['name']}.truth.json").write_text(json.dumps(truth, indent=1))
    t_truth = time.perf_counter() - t0
    campaign = campaign_from_frames(counters, records, aircraft=world["synth"].aircraft_constants(),
                                    source=world["name"])
    own = {"database": world["database"]} if lane == "db1" else {
        "simulation": wt.SIMULATION_COLUMN, "simulation_inputs": list(wt.SIMULATION_INPUTS)}
    cfg = cfg or ExperimentConfig(name=world["name"], discovery=from_dict(DiscoveryConfig, own))
    res = discover(campaign, cfg, name=world["name"], log=lambda m: None)
    js = summary(res)
    keep = [c for c in res.windows.columns if not c.startswith("effect_") and c not in ("i", "k")]
    res.windows[keep].to_parquet(out / "windows" / f"{world['name']}.parquet", index=False)
    row = dict(world=world["name"], seed=world["seed"], database=world["database"] if lane == "db1" else lane,
               family=world["truth"]["effect"] if world["truth"] else "none",
               also=world["truth"].get("also", {}).get("effect", "") if world["truth"] else "",
               aircraft=world["drawn"]["aircraft"], conditions=world["drawn"]["conditions"],
               named=" > ".join(e["name"] for e in js["effects"]) or "none", effects=json.dumps(js["effects"]),
               offset_s=float(res.baseline.offset_s), floor_g=truth["discrepancies"]["floor_g"],
               seconds=time.perf_counter() - t0 - t_truth, truth_seconds=t_truth, commit=_head(),
               stages=json.dumps({k: round(float(v), 1) for k, v in res.seconds.items()}))
    for k in ("ensemble_rms_g", "peak_error_g", "rms_g"):
        row[f"{k}_before"], row[f"{k}_after"] = float(res.before[k]), float(res.after[k])
    return row


def score(rows: pd.DataFrame, worlds: list[dict]) -> pd.DataFrame:
    """Each world's row with its scores (see the module docstring)."""
    by = {w["name"]: w for w in worlds}
    null_cfg = {w["seed"]: w.get("synth") for w in worlds if w["truth"] is None}
    null_records = {}  # seed -> its null world's records, generated once for the two-effect worlds
    nulls = {r.seed: r for r in rows.itertuples() if r.family == "none"}
    out = []
    for r in rows.to_dict("records"):
        w, effects = by[r["world"]], json.loads(r["effects"])
        t = w["truth"]
        s = dict(right_first=np.nan, both_named=np.nan, clean=np.nan, spurious=np.nan, attributable=np.nan,
                 parameter_error=np.nan)
        if t is None:
            s["clean"] = not effects
        else:
            truths = [t] + ([t["also"]] if "also" in t else [])
            if len(truths) > 1:
                if w["seed"] not in null_records:
                    null_records[w["seed"]] = generate(null_cfg[w["seed"]])[1]
                sizes = [effect_size(w, x["effect"], null_records[w["seed"]]) for x in truths]
                truths = [truths[i] for i in np.argsort(sizes)[::-1]]
                s["both_named"] = all(any(matches(e, x["accept"]) for e in effects) for x in truths)
            # The first named as missing: the misfit's forms are named before any.
            first = next((e for e in effects if e.get("kind") != "misfit"), None)
            s["right_first"] = bool(first and matches(first, truths[0]["accept"]))
            s["spurious"] = any(not any(matches(e, x["accept"]) for x in truths) for e in effects)
            null = nulls.get(r["seed"])
            metric = truths[0]["gap_metric"]
            if null is not None:
                gap = r[f"{metric}_before"] - getattr(null, f"{metric}_before")
                if gap > 0:
                    s["attributable"] = (r[f"{metric}_before"] - r[f"{metric}_after"]) / gap
            if s["right_first"] and "parameter" in truths[0]:
                fitted = first["parameters"].get(truths[0]["parameter"], np.nan)
                s["parameter_error"] = abs(fitted - truths[0]["value"]) / abs(truths[0]["value"])
        out.append({**r, **s})
    return pd.DataFrame(out)


def table(df: pd.DataFrame) -> pd.DataFrame:
    """Per family (a two-effect world under its first family) and overall: the counts and
    medians of the scores."""
    def line(name, g):
        hidden, nulls = g[g.family != "none"], g[g.family == "none"]
        two = hidden[hidden.also != ""]
        att = hidden.attributable.dropna()
        frac = lambda a, b: f"{int(a)} / {int(b)}" if b else ""  # noqa: E731
        return {"family": name, "worlds": len(g),
                "right first": frac(hidden.right_first.sum(), len(hidden)),
                "both named (two effects)": frac(two.both_named.sum(), len(two)),
                "nulls clean": frac(nulls.clean.sum(), len(nulls)),
                "median attributable": f"{att.median():.2f}" if len(att) else "",
                "attributable ≥ 0.5": frac((att >= 0.5).sum(), len(att)),
                "spurious extra": frac(hidden.spurious.sum(), len(hidden)),
                "median parameter error": (f"{hidden.parameter_error.median():.1%}"
                                           if hidden.parameter_error.notna().any() else ""),
                "median seconds": f"{g.seconds.median():.0f}"}
    fams = [f for f in df.family.unique() if f != "none"]
    return pd.DataFrame([line(f, df[df.family == f]) for f in ["none", *sorted(fams)]] + [line("all", df)])


def _head() -> str:
    """The commit this process runs (each row carries it: a run resumed after a change of
    the code says which worlds ran on which)."""
    if not hasattr(_head, "commit"):
        _head.commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                      cwd=ROOT).stdout.strip()
    return _head.commit


def _provenance(out: Path) -> dict:
    """The commit and date a run in `out` started at (`provenance.json`, written by its
    first world): the code the table's rows come from, whatever HEAD is when it is written."""
    path = out / "provenance.json"
    if not path.exists():
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                                cwd=ROOT).stdout.strip()
        path.write_text(json.dumps(dict(commit=commit, date=str(date.today()), machine=platform.machine())))
    return json.loads(path.read_text())


def docs(t: pd.DataFrame, df: pd.DataFrame, prov: dict, config: str) -> str:
    """research/discovery-benchmark.md: the protocol, the table per family and every world."""
    cols = ["world", "aircraft", "conditions", "named", "right_first", "both_named", "clean", "spurious",
            "attributable", "parameter_error", "seconds"]
    hours = df.seconds.sum() / 3600
    return f"""# Discovery: the hidden-effect benchmark on drawn worlds

Command: `python research/world_benchmark.py {config} --fresh --docs`, run once at
{prov['commit']} on {prov['date']} ({prov['machine']}, the 2-core VM; {len(df)} worlds in
{hours:.1f} hours of discovery, one process), with `pvvjax discover`'s defaults: no setting
is changed for the benchmark.

The worlds (`research/configs/worlds.toml`, `research/benchmark_worlds.py`): every default
effect of the generator on (both maneuver transients, the rotor-speed resonance,
autorotations, the 0.6 s lag), on the UH-60A or the AH-1S rotor, with the steady vertical
law (each parameter ±30 %), the noise and the scatter (×0.5–2) and the size (80–300
conditions) drawn per world. Each fresh seed gives a null world and two hidden worlds on its
base; a fifth of the hidden worlds carry two families. Eight families draw their
parameters (scales over a decade; a lag's τ 0.5–4 s; a mode's f_n 0.1–1 Hz and ζ 0.1–0.9; a
band's centre over 94–106 % of the rotor speed and its width; a knee's position); three are
left out with the reason in the config. The rules were frozen before this run (the tuning
seeds' record is in the lab log, "Discovery's defaults on drawn worlds: the tuning seeds");
it is not re-run to choose among rules.

Scores (`research/world_benchmark.py`): right first (the larger effect of two, by the RMS of
what it adds to the vertical acceleration); both named; nulls clean (nothing named); the
attributable shrink (before − after) / (before − the null's before) on the family's gap
metric (the ensemble's held-out RMS; the peak error for a lag or a mode; undefined where the
world's baseline is not above its null's); a spurious extra (an effect named that no planted
family accepts); the parameter's error (knee, band centre in rpm; of the first effect when
it is right); seconds per world (generation and discovery).

{markdown_table(t, "{}")}

Every world:

{markdown_table(df[cols], "{:.3g}", nan="")}
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("config")
    ap.add_argument("--fresh", action="store_true", help="the fresh seeds (default: the tuning seeds)")
    ap.add_argument("--only", default="", help="comma-separated world names")
    ap.add_argument("--out", default=None, help="default runs/world-benchmark/{tuning,fresh}")
    ap.add_argument("--lane", choices=("db1", "simulation"), default="db1",
                    help="the baseline: db1's nets, or the world's own law drawn wrong as a simulation column")
    ap.add_argument("--docs", action="store_true", help="write the table into research/discovery-benchmark.md")
    args = ap.parse_args()
    if args.docs and not args.fresh:
        raise SystemExit("--docs reports the fresh seeds only (--fresh)")
    if args.docs and args.lane != "db1":
        raise SystemExit("--docs reports the db1 lane's table")
    enable_compilation_cache()
    plan = bw.load_plan(args.config)
    worlds = bw.worlds(plan, args.fresh)
    if args.only:
        keep = set(args.only.split(","))
        worlds = [w for w in worlds if w["name"] in keep]
    out = Path(args.out or ROOT / "runs" / "world-benchmark" / ("fresh" if args.fresh else "tuning"))
    out.mkdir(parents=True, exist_ok=True)
    prov = _provenance(out)
    path = out / "rows.csv"
    rows = pd.read_csv(path, keep_default_na=False) if path.exists() else pd.DataFrame()
    done = set(rows.world) if len(rows) else set()
    for i, w in enumerate(worlds):
        if w["name"] in done:
            continue
        row = run_world(w, out, lane=args.lane)
        rows = pd.concat([rows, pd.DataFrame([row])], ignore_index=True)
        rows.to_csv(path, index=False)
        print(f"[{i + 1}/{len(worlds)}] {w['name']}: named {row['named']}; {row['seconds']:.0f} s", flush=True)
    rows = rows[rows.world.isin([w["name"] for w in worlds])]
    df = score(rows, worlds)
    df.to_csv(out / "scored.csv", index=False)
    t = table(df)
    print(t.to_string(index=False))
    if args.docs:
        target = ROOT / "research" / "discovery-benchmark.md"
        target.write_text(docs(t, df, prov, args.config))
        print(f"wrote {target}")


if __name__ == "__main__":
    main()
