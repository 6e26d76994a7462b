"""Re-choose the named try of every round of saved discoveries, from their `rounds.csv`.

A discovery is deterministic, so a change to how a round chooses among its confirmed tries
(`discovery._confirm._choose`) changes a world's result only where it changes some round's
choice. This replays the choice on every round with a confirmed try, with each folder's own
settings (its `config.toml`) or others given here, and lists the rounds where it differs
from the one logged: the worlds to re-run, and nothing else.

    python experiments/discovery_rechoose.py runs/discovery-benchmark [more folders]
        [--shrink-noise 0.02] [--alpha 0.01] [--min-shrink 0.05]   # over each folder's config
        [--tie-share 0.5] [--augment-tie additive] [--encompassing on] [--encompassing-margin 0.1]
        [--csv OUT.csv]                                             # every round, recomputed

`--min-shrink=-inf` turns off "beyond the floor first" (every tied candidate kept).
`augment_tie` is replayed too (`--augment-tie shrink` or `additive`; default each folder's):
a chosen input gives way to its proposal's term where the term's row logs `p_input_better`
and the two tie. Folders written before that p was logged for every confirmed input have it
on the named term only; a choice of another proposal's input keeps the input there.
`encompassing` is replayed too (`--encompassing on` or `off`, `--encompassing-margin`; default
each folder's, a folder written before a setting existed at its earlier value) from the
shares its rounds logged (`kept_on_top`, `named_kept_on_top`, `kept_against`). A pair of tied
terms the log has no shares for needs two retrainings: its round is listed as one to re-run
(`unmeasured`), the choice left as if the rival lost. Folders written before `kept_against`
was logged: each share is taken as measured against the try named at its step of the
folder's own settings (what the workflow did).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from pvvjax.config import load_written_config
from pvvjax.discovery._confirm import _choose, _encompassed, _tied, _ties
from pvvjax.discovery._model import source_channels

# Parameters a try adds to its proposal's candidate (a term's coefficient, a band's gain).
_FITTED = r"(?:coefficient|gain|gain_unit)=[^,]*,?"


def proposals(rows: pd.DataFrame) -> pd.Series:
    """The proposal each row of `rounds.csv` tries (a term and an input of one proposal share
    it). Files written before the `proposal` column: the candidate without the parameters its
    try fitted."""
    if "proposal" in rows:
        return rows["proposal"]
    return rows.candidate.str.replace(_FITTED, "", regex=True).str.rstrip(",:")


def tries(rows: pd.DataFrame) -> list[tuple]:
    """`_choose`'s tries from the confirmed rows of one round of `rounds.csv`. Files written
    before the `source` column: a probe's band is the one without a `gain_unit`."""
    proposal = proposals(rows)
    if "source" in rows:
        probe = rows["source"].eq("probe")
    else:
        probe = rows.operator.eq("resonance") & ~rows.candidate.str.contains("gain_unit=", regex=False)
    gain = rows.cv_gain.where(~probe, np.nan)
    control = rows["control_shrink"] if "control_shrink" in rows else pd.Series(np.nan, index=rows.index)
    return list(zip(rows.shrink, gain, rows.p_best_better, proposal, control))


def encompass(rows: pd.DataFrame, t: list, k: int, tied: list[int], measured,
              margin: float = 0.0) -> tuple[int, list[str]]:
    """`_confirm._encompassed`, the workflow's rule, on one round's confirmed rows (`tries`'
    order), with the shares the round logged.

    Args:
        rows, t: the confirmed rows and their `tries`. k: `_choose`'s pick. tied: `_ties`.
        measured: (named proposal, rival proposal) -> (rival's share, named's share), or None
            where not measured.

    Returns:
        The named try's index, and the rivals without shares (their pair needs a re-run)."""
    prop = proposals(rows).to_numpy()
    terms = {p for p in prop[rows.augment.eq("additive").to_numpy() & ~rows.operator.isin(["lag", "resonance"])]}
    unmeasured = []

    def measure(k, i):
        shares = measured(prop[k], prop[i])
        if shares is None:
            unmeasured.append(str(rows["name"].iloc[i]))
        return shares

    k = _encompassed(k, tied, prop, lambda i: prop[i] in terms,
                     lambda i: source_channels(str(rows.channels.iloc[i]).split(",")), measure, margin,
                     lambda j: t[j][0])
    return int(k), unmeasured


def logged_shares(rows: pd.DataFrame, t: list, own: tuple, own_margin: float = 0.0) -> dict:
    """The encompassing shares one round logged: {(named proposal, rival proposal): (rival's
    share, named's share)}. Without `kept_against`, the named of each pair is replayed with
    the folder's `own` settings (noise, alpha, min_shrink, share) and margin."""
    if "kept_on_top" not in rows:
        return {}
    prop = proposals(rows).to_numpy()
    got = np.flatnonzero(rows.kept_on_top.notna().to_numpy())
    share = {i: (rows.kept_on_top.iloc[i], rows.named_kept_on_top.iloc[i]) for i in got}  # on a term's row
    if "kept_against" in rows:
        return {(rows.kept_against.iloc[i], prop[i]): share[i] for i in got}
    by_rival = {prop[i]: share[i] for i in got}
    pairs = {}

    def record(named, rival):
        if rival in by_rival:
            pairs[named, rival] = by_rival[rival]
        return by_rival.get(rival)

    encompass(rows, t, _choose(t, *own), _ties(t, *own), record, own_margin)
    return pairs


def rechoose(rounds: pd.DataFrame, noise: float, alpha: float, min_shrink: float,
             share: float = 0.0, augment_tie: str = "shrink", encompassing: bool = False,
             margin: float = 0.0, own: tuple | None = None, own_margin: float | None = None) -> pd.DataFrame:
    """Every round with a confirmed try (round 0, the lag test's, has its own rule): the try
    logged as chosen and the one `_choose` picks with these settings, then, with
    `encompassing`, the tied term that keeps more on top of the other (`encompass`, from the
    shares logged), then, with `augment_tie = "additive"`, its proposal's term where it ties
    with a chosen input. own, own_margin: the folder's (noise, alpha, min_shrink, share) and
    `encompassing_margin`, for logs without `kept_against` (default: these).

    Returns:
        round, logged, recomputed (name (augment)), changed, unmeasured (the rivals whose
        shares the log lacks, "; "-joined).
    """
    own = own or (noise, alpha, min_shrink, share)
    own_margin = margin if own_margin is None else own_margin
    out = []
    for rnd, g in rounds[rounds["round"] > 0].groupby("round"):
        confirmed = g[g.confirmed.astype(bool)]
        if not len(confirmed):
            continue
        t = tries(confirmed)
        k = _choose(t, noise, alpha, min_shrink, share)
        unmeasured = []
        if encompassing:
            shares = logged_shares(confirmed, t, own, own_margin)
            k, unmeasured = encompass(confirmed, t, k, _ties(t, noise, alpha, min_shrink, share),
                                      lambda a, b: shares.get((a, b)), margin)
        pick = confirmed.index[k]
        if augment_tie == "additive" and g.loc[pick, "augment"] == "input" and "p_input_better" in g:
            terms = g[g.augment.eq("additive") & proposals(g).eq(t[k][3]) & g.p_input_better.notna()]
            if len(terms) and _tied(terms.shrink.iloc[0], t[k][0], terms.p_input_better.iloc[0], noise, alpha,
                                    share):
                pick = terms.index[0]
        logged = g[g.chosen.astype(bool)]
        label = lambda r: f"{r['name']} ({r['augment']})"  # noqa: E731
        out.append(dict(round=int(rnd), logged=label(logged.iloc[0]) if len(logged) else "",
                        recomputed=label(g.loc[pick]), changed=not (len(logged) == 1 and logged.index[0] == pick),
                        unmeasured="; ".join(unmeasured)))
    return pd.DataFrame(out, columns=["round", "logged", "recomputed", "changed", "unmeasured"])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", help="searched for */rounds.csv (each beside its config.toml)")
    ap.add_argument("--shrink-noise", type=float)
    ap.add_argument("--alpha", type=float)
    ap.add_argument("--min-shrink", type=float, help="=-inf: no 'beyond the floor first'")
    ap.add_argument("--tie-share", type=float,
                    help="default: each folder's config (0.5 where it predates tie_share; 0 replays the old rule)")
    ap.add_argument("--augment-tie", choices=["shrink", "additive"], help="default: each folder's config")
    ap.add_argument("--encompassing", choices=["on", "off"], help="default: each folder's config")
    ap.add_argument("--encompassing-margin", type=float, help="default: each folder's config")
    ap.add_argument("--csv", help="write every round, recomputed, here")
    args = ap.parse_args()
    tables = []
    for folder in args.folders:
        for path in sorted(Path(folder).rglob("rounds.csv")):
            try:
                rounds = pd.read_csv(path)
            except pd.errors.EmptyDataError:  # a discovery with max_effects = 0
                continue
            d = load_written_config(path.with_name("config.toml")).discovery
            noise = d.shrink_noise if args.shrink_noise is None else args.shrink_noise
            alpha = d.alpha if args.alpha is None else args.alpha
            min_shrink = d.min_shrink if args.min_shrink is None else args.min_shrink
            share = d.tie_share if args.tie_share is None else args.tie_share
            way = d.augment_tie if args.augment_tie is None else args.augment_tie
            enc = d.encompassing if args.encompassing is None else args.encompassing == "on"
            margin = d.encompassing_margin if args.encompassing_margin is None else args.encompassing_margin
            own = (d.shrink_noise, d.alpha, d.min_shrink, d.tie_share)
            table = rechoose(rounds, noise, alpha, min_shrink, share, way, enc, margin, own, d.encompassing_margin)
            tables.append(table.assign(world=str(path.parent)))
    if not tables:
        raise SystemExit(f"no rounds.csv under {args.folders}")
    table = pd.concat(tables, ignore_index=True)
    for r in table[table.changed].itertuples():
        print(f"{r.world}, round {r.round}: {r.logged} -> {r.recomputed}")
    open_ = table[table.unmeasured != ""]
    for r in open_.itertuples():
        print(f"{r.world}, round {r.round}: encompassing not measured for {r.unmeasured} against the named: re-run")
    worlds = table.world.nunique()
    changed = table[table.changed].world.nunique()
    print(f"{len(table)} rounds with a confirmed try in {worlds} worlds; the choice changes in "
          f"{int(table.changed.sum())} rounds of {changed} worlds"
          + (f"; {len(open_)} rounds of {open_.world.nunique()} worlds need a re-run" if len(open_) else ""))
    if args.csv:
        table.to_csv(args.csv, index=False)


if __name__ == "__main__":
    main()
