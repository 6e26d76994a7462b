"""The benchmark's attributable shrink re-measured with a larger ensemble.

With four nets per fold one world's attributable shrink moves by ±0.4 with the training seed
alone (docs/discovery-studies.md, "How noisy is one world's attributable shrink"). This re-measures
finished benchmark worlds without re-running their discovery: each world's model is rebuilt
from its folder as the workflow built it (the peak nets and their offset, the lag test's
chosen ensembles, then every named effect in its round's way: `rounds.csv`, `lag_test.csv`)
with `--nets` nets per fold, and so is the baseline of the null world of its seed (or of its
reference world). The names are the discovery's; only the before, after and null numbers are
new. With `--nets 4` (the config's `seeds`) it reproduces the table's numbers (a folder
written before `rounds.csv` kept `parameters`: up to the four digits of a candidate's key).

    python experiments/attributable_ensemble.py /work/out --seed-offsets 0,1 --nets 16

writes OUT/[seed+N/]attributable_nets16.csv beside each offset's results, and prints the
worlds side by side with the table's own attributable shrink. With `--draws R` every model
(the world's and its null's) is retrained R times from other training seeds, and the before,
after and null are the means over those draws (OUT/[seed+N/]attributable_nets4_draws4.csv for
`--nets 4 --draws 4`): the expected error of the workflow's ensemble rather than one draw of
it, with each draw's shrink and the gap's standard error beside them. With `--augment
additive` (or `input`) every named term or extra input is added the other way of its
proposal (`..._draws8_additive.csv`): the before and the null are the same trainings, so
the two files' after pair draw by draw (docs/discovery-studies.md, "A term or an input, over
training draws").
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
from pvvjax.config import DiscoveryConfig  # noqa: E402
from pvvjax.discovery import Model  # noqa: E402
from pvvjax.discovery._confirm import _augment  # noqa: E402
from pvvjax.discovery._fits import _fit_offset  # noqa: E402
from pvvjax.discovery._lag import _through_lag  # noqa: E402
from pvvjax.discovery._model import _replay, metrics, predictions  # noqa: E402
from pvvjax.discovery.candidates import Candidate, from_key  # noqa: E402
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


def rebuild(campaign, cfg, folder: Path, log=print, each=None, way: str = "", refit: str = "") -> tuple:
    """A finished discovery's models retrained with `cfg` (its nets per fold). `each(round,
    model)`, if given, sees the model each round started from (and the final one, as the
    round after the last named). `way` ("additive" or "input"), if given, adds every named
    term or extra input that way instead (the other way of its round's proposal); `refit`
    ("peaks" or "windows"), if given, refits every term so instead of as its round did.

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
            how, c = r.augment, named_candidate(r)
            if way and how in _WAYS and way != how:
                how, c = way, dataclasses.replace(c, parameters={k: v for k, v in c.parameters.items()
                                                                 if k not in _FITTED})
                log(f"    added as {how}")
            current = _augment(ctx, current, c, how, refit=refit or window_refit(r))
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


# Settings that change only which tries a round makes or names, not how a named effect is
# trained: a world run without them rebuilds the same (rounds.csv says what was named).
_CHOICE_ONLY = frozenset({"resonance_input", "augment_tie", "encompassing", "encompassing_margin"})
_WAYS = ("additive", "input")  # the ways `--augment` swaps
_FITTED = ("coefficient",)  # what an additive try adds to its proposal's candidate
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


def _draw_config(cfg, nets: int, draw: int):
    """`cfg` with `nets` nets per fold, trained from training draw `draw` (the config's seed +
    1000 × draw: draw 0 is the discovery's own training; the folds stay the same)."""
    return dataclasses.replace(cfg, seed=cfg.seed + 1000 * draw,
                               discovery=dataclasses.replace(cfg.discovery, seeds=nets))


_RESAMPLES = 2000  # bootstrap resamples of a world's draws


def over_draws(draws: list, metric: str, named: bool) -> dict:
    """One world's before / after / null over its training draws (`draws`: one (before, after,
    null) metrics triple a draw): each the mean over the draws, the attributable shrink of
    those means, and the spread a single draw has. The gap (before − null) of one draw is the
    difference of two trainings; `gap_se_g` is the standard error of its mean, and `gap_z`
    the mean gap in those units (a gap below about 2 is not measured apart from the training
    noise). `attributable_lo` and `_hi` bound the shrink of the means by the 5th and 95th
    percentiles of the same over the draws resampled (bootstrap; a resample without a gap
    counts as below every shrink: NaN where it is the 5th percentile's). Nothing named closes
    nothing (the table's convention)."""
    get = lambda i, k: np.array([d[i][k] for d in draws], dtype=float)  # noqa: E731
    b, a, n = (get(i, metric) for i in range(3))
    each = [_closed(*v) if named else 0.0 for v in zip(b, a, n)]
    gap = b - n
    se = float(np.std(gap, ddof=1) / np.sqrt(len(gap))) if len(gap) > 1 else np.nan
    lo = hi = 0.0 if not named else np.nan
    if named and len(gap) > 1:
        i = np.random.default_rng(0).integers(len(gap), size=(_RESAMPLES, len(gap)))
        bb, ab, nb = b[i].mean(1), a[i].mean(1), n[i].mean(1)
        boot = np.where(bb > nb, (bb - ab) / np.where(bb > nb, bb - nb, 1.0), -np.inf)
        lo, hi = (float(v) if np.isfinite(v) else np.nan for v in np.percentile(boot, [5, 95], method="inverted_cdf"))
    eb, ea, en = (get(i, "ensemble_rms_g").mean() for i in range(3))
    return dict(before=b.mean(), after=a.mean(), null=n.mean(),
                attributable=_closed(b.mean(), a.mean(), n.mean()) if named else 0.0,
                attributable_lo=lo, attributable_hi=hi,
                attributable_draws=";".join(f"{v:.3f}" for v in each), gap_g=gap.mean(), gap_se_g=se,
                gap_z=gap.mean() / se if se > 0 else np.nan,
                **{f"{k}_draws": ";".join(f"{v:.6g}" for v in x)
                   for k, x in (("before", b), ("after", a), ("null", n))},
                ensemble_before_g=eb, ensemble_after_g=ea, ensemble_null_g=en,
                attributable_ensemble=_closed(eb, ea, en) if named else 0.0)


def table_name(nets: int, draws: int = 1, way: str = "", refit: str = "") -> str:
    """The re-measurement's file beside an offset's results."""
    return (f"attributable_nets{nets}" + (f"_draws{draws}" if draws > 1 else "") + (f"_{way}" if way else "")
            + (f"_refit-{refit}" if refit else "") + ".csv")


def evaluate_offset(out: Path, offset: int, nets: int, only=(), log=print, draws: int = 1,
                    way: str = "", refit: str = "") -> pd.DataFrame:
    """Every finished world of one seed offset of a benchmark output, re-measured with `nets`
    nets per fold and `draws` training draws (`_draw_config`; each draw retrains the world's
    models and its null's): one row per hidden world, its before / after / null on its gap
    metric and over all windows (ensemble), means over the draws (`over_draws`), with the
    table's attributable shrink beside the new one. `way`: every named term or input added
    that way, `refit`: every term refitted so (`rebuild`); the before and the null are the same
    trainings either way, so two runs' after pair draw by draw."""
    folder = out / (f"seed+{offset}" if offset else "")
    table = read_table(folder / "results.parquet")[0]
    scenarios, overrides = scenario_configs(CONFIG, offset)
    by_name = {s["name"]: s for s in scenarios}
    nulls = {}

    def config(sc, draw):
        cfg = scenario_config(sc, overrides)
        differ = _other_settings(read_table(folder / sc["name"] / "windows.parquet")[1], cfg.discovery)
        if differ:  # its rounds were chosen with other settings
            raise SystemExit(f"{folder / sc['name']} was run with other settings than {CONFIG}'s: {differ}")
        return _draw_config(cfg, nets, draw)

    def null_of(seed: int, draw: int, through_lag: bool, kinds):
        """The null world of `seed` in training draw `draw`: its baseline's metrics (or its lag
        reference's)."""
        if (seed, draw) not in nulls:
            for k in [k for k in nulls if k[1] != draw]:  # one draw's nulls held at a time: memory
                del nulls[k]
            sc = next(s for s in scenarios if s["seed"] == seed and s["truth"] is None)
            t0 = time.perf_counter()
            ctx, base, _, lag_ref = rebuild(_campaign(sc["synth"]), config(sc, draw), folder / sc["name"], log)
            nulls[seed, draw] = dict(ctx=ctx, base=base, lag_ref=lag_ref, lagged=None)
            log(f"  {sc['name']} (seed {seed}, draw {draw}): baseline {time.perf_counter() - t0:.0f} s")
        n = nulls[seed, draw]
        if through_lag and n["lagged"] is None:
            n["lagged"] = n["lag_ref"]()
        got = measure(n["ctx"], n["lagged"] if through_lag else n["base"], kinds)
        n["ctx"].cache.clear()  # its replays at every offset the fits tried: memory, kept for three worlds
        return got

    def one_draw(sc, row, draw):
        kinds = _kinds(row)
        ctx, base, after, _ = rebuild(_campaign(sc["synth"]), config(sc, draw), folder / sc["name"], log, way=way,
                                      refit=refit)
        b, a = measure(ctx, base, kinds), measure(ctx, after, kinds)
        if base.through_lag:  # no region against a null of another kind
            b["region_g"] = np.nan
        if sc["reference_world"] is not None:  # its own reference world: the baseline there, no rounds
            rctx, rbase, _, _ = rebuild(_campaign(sc["reference_world"]), config(sc, draw),
                                        folder / sc["name"] / "reference", log)
            return b, a, measure(rctx, rbase, kinds)
        return b, a, null_of(sc["seed"], draw, base.through_lag, kinds)

    hidden = table[table.hidden != "none"]
    if only:
        hidden = hidden[hidden.scenario.isin(only)]
    per, seconds, rows = {}, {}, []
    for draw in range(draws):  # draws outermost: a null's models are rebuilt once a draw
        for row in hidden.itertuples():
            sc = by_name[row.scenario]
            t0 = time.perf_counter()
            log(f"  {row.scenario} (seed {row.seed}, draw {draw}): {row.named}")
            per.setdefault(row.scenario, []).append(one_draw(sc, row, draw))
            seconds[row.scenario] = seconds.get(row.scenario, 0.0) + time.perf_counter() - t0
            rows = [_row(r, per[r.scenario], offset, nets, seconds[r.scenario]) for r in hidden.itertuples()
                    if r.scenario in per]
            # after each world: the draws so far
            _save(pd.DataFrame(rows), folder / table_name(nets, draws, way, refit))
            new = next(r for r in rows if r["scenario"] == row.scenario)
            log(f"  {row.scenario}, {draw + 1} draw(s): {new['gap_metric']} before {new['before']:.4f}, after "
                f"{new['after']:.4f}, null {new['null']:.4f}: attributable {new['attributable']:.2f} (draws "
                f"{new['attributable_draws']}; gap {new['gap_g']:.4f} ± {new['gap_se_g']:.4f}; table "
                f"{new['table_attributable']:.2f}); {new['seconds']:.0f} s")
    return pd.DataFrame(rows)


def _row(row, per: list, offset: int, nets: int, seconds: float) -> dict:
    """A world's re-measured row from its draws' (before, after, null) metrics."""
    metric, named = row.gap_metric, row.named != "none"
    new = dict(scenario=row.scenario, seed=row.seed, offset=offset, nets=nets, draws=len(per), named=row.named,
               correct_first=row.correct_first, gap_metric=metric, **over_draws(per, metric, named))
    regions = np.mean([(b["region_g"], a["region_g"], n["region_g"]) for b, a, n in per], axis=0)
    new["attributable_region"] = _closed(*regions) if named else 0.0  # NaN without a region
    before, after = _GAP_COLUMNS[metric]
    return new | dict(table_before=getattr(row, before), table_after=getattr(row, after),
                      table_attributable=row.attributable_shrink, seconds=seconds)


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
    ap.add_argument("--draws", type=int, default=1,
                    help="training draws (the config's seed + 1000 × draw), each retraining every model; the "
                         "before, after and null are their means")
    ap.add_argument("--only", default="", help="comma-separated hidden scenario names")
    ap.add_argument("--augment", choices=_WAYS, default="",
                    help="add every named term or extra input this way instead (the other way of its proposal); "
                         "the file gets the way's name")
    ap.add_argument("--refit", choices=("peaks", "windows"), default="",
                    help="refit every named term so (term_refit's \"peaks\" or \"windows\"), not as its round did; "
                         "the file gets _refit-NAME")
    args = ap.parse_args()
    only = tuple(s for s in args.only.split(",") if s)
    frames = []
    for off in (int(v) for v in args.seed_offsets.split(",")):
        print(f"seed offset {off}", flush=True)
        frames.append(evaluate_offset(args.out, off, args.nets, only, log=lambda m: print(m, flush=True),
                                      draws=args.draws, way=args.augment, refit=args.refit))
    df = pd.concat(frames, ignore_index=True)
    print(df[["scenario", "seed", "named", "gap_metric", "before", "after", "null", "attributable",
              "table_attributable", "seconds"]].to_string())
    ok = lambda v: int((v.fillna(0) >= 0.5).sum())  # noqa: E731
    print(f"attributable >= 0.5: {ok(df.attributable)} / {len(df)} with {args.nets} nets per fold, "
          f"{ok(df.table_attributable)} / {len(df)} in the table; median {df.attributable.median():.2f} "
          f"against {df.table_attributable.median():.2f}")


if __name__ == "__main__":
    main()
