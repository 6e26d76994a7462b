"""The oracle beside each drawn world, and the benchmark's table against the truth.

For every discrepancy of a world's truth (`world_truth.discrepancies`), the oracle tests the
discrepancy's own feature, told its form and parameters: the window means of what it adds to
the world (the law minus the law with it switched off, on the measured windows), against the
baseline's out-of-fold residual on those windows (measured − `predicted_before_g`, the
windows `world_benchmark.run_world` kept). A missing input or a response is tested beyond any
function of db1's inputs (`pvvjax.discovery.gcm_test`, cross-fitted trees, conditions as the
units, at 5 %); a misfit (a function of db1's inputs: the rotor-speed resonance, a planted
band) by whether the residual covaries with its form at all. A single test told the answer:
its detection is the ceiling a search over candidates can reach.

    python research/world_oracle.py research/configs/worlds.toml --fresh --out runs/world-benchmark/fresh-9200 [--docs]

reads the runner's rows, truth files and windows, adds OUT/oracle.csv (resumes: a world
there is not tested again) and prints (with --docs writes research/discovery-benchmark.md)
the tables: per family and per size bin (the planted effect's size where it acts over the
floor), the oracle's detection beside discovery's, each rate with its Monte Carlo standard
error; the nulls' false naming against the truth; each world's baseline, model after
discovery and floor.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one process, the trees on one thread (see tests/conftest.py)

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from pvvjax.analysis import DB_INPUTS  # noqa: E402
from pvvjax.discovery import (  # noqa: E402
    capacity_test,
    from_key,
    partial_out,
    regression_tests,
    static_inputs,
    unit_folds,
)
from pvvjax.io import markdown_table  # noqa: E402
from pvvjax.synth import law_amplitudes  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _research(name: str):
    """A script of research/ as a module (research/ is not a package)."""
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / "research" / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
    return sys.modules[name]


wb = _research("world_benchmark")
bw, wt, matches = wb.bw, wb.wt, wb.matches

LEVEL = 0.05
BINS = [0.0, 0.5, 1.0, 2.0, 4.0, np.inf]
BIN_NAMES = ["< 0.5", "0.5-1", "1-2", "2-4", "> 4"]
# What a named effect must be to match a base term of the truth (operator[:channel], as a
# family's `accept`).
BASE_ACCEPT = {
    "measured load factor": ["input:nz_g", "abs:nz_g", "threshold:nz_g", "rate:nz_g", "abs_rate:nz_g"],
    "0.6 s lag": ["lag"],
    "pitch rate": ["input:pitch_rate_dps", "abs:pitch_rate_dps", "threshold:pitch_rate_dps"],
    "roll rate": ["input:roll_rate_dps", "abs:roll_rate_dps", "threshold:roll_rate_dps"],
    "rotor-speed resonance": ["resonance:rotor_rpm"],
}


def _window_means(t, v, a, b):
    """Means of the samples `v` (at times `t`) in each window [a, b)."""
    return wt._means(v, np.searchsorted(t, a), np.searchsorted(t, b))


def features(world: dict, truth: dict, win: pd.DataFrame, offset_s: float) -> dict[str, np.ndarray]:
    """Per discrepancy of the truth: what it adds to the world, as window means over the
    measured windows of `win` (its input windows `t0`, `t1` shifted by the offset)."""
    cfg = world["synth"]
    specs = {}
    for e in truth["entries"]:
        if e["kind"] == "all":
            continue
        if e["source"] == "base":
            specs[e["name"]] = wt._switched(cfg, wt.BASE_TERMS[e["name"]]["switch"])
        else:
            specs[e["name"]] = wt._off(cfg, e["name"])
    law = law_amplitudes(cfg, {"law": cfg, **specs})
    out = {n: np.zeros(len(win)) for n in specs}
    for counter, rows in win.groupby("counter", sort=False).indices.items():
        rec = law[counter]
        t = rec.time_s.to_numpy()
        a = win.t0.to_numpy()[rows] + offset_s
        b = win.t1.to_numpy()[rows] + offset_s
        for n in specs:
            out[n][rows] = _window_means(t, (rec.law - rec[n]).to_numpy(), a, b)
    return out


def oracle(world: dict, truth: dict, win: pd.DataFrame, offset_s: float, seed: int = 0) -> list[dict]:
    """The oracle's test of each discrepancy of a world, and the baseline's capacity test
    (is its out-of-fold residual predictable from db1's inputs at all): rows of name, kind,
    statistic, p_value, theta, detected (at `LEVEL`). The test is `pvvjax.discovery.explain`'s
    told the answer, with its learners: the residual and each feature partialled out of the
    inputs and their composites (`static_inputs`) by the best out of fold of the mean, the
    additive spline and the trees (`partial_out`), the partially linear regression's t over
    conditions; a misfit (a function of the inputs) by its form alone. Discovery's missing
    kind also holds the inputs' history fixed, which the oracle does not: it stays the
    ceiling."""
    win = win[win.weight >= 0.999].reset_index(drop=True)  # the fully weighted windows, as the metrics
    y = (win.measured_g - win.predicted_before_g).to_numpy()
    inputs = list(DB_INPUTS["db1"])
    Z = static_inputs(win[inputs].rename(columns=lambda k: f"x:{k}"), inputs)
    groups = win.condition.astype(str).to_numpy()
    fold = unit_folds(groups, 5, seed)
    feats = features(world, truth, win, offset_s)
    entries = [e for e in truth["entries"] if e["name"] in feats and np.ptp(feats[e["name"]]) > 0]
    rows = []
    missing = [e for e in entries if e["kind"] != "misfit"]
    if missing:
        X = np.column_stack([feats[e["name"]] for e in missing])
        ry = partial_out(y, Z, fold, trees=True).left[:, 0]
        theta, t, p = regression_tests(ry, partial_out(X, Z, fold, trees=True).left, groups)
        rows += [_row(world, e, t[j], p[j], theta[j]) for j, e in enumerate(missing)]
    misfits = [e for e in entries if e["kind"] == "misfit"]
    if misfits:
        X = np.column_stack([feats[e["name"]] for e in misfits])
        theta, t, p = regression_tests(y - y.mean(), X - X.mean(axis=0), groups)
        rows += [_row(world, e, t[j], p[j], theta[j]) for j, e in enumerate(misfits)]
    rows += [_row(world, e, np.nan, 1.0, np.nan) for e in truth["entries"]
             if e["kind"] != "all" and e not in entries]
    cap = capacity_test(y, Z, groups, seed=seed)
    rows.append(dict(world=world["name"], name="capacity", source="baseline", kind="capacity", against_noise=np.nan,
                     rms_g=np.nan, statistic=cap.statistic, p_value=cap.p_value, theta=np.nan))
    for r in rows:
        r["detected"] = r["p_value"] < LEVEL
    return rows


def _row(world, e, t, p, theta) -> dict:
    return dict(world=world["name"], name=e["name"], source=e["source"], kind=e["kind"],
                against_noise=e["against_noise"], rms_g=e["rms_g"], statistic=float(t), p_value=float(p),
                theta=float(theta))


def _rate(k, n) -> str:
    if not n:
        return ""
    p = k / n
    return f"{int(k)} / {int(n)} ({100 * p:.0f} ± {100 * np.sqrt(p * (1 - p) / n):.0f} %)"


def _forms(e: dict) -> list[dict]:
    """A named effect and the candidates of its tied set (keys), each as operator and channels."""
    tied = [from_key(k) for k in e.get("tied", [])]
    return [e] + [dict(operator=c.operator, channels=list(c.channels)) for c in tied]


def _names(e: dict, accept, capacity: bool = False) -> bool:
    """Whether a named effect (or a candidate of its tied set) is one of the accepted forms;
    a misfit is right wherever the baseline's residual is predictable from its inputs at all
    (the capacity test: what a misfit names is the baseline's, not the world's)."""
    return (e.get("kind") == "misfit" and capacity) or any(matches(f, accept) for f in _forms(e))


def judged(rows: pd.DataFrame, orc: pd.DataFrame, worlds: list[dict], truths: dict, plan) -> pd.DataFrame:
    """One row per world: its planted entry (the first family's), its size against the floor,
    the oracle's and discovery's detection of it, and the naming against the whole truth."""
    by = {w["name"]: w for w in worlds}
    effect_of = {f.name: f.planted.effect for f in plan.family}
    out = []
    for r in rows.to_dict("records"):
        w, effects = by[r["world"]], json.loads(r["effects"])
        truth = truths[r["world"]]
        accepts = dict(BASE_ACCEPT)
        fam = w["truth"]
        planted = None
        if fam:
            planted = next((e for e in truth["entries"] if e["source"] == "planted"
                            and e["name"] == effect_of[fam["effect"]]), None)
            accepts[effect_of[fam["effect"]]] = fam["accept"]
            if "also" in fam:
                accepts[effect_of[fam["also"]["effect"]]] = fam["also"]["accept"]
        o = orc[orc.world == r["world"]].set_index("name")
        capacity = "capacity" in o.index and bool(o.loc["capacity", "detected"])
        in_truth = [any(_names(e, a, capacity) for a in accepts.values()) for e in effects]
        # First: the first effect named as missing (the misfit's forms are named before any).
        first = next((e for e in effects if e.get("kind") != "misfit"), None)
        # The largest entry the oracle detects: is it what discovery names first?
        seen = [e for e in truth["entries"] if e["name"] in o.index and bool(o.loc[e["name"], "detected"])
                and e["name"] in accepts]
        largest = max(seen, key=lambda e: e["rms_g"]) if seen else None
        row = dict(world=r["world"], family=r["family"], aircraft=r["aircraft"], conditions=r["conditions"],
                   named=r["named"], named_count=len(effects), false_named=int(len(effects) - sum(in_truth)),
                   base_named=int(sum(any(_names(e, a) for e in effects) for a in BASE_ACCEPT.values())),
                   set_sizes=json.dumps([1 + len(e.get("tied", [])) for e in effects]),
                   capacity_p=float(o.loc["capacity", "p_value"]) if "capacity" in o.index else np.nan,
                   named_in_truth=int(sum(in_truth)),
                   largest_first=(np.nan if largest is None else
                                  first is not None and _names(first, accepts[largest["name"]])),
                   floor_g=r["floor_g"], before_g=r["ensemble_rms_g_before"], after_g=r["ensemble_rms_g_after"],
                   seconds=r["seconds"])
        if planted is not None:
            row.update(size=planted["against_noise"], size_mg=1e3 * planted["where_acts_g"],
                       oracle=bool(o.loc[planted["name"], "detected"]) if planted["name"] in o.index else np.nan,
                       discovered=any(_names(e, fam["accept"]) for e in effects),
                       first=first is not None and _names(first, fam["accept"]))
        out.append(row)
    df = pd.DataFrame(out)
    if "size" in df:
        df["bin"] = pd.cut(df["size"], BINS, labels=BIN_NAMES, right=False)
    return df


def with_scores(df: pd.DataFrame, rows: pd.DataFrame, worlds: list[dict]) -> pd.DataFrame:
    """`judged` with the runner's own scores of each world (`world_benchmark.score`): the
    attributable shrink and the parameter's error of a right first effect."""
    s = wb.score(rows, worlds)[["world", "attributable", "parameter_error"]]
    return df.merge(s, on="world", how="left")


def tables(df: pd.DataFrame, orc: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The report's tables: detection per size bin and per family (oracle beside discovery),
    the nulls, the base terms' detection by the oracle."""
    hidden = df[df.family != "none"]
    nulls = df[df.family == "none"]

    def line(name, g):
        att = g["attributable"].dropna() if "attributable" in g else pd.Series(dtype=float)
        err = g["parameter_error"].dropna() if "parameter_error" in g else pd.Series(dtype=float)
        return {"": name, "worlds": len(g), "oracle detects": _rate(g.oracle.sum(), g.oracle.notna().sum()),
                "discovery names it": _rate(g.discovered.sum(), len(g)), "named first": _rate(g.first.sum(), len(g)),
                "names something not in the truth": _rate((g.false_named > 0).sum(), len(g)),
                "median size / floor": f"{g['size'].median():.2f}",
                "attributable ≥ 0.5": _rate((att >= 0.5).sum(), len(att)),
                "median parameter error": f"{err.median():.1%}" if len(err) else "",
                "median seconds": f"{g.seconds.median():.0f}"}

    by_bin = pd.DataFrame([line(b, hidden[hidden.bin == b]) for b in BIN_NAMES if (hidden.bin == b).any()]
                          + [line("all", hidden)])
    by_family = pd.DataFrame([line(f, hidden[hidden.family == f]) for f in sorted(hidden.family.unique())])
    null = pd.DataFrame([{"worlds": len(nulls), "name anything": _rate((nulls.named_count > 0).sum(), len(nulls)),
                          "name something not in the truth": _rate((nulls.false_named > 0).sum(), len(nulls)),
                          "name a base term": _rate((nulls.base_named > 0).sum(), len(nulls)),
                          "baseline's residual predictable from its inputs (capacity, 5 %)":
                              _rate((nulls.capacity_p < LEVEL).sum(), len(nulls))}])
    largest = df.largest_first.dropna()
    sizes = [n for v in df.get("set_sizes", pd.Series(dtype=str)) for n in json.loads(v)]
    overall = pd.DataFrame([{"named effects": int(df.named_count.sum()),
                             "precision (named effects in the truth)": _rate(df.named_in_truth.sum(),
                                                                             df.named_count.sum()),
                             "the largest entry the oracle detects named first": _rate(largest.sum(), len(largest)),
                             "median named set size": f"{np.median(sizes):.0f}" if len(sizes) else "",
                             "median seconds per world": f"{df.seconds.median():.0f}"}])
    base = orc[orc.source == "base"]
    terms = pd.DataFrame([{"term": n, "worlds": len(g), "median size / floor": f"{g.against_noise.median():.2f}",
                           "median size (mg)": f"{1e3 * g.rms_g.median():.1f}",
                           "oracle detects": _rate(g.detected.sum(), len(g))}
                          for n, g in base.groupby("name", sort=False)])
    return dict(by_bin=by_bin, by_family=by_family, nulls=null, overall=overall, base_terms=terms)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("config")
    ap.add_argument("--fresh", action="store_true")
    ap.add_argument("--out", required=True, action="append",
                    help="the runner's folder (rows.csv, truth/, windows/); again for a run of the same commit's "
                         "worlds in another folder (processes side by side)")
    ap.add_argument("--docs", action="store_true", help="write research/discovery-benchmark.md (fresh seeds only)")
    args = ap.parse_args()
    outs = [Path(o) for o in args.out]
    provs = [json.loads((o / "provenance.json").read_text()) for o in outs]
    if len({p["commit"] for p in provs}) > 1:
        raise SystemExit(f"--out folders of different commits: {[p['commit'] for p in provs]}")
    plan = bw.load_plan(args.config)
    worlds = bw.worlds(plan, args.fresh)
    by = {w["name"]: w for w in worlds}
    rows, orcs, truths = [], [], {}
    for out in outs:
        r = pd.read_csv(out / "rows.csv", keep_default_na=False)
        r = r[r.world.isin(list(by))]
        truths.update({n: json.loads((out / "truth" / f"{n}.truth.json").read_text())["discrepancies"]
                       for n in r.world})
        orcs.append(_oracle_of(out, r, by, truths))
        rows.append(r)
    rows = pd.concat(rows, ignore_index=True).drop_duplicates("world")
    orc = pd.concat(orcs, ignore_index=True).drop_duplicates(["world", "name"])
    df = with_scores(judged(rows, orc, worlds, truths, plan), rows, worlds)
    df.to_csv(outs[0] / "judged.csv", index=False)
    t = tables(df, orc)
    for name, tab in t.items():
        print(f"\n{name}\n{tab.to_string(index=False)}")
    if args.docs:
        target = ROOT / "research" / "discovery-benchmark.md"
        target.write_text(docs(t, df, provs[0], args.config, len(worlds), [str(o) for o in outs]))
        print(f"wrote {target}")


def _oracle_of(out: Path, rows: pd.DataFrame, by: dict, truths: dict) -> pd.DataFrame:
    """The oracle's rows of a runner's folder (OUT/oracle.csv), the worlds not yet tested
    tested first."""
    path = out / "oracle.csv"
    orc = pd.read_csv(path) if path.exists() else pd.DataFrame()
    done = set(orc.world) if len(orc) else set()
    for i, r in enumerate(rows.itertuples()):
        if r.world in done:
            continue
        win = pd.read_parquet(out / "windows" / f"{r.world}.parquet")
        new = pd.DataFrame(oracle(by[r.world], truths[r.world], win, r.offset_s))
        orc = pd.concat([orc, new], ignore_index=True)
        orc.to_csv(path, index=False)
        print(f"[{i + 1}/{len(rows)}] {r.world}: " + ", ".join(f"{n} p={p:.3g}" for n, p in zip(new.name, new.p_value)),
              flush=True)
    return orc


def docs(t: dict, df: pd.DataFrame, prov: dict, config: str, planned: int, outs=("runs/world-benchmark/fresh",)) -> str:
    cols = ["world", "aircraft", "conditions", "named", "size", "oracle", "discovered", "false_named", "capacity_p",
            "attributable", "parameter_error", "before_g", "after_g", "floor_g", "seconds"]
    return f"""# Discovery: the drawn-world benchmark against the truth

Commands: `python research/world_benchmark.py {config} --fresh --only ... --out OUT` (discovery, run once
at {prov['commit']} from {prov['date']}, in processes of that commit side by side, each on a part of the
worlds with its own OUT: {', '.join(f'`{o}`' for o in outs)}; {len(df)} of {planned} worlds), then
`python research/world_oracle.py {config} --fresh {' '.join(f'--out {o}' for o in outs)} --docs`
(the oracle and the scores). The machine: the 2-core VM ({prov['machine']}).

Each world's truth (`research/world_truth.py`) lists every discrepancy against db1, sized by
switching it off in the generator: the planted effect, and the base's own terms db1's inputs
cannot carry (the measured load factor, the 0.6 s lag, the pitch- and roll-rate terms; the
rotor-speed resonance as a possible misfit of rotor speed). A size is the RMS where it acts
over the world's floor (the noise-free, scatter-free world scored as a model). The oracle
(`research/world_oracle.py`) tests each discrepancy's own feature on the baseline's
out-of-fold residual, conditions as the units, at 5 %: the ceiling of any search. A named
effect is "in the truth" if it matches a planted family's accepted forms or a base term.
Rates carry their Monte Carlo standard error.

## Planted effects by size (size where it acts / floor)

{markdown_table(t['by_bin'], "{}")}

## By family

{markdown_table(t['by_family'], "{}")}

## Null worlds

{markdown_table(t['nulls'], "{}")}

## Every world's naming against its truth

{markdown_table(t['overall'], "{}")}

## The base's own terms, by the oracle (every world)

{markdown_table(t['base_terms'], "{}")}

## Every world: baseline, after discovery and floor (ensemble held-out RMS, g)

{markdown_table(df[[c for c in cols if c in df]], "{:.3g}", nan="")}
"""


if __name__ == "__main__":
    main()
