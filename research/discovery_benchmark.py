"""Hidden-effect benchmark of the discovery workflow.

Each scenario generates a synthetic campaign (the base physics of the benchmark config plus
the scenario's effect, or nothing for a null scenario), runs `pvvjax.discovery.discover`
on it, which never sees the generator's settings, and scores the outcome against the truth:
the effect ranked first, its fitted parameter, and the attributable shrink
(before − after) / (before − before of the null scenario with the same seed; for an input
taken away from the model, before on the same campaign generated without the input's
effect: the scenario's `reference_world`).

    python research/discovery_benchmark.py research/configs/benchmark.toml [--only a,b] [--docs]
        [--seed-offsets 0,1]   # and again with every seed shifted by 1 (a replication)
        [--set KEY=VALUE ...]  # [discovery] settings over the config's (a sensitivity run)
        [--reuse]              # read OUT's results instead of running (--docs after parallel runs)
        [--update]             # run the --only scenarios into OUT's results, the other rows kept
        [--resume]             # go on with an interrupted run: its finished scenarios read back

Writes runs/discovery-benchmark/ (results table, each scenario's discovery.json and
report; seed offset N in runs/discovery-benchmark/seed+N/); with --docs also
research/discovery-benchmark-fixed.md.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

from pvvjax.config import DiscoveryConfig, ExperimentConfig, config_hash, from_dict, load_toml, to_dict
from pvvjax.data.campaign import campaign_from_frames
from pvvjax.discovery import discover, selection_gain, summary
from pvvjax.discovery.report import write_discovery
from pvvjax.io import markdown_table, read_table, write_table
from pvvjax.synth import SynthConfig, generate

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]


def scenario_configs(path, seed_offset: int = 0) -> tuple[list[dict], dict]:
    """Scenarios of a benchmark config, each with its `SynthConfig` (seeds shifted by
    `seed_offset`, for a replication on other worlds); and the discovery overrides."""
    raw = load_toml(path)
    base = dict(raw.get("base", {}))
    base_effects = base.pop("effects", {})
    out = []
    for sc in raw["scenario"]:
        effects = {k: dict(v) for k, v in base_effects.items()}
        for k, v in sc.get("effects", {}).items():
            effects[k] = {**effects.get(k, {}), **v}
        seed = sc["seed"] + seed_offset
        synth = from_dict(SynthConfig, {**base, "name": f"bench-{sc['name']}", "seed": seed, "effects": effects})
        world = sc.get("reference_world")
        reference = (from_dict(SynthConfig, {**to_dict(synth), "name": f"{synth.name}-reference", **world})
                     if world else None)
        out.append(dict(name=sc["name"], seed=seed, database=sc.get("database", "db1"), truth=sc.get("truth"),
                        synth=synth, reference_world=reference,
                        reference_label=", ".join(f"{k} = {v:g}" for k, v in (world or {}).items())))
    # A lag scenario's gap is measured by its null's window nets (the lag test's reference,
    # `attributable`), which discover trains only where it confirms a lag unless told to.
    lagged = {s["seed"] for s in out if s["truth"] and "lag" in s["truth"]["accept"]}
    for s in out:
        s["lag_trials"] = s["truth"] is None and s["seed"] in lagged
    return out, raw.get("discovery", {})


def matches(effect: dict, accept) -> bool:
    """Whether a named effect is one of the accepted operator[:channel] forms."""
    for a in accept:
        op, _, ch = a.partition(":")
        if effect["operator"] == op and (not ch or ch in effect["channels"]):
            return True
    return False


def find_scenario(path, seed_offset: int, name: str) -> tuple[dict, dict]:
    """The scenario `name` of the config at `path`, its seed shifted by `seed_offset`, and the
    config's [discovery] overrides (`scenario_configs`); an unknown name exits naming them."""
    scs, overrides = scenario_configs(path, seed_offset)
    sc = next((s for s in scs if s["name"] == name), None)
    if sc is None:
        raise SystemExit(f"unknown scenario {name!r}; one of {', '.join(s['name'] for s in scs)}")
    return sc, overrides


def scenario_config(sc: dict, overrides: dict) -> ExperimentConfig:
    """The config a scenario's discovery runs with (stored beside its results)."""
    dcfg = from_dict(DiscoveryConfig, {**overrides, "database": sc["database"]})
    return ExperimentConfig(name=sc["name"], discovery=dcfg)


def run_scenario(sc: dict, overrides: dict, out: Path, log=print):
    t0 = time.perf_counter()
    campaign = _campaign(sc["synth"])
    t_gen = time.perf_counter() - t0
    cfg = scenario_config(sc, overrides)
    res = discover(campaign, cfg, name=sc["synth"].name, log=lambda m: log(f"  [{sc['name']}] {m}"),
                   lag_trials=sc.get("lag_trials", False))
    seconds = time.perf_counter() - t0
    js = summary(res)
    folder = out / sc["name"]
    write_discovery(res, folder, cfg)  # discovery.json, report.md, figures, tables
    truth = sc["truth"] or {}
    first = js["effects"][0] if js["effects"] else None
    row = dict(scenario=sc["name"], seed=sc["seed"], database=sc["database"], hidden=truth.get("effect", "none"),
               named=" > ".join(e["name"] for e in js["effects"]) or "none",
               operator=first["operator"] if first else "", channels=",".join(first["channels"]) if first else "",
               rms_before_g=res.before["rms_g"], rms_after_g=res.after["rms_g"],
               ensemble_before_g=res.before["ensemble_rms_g"], ensemble_after_g=res.after["ensemble_rms_g"],
               offset_s=res.baseline.offset_s, lag_baseline=res.baseline.through_lag, generate_s=t_gen,
               seconds=seconds)
    if truth:
        row["correct_first"] = bool(first and matches(first, truth["accept"]))
        # The truth among the first round's confirmed tries (named or not; round 0 is the lag test).
        tries = res.tries[(res.tries["round"] <= 1) & res.tries.confirmed] if len(res.tries) else res.tries
        row["truth_confirmed"] = any(matches(dict(operator=t.operator, channels=t.channels.split(",")), truth["accept"])
                                     for t in tries.itertuples())
        if "parameter" in truth and first and row["correct_first"]:
            row["parameter"] = truth["parameter"]
            row["true_value"] = float(truth["value"])
            row["fitted_value"] = float(first["parameters"].get(truth["parameter"], np.nan))
    else:
        row["correct_first"] = not js["effects"]
    # The ensemble's (median) prediction is what the confirmation measures and the report plots;
    # the median of the seeds' own RMS carries each net's retraining noise (a few percent).
    row["gap_metric"] = truth.get("gap_metric", "ensemble_rms_g")
    row["region"] = first["region"]["where"] if first else ""
    row["phase_before_s"], row["phase_after_s"] = res.before["phase_error_s"], res.after["phase_error_s"]
    row["peak_before_g"], row["peak_after_g"] = res.before["peak_error_g"], res.after["peak_error_g"]
    if row["region"]:
        kinds = row["region"].split(", ")
        row["region_before_g"] = _rms_in(res, kinds, "predicted_before_g")
        row["region_after_g"] = _rms_in(res, kinds, "predicted_after_g")
    ref = None
    if sc["reference_world"] is not None:
        ref = reference_baseline(sc, overrides, log)
        _save_reference(ref, folder / "reference")
        row["reference"] = sc["reference_label"]
    return row, res, ref


def _campaign(synth: SynthConfig):
    """A generated campaign; the generator's truth stays here, never passed on."""
    counters, records, _truth = generate(synth)
    return campaign_from_frames(counters, records, source=synth.name)


def reference_baseline(sc: dict, overrides: dict, log=print):
    """The scenario's model on its `reference_world`, for an input taken away from the model:
    the same campaign (seed, conditions, flight) generated without the input's effect on the
    vibration (weight: `vibration_weight_lb` fixed), so that the model misses nothing the
    input carries. The null world of the seed is the scenario's own world, and a database
    that has the input is another model: db2 (db3 plus the weight) was no better than db3
    on two of three worlds, since nets on ~200 peaks do not learn the weight's knee from one
    more input. Discovery with no rounds trains, calibrates and replays the baseline alone."""
    campaign = _campaign(sc["reference_world"])
    dcfg = from_dict(DiscoveryConfig, {**overrides, "database": sc["database"], "max_effects": 0})
    tag = f"{sc['name']}, {sc['reference_label']}"
    return discover(campaign, ExperimentConfig(name=tag, discovery=dcfg), name=sc["reference_world"].name,
                    log=lambda m: log(f"  [{tag}] {m}"))


def _save_reference(ref, folder: Path) -> None:
    """A reference baseline's report and what scoring needs of it (`_load_reference`)."""
    write_discovery(ref, folder)
    before = {k: float(ref.before[k]) for k in _GAP_COLUMNS}
    (folder / "before.json").write_text(json.dumps(dict(before=before, through_lag=bool(ref.baseline.through_lag))))


def _scored(before: dict, through_lag: bool, folder: Path) -> SimpleNamespace:
    """What the scoring (`attributable`, `identifiability`) reads of a finished discovery,
    from its folder: its baseline's metrics and kind, its lag test's table and its windows."""
    lag = folder / "lag_test.csv"
    return SimpleNamespace(before=before, baseline=SimpleNamespace(through_lag=bool(through_lag)),
                           lag_test=pd.read_csv(lag) if lag.exists() else None,
                           windows=read_table(folder / "windows.parquet")[0])


def _load_reference(folder: Path):
    """A reference baseline saved by `_save_reference`, or None."""
    if not (folder / "before.json").exists():
        return None
    saved = json.loads((folder / "before.json").read_text())
    return _scored(saved["before"], saved["through_lag"], folder)


# partial.csv's text columns (empty cells are read back as NaN).
_TEXT = ("named", "operator", "channels", "region", "reference", "parameter")


def resumed(scenarios, overrides: dict, out: Path, log=print) -> dict:
    """The scenarios an interrupted run in `out` finished (its `partial.csv`), by name: their
    row, what the scoring reads of their result (`_scored`) and their reference baseline
    (re-run if it was not saved). An error where a scenario's folder was run with other
    settings than these (rows of two settings would be compared as one)."""
    path = out / "partial.csv"
    if not path.exists():
        return {}
    df = pd.read_csv(path)
    for c in _TEXT:
        if c in df:
            df[c] = df[c].astype(object).where(df[c].notna(), "").astype(str)
    by = {(s["name"], s["seed"]): s for s in scenarios}
    done = {}
    for row in df.to_dict("records"):
        sc = by.get((row["scenario"], row["seed"]))
        if sc is None:
            continue
        folder = out / sc["name"]
        _, stored = read_table(folder / "windows.parquet")
        if config_hash(stored) != config_hash(scenario_config(sc, overrides)):
            raise SystemExit(f"--resume: {folder} was run with other settings: {(stored or {}).get('discovery')} "
                             f"against {to_dict(scenario_config(sc, overrides).discovery)}")
        before = {k: row[cols[0]] for k, cols in _GAP_COLUMNS.items()}  # the gap metrics the scoring reads
        ref = None
        if sc["reference_world"] is not None:
            ref = _load_reference(folder / "reference")
            if ref is None:  # a run before references were saved
                ref = reference_baseline(sc, overrides, log)
                _save_reference(ref, folder / "reference")
        done[sc["name"]] = (row, _scored(before, row["lag_baseline"], folder), ref)
    return done


def _rms_in(res, kinds, column: str = "predicted_before_g") -> float:
    """Held-out RMS of a prediction column over the fully weighted windows of some maneuver kinds."""
    w = res.windows[(res.windows.weight >= 0.999) & res.windows.maneuver.isin(kinds)]
    return float(np.sqrt(np.mean((w.measured_g - w[column]) ** 2)))


def identifiability(res, null) -> dict:
    """Could the selection have named the hidden effect? The true effect per window (measured
    PVV minus the same window of the same-seed world without it: the null world, or the
    scenario's reference world) scored as a candidate by the first round's selection
    (`selection_gain`: same residual, floor and folds), beside the candidate it named; and
    the share of the true effect the baseline already predicts (least-squares slope of its
    prediction's change on the true effect): an effect of the model's own inputs is learned
    from the peaks, and only its remainder is left to name."""
    w = res.windows[["counter", "window", "measured_g", "predicted_before_g", "weight"]].merge(
        null.windows[["counter", "window", "measured_g", "predicted_before_g"]], on=["counter", "window"], how="left",
        suffixes=("", "_null"))
    effect = (w.measured_g - w.measured_g_null).to_numpy()
    full = (w.weight >= 0.999).to_numpy() & np.isfinite(effect)
    out = dict(effect_rms_g=np.nan, truth_gain=np.nan, learned_share=np.nan, named_gain=np.nan)
    if res.effects and res.residual is not None and res.effects[0].operator != "lag":
        out["named_gain"] = selection_gain(res, res.windows["effect_1"])
    if not np.any(np.abs(effect[full]) > 1e-6) or res.residual is None:  # same world (a model input taken away)
        return out
    if res.baseline.through_lag != null.baseline.through_lag:  # baselines of another kind: no learned share
        return out | dict(effect_rms_g=float(np.sqrt(np.mean(effect[full] ** 2))))
    e = np.where(np.isfinite(effect), effect, 0.0)
    learned = (w.predicted_before_g - w.predicted_before_g_null).to_numpy()
    ec = e[full] - e[full].mean()
    out.update(effect_rms_g=float(np.sqrt(np.mean(e[full] ** 2))), truth_gain=selection_gain(res, e),
               learned_share=float(ec @ (learned[full] - learned[full].mean()) / (ec @ ec)))
    return out


# A scenario's gap metric: its before and after columns.
_GAP_COLUMNS = {"ensemble_rms_g": ("ensemble_before_g", "ensemble_after_g"), "rms_g": ("rms_before_g", "rms_after_g"),
                "phase_error_s": ("phase_before_s", "phase_after_s"), "peak_error_g": ("peak_before_g", "peak_after_g")}


def _closed(before: float, after: float, reference: float) -> float:
    """The share of the gap before − reference that after closes; NaN without a gap."""
    return (before - after) / (before - reference) if before - reference > 0 else np.nan


def attributable(df: pd.DataFrame, nulls: dict, references: dict | None = None) -> pd.DataFrame:
    """(before − after) / (before − before of the same seed's null scenario, or of the
    scenario's own reference baseline where `references` holds one by scenario name): over
    all windows on the ensemble's RMS and on the seeds' median RMS, in the named effect's
    region (ensemble), and on the scenario's gap metric (`truth.gap_metric`, default the
    ensemble's RMS: a lag lowers the RMS, since the smoothed vibration is easier to fit, and
    shows in the peaks instead)."""
    df = df.copy()
    references = references or {}
    for col in ("rms_null_g", "ensemble_null_g", "region_null_g", "attributable_rms", "attributable_ensemble",
                "attributable_region", "attributable_shrink"):
        df[col] = np.nan
    for i, r in df.iterrows():
        null = references.get(r.scenario, nulls.get(r.seed))
        if r.hidden == "none" or null is None:
            continue
        null_before, null_lagged = null.before, null.baseline.through_lag
        if r.lag_baseline != null_lagged:  # the null's nets of the scenario's kind, from its lag test's table
            if null.lag_test is None:
                continue
            t = null.lag_test
            ref = t[(t.role == "reference") & t.chosen] if r.lag_baseline else t[t.role == "baseline"]
            if not len(ref):  # a table written before the baseline row
                continue
            null_before = {k: float(ref.iloc[0][k]) for k in ("rms_g", "peak_error_g", "phase_error_s",
                                                              "ensemble_rms_g")}
        df.loc[i, "rms_null_g"] = null_before["rms_g"]
        df.loc[i, "attributable_rms"] = _closed(r.rms_before_g, r.rms_after_g, null_before["rms_g"])
        df.loc[i, "ensemble_null_g"] = null_before["ensemble_rms_g"]
        df.loc[i, "attributable_ensemble"] = _closed(r.ensemble_before_g, r.ensemble_after_g,
                                                     null_before["ensemble_rms_g"])
        if r.region and not r.lag_baseline and not null_lagged:
            ref = _rms_in(null, r.region.split(", "))
            df.loc[i, "region_null_g"] = ref
            df.loc[i, "attributable_region"] = _closed(r.region_before_g, r.region_after_g, ref)
        before, after = _GAP_COLUMNS[r.gap_metric]
        df.loc[i, "attributable_shrink"] = _closed(r[before], r[after], null_before[r.gap_metric])
    return df


def run_all(scenarios, overrides, out: Path, update: bool = False, resume: bool = False) -> pd.DataFrame:
    """Every scenario (the null ones first: they are the references of the hidden ones with
    the same seed, unless a scenario brings its own `reference_world`), scored; writes
    `out/results.*` and each scenario's folder, and `out/partial.csv` after each scenario.
    With `update`, the rows of these scenarios replace theirs in the results already in `out`
    (same discovery settings), the others kept. With `resume`, the scenarios that an
    interrupted run in `out` finished (`resumed`) are read back instead of run again."""
    cfg = ExperimentConfig(discovery=from_dict(DiscoveryConfig, overrides))
    old = _previous(out / "results.parquet", cfg) if update else None
    done = resumed(scenarios, overrides, out) if resume else {}
    out.mkdir(parents=True, exist_ok=True)
    rows, nulls, refs = [], {}, {}
    for sc in sorted(scenarios, key=lambda s: s["truth"] is not None):
        if sc["name"] in done:
            print(f"scenario {sc['name']} (seed {sc['seed']}, {sc['database']}): resumed from {out / 'partial.csv'}",
                  flush=True)
            r, res, ref = done[sc["name"]]
        else:
            print(f"scenario {sc['name']} (seed {sc['seed']}, {sc['database']})", flush=True)
            r, res, ref = run_scenario(sc, overrides, out)
            if sc["truth"] is not None and (ref is not None or sc["seed"] in nulls):
                r.update(identifiability(res, ref if ref is not None else nulls[sc["seed"]]))
        if ref is not None:
            refs[sc["name"]] = ref
        if sc["truth"] is None:
            nulls[sc["seed"]] = res
        rows.append(r)
        print(f"  named: {r['named']}; correct: {r['correct_first']}; RMS {r['rms_before_g']:.4f} -> "
              f"{r['rms_after_g']:.4f} g; {r['seconds']:.0f} s", flush=True)
        pd.DataFrame(rows).to_csv(out / "partial.csv", index=False)
    df = attributable(pd.DataFrame(rows), nulls, refs)
    if old is not None:
        df = merged(old, df)
    write_table(df, out / "results", cfg)
    print(df.drop(columns=["generate_s"]).to_string())
    print(f"results: {out / 'results.csv'}")
    return df


def _previous(path: Path, cfg) -> pd.DataFrame:
    """The results an update goes into; an error unless they exist and were run with the same
    discovery settings (rows of two settings in one table would be compared as one)."""
    if not path.exists():
        raise SystemExit(f"--update: no results to update at {path}")
    old, stored = read_table(path)
    if config_hash(stored) != config_hash(cfg):  # the hash of the stored config's content, as of cfg's
        raise SystemExit(f"--update: {path} was run with other settings: {(stored or {}).get('discovery')} "
                         f"against {to_dict(cfg).get('discovery')}")
    return old


def _check_update(scenarios):
    """An updated hidden scenario's gap is measured against the null scenario of its seed run
    beside it (unless it brings its own reference world): without it, its row would lose its
    attributable shrink."""
    nulls = {s["seed"] for s in scenarios if s["truth"] is None}
    missing = [f"{s['name']} (seed {s['seed']})" for s in scenarios
               if s["truth"] is not None and s["reference_world"] is None and s["seed"] not in nulls]
    if missing:
        raise SystemExit(f"--update: {', '.join(missing)} need the null scenario of their seed in --only")


def merged(old: pd.DataFrame, new: pd.DataFrame) -> pd.DataFrame:
    """`old`'s rows in their order, those of a scenario in `new` replaced by its row (a new
    scenario at the end); the columns of both."""
    order = {s: i for i, s in enumerate(old.scenario)}
    df = pd.concat([old[~old.scenario.isin(new.scenario)], new], ignore_index=True)
    rank = df.scenario.map(lambda v: order.get(v, len(order)))
    return df.iloc[np.argsort(rank.to_numpy(), kind="stable")].reset_index(drop=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("config")
    ap.add_argument("--only", default="", help="comma-separated scenario names")
    ap.add_argument("--out", default="runs/discovery-benchmark")
    ap.add_argument("--docs", action="store_true", help="also write research/discovery-benchmark-fixed.md")
    ap.add_argument("--exclude", nargs="+", default=[], metavar="CHANNEL",
                    help="channels left out of the candidates (added to [discovery] exclude_channels)")
    ap.add_argument("--set", nargs="+", action="extend", default=[], metavar="KEY=VALUE", dest="settings",
                    help="[discovery] settings over the config's (a TOML value; a bare word is a string), "
                         "e.g. --set selection.alpha=0.02: a sensitivity run (use another --out)")
    ap.add_argument("--seed-offsets", default="0",
                    help="comma-separated: the benchmark once per offset, every scenario's seed shifted by it (a "
                         "replication on other worlds; offset N writes to OUT/seed+N)")
    ap.add_argument("--reuse", action="store_true",
                    help="read each offset's results from OUT instead of running it (e.g. --docs after one process "
                         "per seed offset, side by side)")
    ap.add_argument("--resume", action="store_true",
                    help="go on with an interrupted run in OUT (same settings): the scenarios in its partial.csv "
                         "are read back, the others run")
    ap.add_argument("--update", action="store_true",
                    help="run the --only scenarios and put their rows into OUT's results (same settings), the other "
                         "rows kept: re-run one scenario without the whole table")
    args = ap.parse_args()
    if args.update and (args.reuse or not args.only):
        raise SystemExit("--update runs the --only scenarios into OUT's results (not with --reuse)")
    if args.resume and (args.update or args.reuse):
        raise SystemExit("--resume goes on with an interrupted run (not with --update or --reuse)")
    offsets = [int(v) for v in args.seed_offsets.split(",")]
    tables = {}
    for off in offsets:
        scenarios, overrides = scenario_configs(args.config, off)
        if args.exclude:
            overrides = {**overrides, "exclude_channels": [*overrides.get("exclude_channels", []), *args.exclude]}
        overrides = _merged(overrides, _settings(args.settings))
        if args.only:
            keep = set(args.only.split(","))
            scenarios = [s for s in scenarios if s["name"] in keep]
        out = Path(args.out) / (f"seed+{off}" if off else "")
        if args.update:
            _check_update(scenarios)
        if args.reuse:
            tables[off] = read_table(out / "results.parquet")[0]
            tables[off] = tables[off][tables[off].scenario.isin([s["name"] for s in scenarios])]
        else:
            tables[off] = run_all(scenarios, overrides, out, update=args.update, resume=args.resume)
    if args.docs:
        write_docs(tables, args.config, args.seed_offsets, remeasured(Path(args.out), offsets), args.settings)


def remeasured(out: Path, offsets) -> dict:
    """The re-measurements of experiments/attributable_ensemble.py in `out`
    (`[seed+N/]attributable_netsK.csv`): {nets per fold: {offset: rows}}. Those over several
    training draws (`..._drawsR.csv`) are another measurement, not read here."""
    found = {}
    for off in offsets:
        for path in sorted((out / (f"seed+{off}" if off else "")).glob("attributable_nets*.csv")):
            if (nets := path.stem.removeprefix("attributable_nets")).isdigit():
                found.setdefault(int(nets), {})[off] = pd.read_csv(path)
    return found


def remeasured_by_scenario(frames: dict) -> pd.DataFrame:
    """Each scenario's re-measured worlds (frames: {offset: attributable_ensemble.py's rows}):
    attributable ≥ 0.5, a gap measured and the median, with the table's own beside them (a
    world without a gap counts below 0.5; nothing named closes nothing). One row per
    scenario, then the total."""
    df = pd.concat(list(frames.values()), ignore_index=True)
    rows = []
    for name, g in [*df.groupby("scenario", sort=False), ("all", df)]:
        new, old = pd.to_numeric(g.attributable), pd.to_numeric(g.table_attributable)
        rows.append(dict(scenario=name, worlds=len(g),
                         at_least_half=f"{int((old >= 0.5).sum())} / {int((new >= 0.5).sum())}",
                         gap_measured=f"{int(old.notna().sum())} / {int(new.notna().sum())}",
                         median=f"{np.nanmedian(old):.2f} / {np.nanmedian(new):.2f}"))
    return pd.DataFrame(rows)


def _settings(items) -> dict:
    """KEY=VALUE strings as [discovery] overrides: VALUE read as TOML, else as a string; a
    dotted KEY (`selection.alpha`) sets a key of a section."""
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise SystemExit(f"--set: expected KEY=VALUE, got {item!r}")
        try:
            v = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            v = value
        *sections, leaf = key.split(".")
        for s in reversed(sections):
            v, leaf = {leaf: v}, s
        out = _merged(out, {leaf: v})
    return out


def _merged(a: dict, b: dict) -> dict:
    """`a` with `b`'s keys, sections merged key by key."""
    out = dict(a)
    for k, v in b.items():
        out[k] = _merged(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def _summary(df: pd.DataFrame) -> dict:
    hidden, nulls = df[df.hidden != "none"], df[df.hidden == "none"]
    return dict(right_first=f"{int(hidden.correct_first.sum())} / {len(hidden)}",
                truth_confirmed=f"{int(hidden.truth_confirmed.sum())} / {len(hidden)}",
                nulls_clean=f"{int(nulls.correct_first.sum())} / {len(nulls)}",
                attributable_median=float(np.nanmedian(hidden.attributable_shrink)),
                attributable_at_least_half=f"{int((hidden.attributable_shrink >= 0.5).sum())} / {len(hidden)}",
                seeds_rms_at_least_half=f"{int((_on_seeds_rms(hidden) >= 0.5).sum())} / {len(hidden)}",
                gap_measured=f"{int(hidden.attributable_shrink.notna().sum())} / {len(hidden)}",
                seconds=f"{df.seconds.min():.0f}-{df.seconds.max():.0f}")


def by_scenario(tables: dict) -> pd.DataFrame:
    """Each scenario over the seed offsets run: worlds, right first (nothing named, for a
    null), attributable ≥ 0.5, a gap measured, the median attributable shrink and the median
    seconds. tables: {offset: results}. Returns one row per scenario, in the config's order."""
    df = pd.concat(list(tables.values()), ignore_index=True)
    rows = []
    for name, g in df.groupby("scenario", sort=False):
        null = bool((g.hidden == "none").all())
        a = pd.to_numeric(g.attributable_shrink, errors="coerce")
        rows.append(dict(scenario=name, worlds=len(g),
                         right_first=f"{int(g.correct_first.eq(True).sum())} / {len(g)}",
                         attributable_at_least_half="" if null else f"{int((a >= 0.5).sum())} / {len(g)}",
                         gap_measured="" if null else f"{int(a.notna().sum())} / {len(g)}",
                         median_attributable=np.nan if null or a.isna().all() else float(np.nanmedian(a)),
                         median_seconds=int(round(float(np.median(pd.to_numeric(g.seconds)))))))
    return pd.DataFrame(rows)


def _on_seeds_rms(hidden: pd.DataFrame) -> pd.Series:
    """The attributable shrink with the seeds' median RMS in place of the ensemble's."""
    return hidden.attributable_shrink.where(hidden.gap_metric != "ensemble_rms_g", hidden.attributable_rms)


def _blank(t: pd.DataFrame) -> pd.DataFrame:
    """Missing values (a null scenario has no truth to confirm) as empty cells."""
    return t.astype(object).where(t.notna(), np.nan)


_SUMMARY_HEADER = ("| seeds | right first | truth confirmed | nulls clean | attributable ≥ 0.5 | gap measured "
                   "| median attributable | ≥ 0.5 on the seeds' RMS | seconds |\n"
                   "|---|---|---|---|---|---|---|---|---|\n")


# What of the benchmark `make test` runs (kept here so that --docs writes it with the table).
_FAST_SUBSET = """
## In `make test`

A fast subset runs in `make test`, on the benchmark's base world with lighter settings
(3 seeds, one round, offset step 0.25 s; no resonance probe):

| world (seed) | test | asserts |
|---|---|---|
| sideslip (41) | `notebooks/discovery.py` (`tests/test_notebooks.py`) | sideslip first; attributable ≥ 0.5 |
| null (51) | `test_cli_on_a_world_without_hidden_effects_names_nothing` | `pvvjax discover` names nothing |
| long lag, τ = 2 s (31) | `test_discover_names_a_long_lag_first_with_nets_trained_through_it` | the lag first |
| null (51) | `test_a_world_without_a_hidden_lag_gains_nothing_from_nets_trained_through_one` | a 2 s lag gains < 5 % |
| null (51) | the same test | nets trained on the windows: a lower floor than the peak nets |

The benchmark's own bookkeeping (attributable shrink against the seed's null or the
scenario's reference world, `--update`) is tested in `tests/test_benchmark.py`.
"""


def _remeasured_section(found: dict) -> str:
    """The docs' section on the re-measurements with more nets per fold (`remeasured`)."""
    text = ""
    for nets, frames in sorted(found.items()):
        df = pd.concat(list(frames.values()), ignore_index=True)
        new, old = pd.to_numeric(df.attributable), pd.to_numeric(df.table_attributable)
        flipped = df[(new >= 0.5) != (old >= 0.5)].copy()
        for c in ("attributable", "table_attributable"):  # four decimals, rounded down: 0.49999 is below 0.5
            flipped[c] = [f"{np.floor(v * 1e4) / 1e4:.4f}" if np.isfinite(v) else "" for v in pd.to_numeric(flipped[c])]
        per = remeasured_by_scenario(frames).rename(columns={
            "at_least_half": "attributable ≥ 0.5 (4 / %d nets)" % nets, "gap_measured": f"gap measured (4 / {nets})",
            "median": f"median attributable (4 / {nets})"})
        text += f"""
## The attributable shrink with {nets} nets per fold

Command: `python experiments/attributable_ensemble.py OUT --seed-offsets {",".join(map(str, sorted(frames)))} \\
--nets {nets}` (OUT: the table's `--out`; {len(df)} hidden worlds, {df.seconds.min():.0f}-{df.seconds.max():.0f} s
each). Each world's model is rebuilt from its folder as the
workflow built it (the peak nets and their offset, the lag test's chosen ensembles, then each
named effect the way its round added it) with {nets} nets per fold instead of 4, and so is the
baseline of its null world (or reference world): the names are the discovery's, the before,
after and null numbers new, with less training noise (with 4 nets the rebuild reproduces the
table to the digit). Over all worlds re-measured and by scenario, the table's value first:

{markdown_table(per, "{:.3g}", nan="")}
""" + (f"""
Worlds on the other side of 0.5 ({len(flipped)}):

{markdown_table(flipped[["scenario", "seed", "named", "gap_metric", "before", "after", "null", "attributable",
                         "table_attributable"]], "{:.3g}", nan="")}
""" if len(flipped) else "")
    return text


def write_docs(tables: dict, config: str, offsets: str, found: dict | None = None, settings=()):
    """research/discovery-benchmark-fixed.md from the offsets' tables; `settings`: the run's `--set`
    items, which its command line repeats."""
    tables = {off: _blank(t) for off, t in tables.items()}
    sets = "".join(f" --set {v}" for v in settings)
    df = tables[min(tables)]
    cols = ["scenario", "seed", "database", "hidden", "named", "correct_first", "truth_confirmed", "parameter",
            "true_value", "fitted_value", "reference", "ensemble_null_g", "ensemble_before_g", "ensemble_after_g",
            "rms_null_g", "rms_before_g", "rms_after_g", "region",
            "region_null_g", "region_before_g", "region_after_g", "peak_before_g", "peak_after_g", "phase_before_s",
            "phase_after_s", "gap_metric", "attributable_ensemble", "attributable_rms", "attributable_region",
            "attributable_shrink",
            "effect_rms_g", "learned_share", "truth_gain", "named_gain", "seconds"]
    cols = [c for c in cols if c in df.columns]
    summaries = {off: _summary(t) for off, t in tables.items()}
    s = summaries[min(tables)]
    summary = pd.DataFrame([dict(seeds=f"config + {off}", **v) for off, v in summaries.items()])
    reps = {off: t for off, t in tables.items() if off != min(tables)}
    per_scenario = by_scenario(tables).rename(columns={
        "right_first": "right first (nulls: clean)", "attributable_at_least_half": "attributable ≥ 0.5",
        "gap_measured": "gap measured", "median_attributable": "median attributable",
        "median_seconds": "median seconds"})
    rep_cols = ["scenario", "seed", "named", "correct_first", "truth_confirmed", "attributable_shrink",
                "attributable_rms", "truth_gain",
                "named_gain", "seconds"]
    replication = "".join(f"""
### Seeds + {off}

{markdown_table(t[[c for c in rep_cols if c in t.columns]], "{:.3g}", nan="")}
""" for off, t in reps.items())
    text = f"""# Discovery: the first hidden-effect benchmark, on fixed worlds

Superseded by the drawn worlds of [discovery-benchmark.md](discovery-benchmark.md).

Command: `python research/discovery_benchmark.py {config} --seed-offsets {offsets}{sets} --docs`
(2-core VM, {time.strftime('%Y-%m-%d')}; `seconds` is the wall time of each scenario:
generation, training, offset, selection, retraining and replays).

""" + _SUMMARY_HEADER + "".join(f"| {r.seeds} | {r.right_first} | {r.truth_confirmed} | {r.nulls_clean} | "
               f"{r.attributable_at_least_half} | {r.gap_measured} | {r.attributable_median:.2f} | "
               f"{r.seeds_rms_at_least_half} | {r.seconds} |\n"
               for r in summary.itertuples()) + f"""
On the config's seeds:

- Right effect ranked first: {s['right_first']} hidden scenarios; the right effect among the
  first round's confirmed tries (`truth_confirmed`, named or not): {s['truth_confirmed']}.
- Nothing named: {s['nulls_clean']} null scenarios.
- Attributable shrink (before − after) / (before − null of the same seed), on each
  scenario's gap metric: median {s['attributable_median']:.2f}, ≥ 0.5 in {s['attributable_at_least_half']}
  scenarios. The gap metric is the held-out RMS of the ensemble's prediction (the median
  over seeds, over all windows: `ensemble_*`, `attributable_ensemble`), which the
  confirmation measures and the report plots, unless the scenario names another (the lag's
  peak error). `attributable_rms` is the same on the median of the seeds' own RMS (the
  metric of `discovery.json`; each net's retraining moves it by a few percent), ≥ 0.5 in
  {s['seeds_rms_at_least_half']}; `attributable_region` is over the named effect's region
  (the maneuver kinds where it acts, ensemble prediction). All against the null scenario's
  baseline on the same windows (`*_null_g`). Where an input is taken away
  from the model (weight missing from db3) the world is the null world itself, and the
  reference is the same model on the same campaign generated without the input's effect
  (`reference`: the gross weight the vibration sees held fixed; the flight keeps each
  condition's weight). `gap measured`: the scenarios whose reference is below their
  baseline (a gap to attribute); the others count as below 0.5. Before, after and the
  null's before come from three trainings: on a world whose gap is a few times the
  training noise, one world's value moves with the training seed alone (the same term on
  pitch acceleration 31: 0.18–1.15 with four nets per fold; research/notes/discovery-studies.md, "How noisy
  is one world's attributable shrink").
- `peak_*`: mean abs peak error over counters (g); `phase_*`: mean abs peak-time error over
  the transient counters (s; 3–5 s already on the null worlds, where a flat counter's
  largest window wanders, so a noisy gauge).
- Could the selection have named the truth? `effect_rms_g`: the true effect per window (the
  measured PVV minus the same window of the same seed's null world, or of the reference
  world). `learned_share`: how
  much of it the baseline already predicts (slope of its prediction's change on the true
  effect; an effect of the model's own inputs is learned from the peaks). `truth_gain`: the
  gain the first round's selection credits the true effect itself with, as if it were a
  candidate (same residual, floor covariates, with the refinements of the model's own
  inputs the round took, and folds); `named_gain`: the same for the candidate it named.
  Where `truth_gain` ≤ `named_gain` the residual itself prefers the named candidate: no
  selection on it could name the truth.

{markdown_table(df[cols], "{:.3g}", nan="")}
""" + (f"""
## By scenario, over the seed offsets {offsets}

Where the misses lie: each scenario's worlds over every seed offset of the command (for a
null scenario, "right first" counts the worlds where nothing was named).

{markdown_table(per_scenario, "{:.3g}", nan="")}
""" if reps else "") + (f"""
## Replication on other seeds

The same scenarios, every seed shifted (other conditions, pilot inputs and scatter; the
same physics and discovery settings).
{replication}""" if reps else "") + _remeasured_section(found or {}) + _FAST_SUBSET
    (ROOT / "research" / "discovery-benchmark-fixed.md").write_text(text)
    print(f"wrote {ROOT / 'research' / 'discovery-benchmark-fixed.md'}")


if __name__ == "__main__":
    main()
