"""The benchmark's attributable shrink re-measured with a larger ensemble.

With four nets per fold one world's attributable shrink moves by ±0.4 with the training seed
alone (docs/discovery.md, "How noisy is one world's attributable shrink"). This re-measures
finished benchmark worlds without re-running their discovery: each world's model is rebuilt
from its folder as the workflow built it (the peak nets and their offset, the lag test's
chosen ensembles, then every named effect in its round's way: `rounds.csv`, `lag_test.csv`)
with `--nets` nets per fold, and so is the baseline of the null world of its seed (or of its
reference world). The names are the discovery's; only the before, after and null numbers are
new. With `--nets 4` (the config's `seeds`) it reproduces the table's numbers (a folder
written before `rounds.csv` kept `parameters`: up to the four digits of a candidate's key).

    python experiments/attributable_ensemble.py /work/out --seed-offsets 0,1 --nets 16

writes OUT/[seed+N/]attributable_nets16.csv beside each offset's results, and prints the
worlds side by side with the table's own attributable shrink.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).parent))
from discovery_benchmark import _GAP_COLUMNS, _campaign, _closed, scenario_config, scenario_configs  # noqa: E402
from term_backfit_probe import baseline  # noqa: E402

from pvvjax._strict import to_dict  # noqa: E402
from pvvjax.candidates import Candidate, from_key  # noqa: E402
from pvvjax.config import DiscoveryConfig  # noqa: E402
from pvvjax.discovery import Model  # noqa: E402
from pvvjax.discovery._confirm import _augment  # noqa: E402
from pvvjax.discovery._fits import _fit_offset  # noqa: E402
from pvvjax.discovery._lag import _through_lag  # noqa: E402
from pvvjax.discovery._model import _replay, metrics, predictions  # noqa: E402
from pvvjax.io import read_table  # noqa: E402

CONFIG = Path(__file__).parent / "configs" / "discovery" / "benchmark.toml"
_METRICS = ("ensemble_rms_g", "rms_g", "peak_error_g", "phase_error_s")


def _lag_row(folder: Path, role: str) -> pd.Series:
    t = pd.read_csv(folder / "lag_test.csv")
    rows = t[(t.role == role) & t.chosen]
    if not len(rows):
        raise SystemExit(f"{folder / 'lag_test.csv'}: no chosen {role} row")
    return rows.iloc[0]


def chosen_rounds(folder: Path) -> pd.DataFrame:
    """The named tries of a finished discovery (`rounds.csv`'s chosen rows), in round order."""
    try:
        r = pd.read_csv(folder / "rounds.csv")
    except (FileNotFoundError, pd.errors.EmptyDataError):  # no rounds: a reference baseline
        return pd.DataFrame(columns=["round", "candidate", "augment"])
    return r[r.chosen.fillna(False).astype(bool)].sort_values("round")


def named_candidate(row) -> Candidate:
    """A rounds-table row's candidate, its parameters at full precision where the table keeps
    them (a table before that column: the key's four digits)."""
    exact = getattr(row, "parameters", None)
    return from_key(row.candidate, exact if isinstance(exact, str) else None)


def window_refit(row) -> str:
    """"windows" where a round kept its named term refitted on window nets (`term_refit =
    "named"`, rounds.csv's `window_refit_kept`), else "" (the config's own refit)."""
    return "windows" if getattr(row, "window_refit_kept", False) in (True, "True") else ""


def rebuild(campaign, cfg, folder: Path, log=print, each=None) -> tuple:
    """A finished discovery's models retrained with `cfg` (its nets per fold). `each(round,
    model)`, if given, sees the model each round started from (and the final one, as the
    round after the last named).

    Returns:
        (context, baseline, after, lag reference): the workflow's baseline (the lag test's
        chosen reference where the lag was named in round 0), the model with every named
        effect, and a callable giving the lag test's chosen reference of this world (nets
        through a lag, for a hidden world whose baseline is of that kind).
    """
    ctx, base, _ = baseline(campaign, cfg)
    current, last = base, 0
    for r in chosen_rounds(folder).itertuples():
        if each is not None:
            each(r.round, current)
        last = r.round
        log(f"    round {r.round}: {r.candidate} ({r.augment})")
        if r.round == 0:  # the lag test's: before its reference, after its slow lag
            ref, slow = _lag_row(folder, "reference"), _lag_row(folder, "slow")
            base = _through_lag(ctx, float(ref.tau_s), float(ref.train_offset_s))
            current = _through_lag(ctx, float(slow.tau_s), float(slow.train_offset_s))
        elif r.augment == "lag":
            current = _fit_offset(ctx, current, with_lag=True)
        else:
            current = _augment(ctx, current, named_candidate(r), r.augment, refit=window_refit(r))
    if each is not None:
        each(last + 1, current)

    def lag_reference():
        ref = _lag_row(folder, "reference")
        return _through_lag(ctx, float(ref.tau_s), float(ref.train_offset_s))
    return ctx, base, current, lag_reference


def measure(ctx, model: Model, kinds=()) -> dict:
    """The held-out metrics of `model` (`metrics`), and the ensemble's RMS over the full
    windows of the maneuver kinds `kinds` (`region_g`)."""
    win = _replay(ctx, model.offset_s)
    pred = predictions(ctx, model, win)
    out = {k: float(v) for k, v in metrics(pred, win).items() if k in _METRICS}
    t = win.table
    there = (t.weight.to_numpy() >= 0.999) & t.maneuver.isin(list(kinds)).to_numpy()
    e = t.measured_g.to_numpy()[there] - np.median(pred, axis=0)[there]
    out["region_g"] = float(np.sqrt(np.mean(e ** 2))) if there.any() else np.nan
    return out


# Settings that change only which tries a round makes, not how a named effect is trained:
# a world run without them rebuilds the same.
_CHOICE_ONLY = frozenset({"resonance_input"})
# Values of a setting that rebuild the same: "named" refits a term as "peaks" does, unless its
# round kept the window refit, which rounds.csv records (`window_refit`).
_SAME_REBUILD = {"term_refit": {"peaks", "named"}}


def _same_rebuild(key: str, then, now) -> bool:
    return {then, now} <= _SAME_REBUILD.get(key, set())


def _other_settings(stored: dict | None, d: DiscoveryConfig) -> dict:
    """The [discovery] settings a world's folder was run with that differ from `d`, by name:
    (then, now). A setting added since must be at its default (it did not exist then)."""
    was, now = (stored or {}).get("discovery", {}), to_dict(d)
    default = to_dict(DiscoveryConfig(database=d.database))
    then = {k: was.get(k, default[k]) for k in now}
    return {k: (was.get(k, f"(none; default {default[k]!r})"), v) for k, v in now.items()
            if v != then[k] and k not in _CHOICE_ONLY and not _same_rebuild(k, then[k], v)}


def _kinds(row) -> tuple:
    return tuple(row.region.split(", ")) if isinstance(row.region, str) and row.region else ()


def evaluate_offset(out: Path, offset: int, nets: int, only=(), log=print) -> pd.DataFrame:
    """Every finished world of one seed offset of a benchmark output, re-measured with `nets`
    nets per fold: one row per hidden world, its before / after / null on its gap metric and
    over all windows (ensemble), with the table's attributable shrink beside the new one."""
    folder = out / (f"seed+{offset}" if offset else "")
    table = read_table(folder / "results.parquet")[0]
    scenarios, overrides = scenario_configs(CONFIG, offset)
    by_name = {s["name"]: s for s in scenarios}
    nulls, rows = {}, []

    def config(sc):
        cfg = scenario_config(sc, overrides)
        differ = _other_settings(read_table(folder / sc["name"] / "windows.parquet")[1], cfg.discovery)
        if differ:  # its rounds were chosen with other settings
            raise SystemExit(f"{folder / sc['name']} was run with other settings than {CONFIG}'s: {differ}")
        return dataclasses.replace(cfg, discovery=dataclasses.replace(cfg.discovery, seeds=nets))

    def null_of(seed: int, through_lag: bool, kinds):
        """The null world of `seed`: its baseline's metrics (and of its lag reference's)."""
        if seed not in nulls:
            sc = next(s for s in scenarios if s["seed"] == seed and s["truth"] is None)
            t0 = time.perf_counter()
            ctx, base, _, lag_ref = rebuild(_campaign(sc["synth"]), config(sc), folder / sc["name"], log)
            nulls[seed] = dict(ctx=ctx, base=base, lag_ref=lag_ref, lagged=None)
            log(f"  {sc['name']} (seed {seed}): baseline {time.perf_counter() - t0:.0f} s")
        n = nulls[seed]
        if through_lag and n["lagged"] is None:
            n["lagged"] = n["lag_ref"]()
        got = measure(n["ctx"], n["lagged"] if through_lag else n["base"], kinds)
        n["ctx"].cache.clear()  # its replays at every offset the fits tried: memory, kept for three worlds
        return got

    hidden = table[table.hidden != "none"]
    if only:
        hidden = hidden[hidden.scenario.isin(only)]
    for row in hidden.itertuples():
        sc = by_name[row.scenario]
        t0 = time.perf_counter()
        log(f"  {row.scenario} (seed {row.seed}): {row.named}")
        ctx, base, after, _ = rebuild(_campaign(sc["synth"]), config(sc), folder / sc["name"], log)
        kinds = _kinds(row)
        b, a = measure(ctx, base, kinds), measure(ctx, after, kinds)
        if sc["reference_world"] is not None:  # its own reference world: the baseline there, no rounds
            rctx, rbase, _, _ = rebuild(_campaign(sc["reference_world"]), config(sc), folder / sc["name"] / "reference",
                                        log)
            n = measure(rctx, rbase, kinds)
        else:
            n = null_of(sc["seed"], base.through_lag, kinds)
        metric = row.gap_metric
        new = dict(scenario=row.scenario, seed=row.seed, offset=offset, nets=nets, named=row.named,
                   correct_first=row.correct_first, gap_metric=metric,
                   before=b[metric], after=a[metric], null=n[metric],
                   attributable=_closed(b[metric], a[metric], n[metric]) if row.named != "none" else 0.0,
                   ensemble_before_g=b["ensemble_rms_g"], ensemble_after_g=a["ensemble_rms_g"],
                   ensemble_null_g=n["ensemble_rms_g"],
                   attributable_ensemble=_closed(b["ensemble_rms_g"], a["ensemble_rms_g"], n["ensemble_rms_g"]),
                   attributable_region=(_closed(b["region_g"], a["region_g"], n["region_g"])
                                        if kinds and not base.through_lag else np.nan),
                   table_before=getattr(row, _GAP_COLUMNS[metric][0]),
                   table_after=getattr(row, _GAP_COLUMNS[metric][1]),
                   table_attributable=row.attributable_shrink, seconds=time.perf_counter() - t0)
        if row.named == "none":  # nothing named: nothing closed (the table's convention)
            new["attributable_ensemble"] = new["attributable_region"] = 0.0
        rows.append(new)
        log(f"  {row.scenario}: {metric} before {new['before']:.4f}, after {new['after']:.4f}, null {new['null']:.4f}: "
            f"attributable {new['attributable']:.2f} (table {new['table_attributable']:.2f}); "
            f"{new['seconds']:.0f} s")
        _save(pd.DataFrame(rows), folder / f"attributable_nets{nets}.csv")
    return pd.DataFrame(rows)


def _save(df: pd.DataFrame, path: Path) -> None:
    """`df` into the table at `path`: its scenarios' rows replaced, the others kept (the
    scenarios of one offset can be re-measured by several runs, one after another)."""
    if path.exists():
        old = pd.read_csv(path)
        df = pd.concat([old[~old.scenario.isin(df.scenario)], df], ignore_index=True)
    df.to_csv(path, index=False)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path, help="a benchmark output folder (discovery_benchmark.py --out)")
    ap.add_argument("--seed-offsets", default="0", help="comma-separated, as the benchmark's")
    ap.add_argument("--nets", type=int, default=16, help="nets per fold (the discovery's `seeds`)")
    ap.add_argument("--only", default="", help="comma-separated hidden scenario names")
    args = ap.parse_args()
    only = tuple(s for s in args.only.split(",") if s)
    frames = []
    for off in (int(v) for v in args.seed_offsets.split(",")):
        print(f"seed offset {off}", flush=True)
        frames.append(evaluate_offset(args.out, off, args.nets, only, log=lambda m: print(m, flush=True)))
    df = pd.concat(frames, ignore_index=True)
    print(df[["scenario", "seed", "named", "gap_metric", "before", "after", "null", "attributable",
              "table_attributable", "seconds"]].to_string())
    ok = lambda v: int((v.fillna(0) >= 0.5).sum())  # noqa: E731
    print(f"attributable >= 0.5: {ok(df.attributable)} / {len(df)} with {args.nets} nets per fold, "
          f"{ok(df.table_attributable)} / {len(df)} in the table; median {df.attributable.median():.2f} "
          f"against {df.table_attributable.median():.2f}")


if __name__ == "__main__":
    main()
