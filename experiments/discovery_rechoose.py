"""Re-choose the named try of every round of saved discoveries, from their `rounds.csv`.

A discovery is deterministic, so a change to how a round chooses among its confirmed tries
(`discovery._confirm._choose`) changes a world's result only where it changes some round's
choice. This replays the choice on every round with a confirmed try, with each folder's own
settings (its `config.toml`) or others given here, and lists the rounds where it differs
from the one logged: the worlds to re-run, and nothing else.

    python experiments/discovery_rechoose.py runs/discovery-benchmark [more folders]
        [--shrink-noise 0.02] [--alpha 0.01] [--min-shrink 0.05]   # over each folder's config
        [--tie-share 0.5]
        [--csv OUT.csv]                                             # every round, recomputed

`--min-shrink=-inf` turns off "beyond the floor first" (every tied candidate kept). A round
whose named input gave way to its proposal's term (`augment_tie = "additive"`, `p_input_better`
logged) counts as unchanged where the same proposal is chosen; whether the term would tie
with another proposal's input needs that input's predictions, so it is not replayed.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from pvvjax.config import load_config
from pvvjax.discovery._confirm import _choose

# Parameters a try adds to its proposal's candidate (a term's coefficient, a band's gain).
_FITTED = r"(?:coefficient|gain|gain_unit)=[^,]*,?"


def tries(rows: pd.DataFrame) -> list[tuple]:
    """`_choose`'s tries from the confirmed rows of one round of `rounds.csv`. Files written
    before the `proposal` and `source` columns: the proposal is the candidate without the
    parameters its try fitted, and a probe's band the one without a `gain_unit`."""
    if "proposal" in rows:
        proposal = rows["proposal"]
    else:
        proposal = rows.candidate.str.replace(_FITTED, "", regex=True).str.rstrip(",:")
    if "source" in rows:
        probe = rows["source"].eq("probe")
    else:
        probe = rows.operator.eq("resonance") & ~rows.candidate.str.contains("gain_unit=", regex=False)
    gain = rows.cv_gain.where(~probe, np.nan)
    control = rows["control_shrink"] if "control_shrink" in rows else pd.Series(np.nan, index=rows.index)
    return list(zip(rows.shrink, gain, rows.p_best_better, proposal, control))


def rechoose(rounds: pd.DataFrame, noise: float, alpha: float, min_shrink: float,
             share: float = 0.0) -> pd.DataFrame:
    """Every round with a confirmed try (round 0, the lag test's, has its own rule): the try
    logged as chosen and the one `_choose` picks with these settings.

    Returns:
        round, logged, recomputed (name (augment)), changed.
    """
    out = []
    for rnd, g in rounds[rounds["round"] > 0].groupby("round"):
        c = g[g.confirmed.astype(bool)].reset_index(drop=True)
        if not len(c):
            continue
        t = tries(c)
        k = _choose(t, noise, alpha, min_shrink, share)
        logged = g[g.chosen.astype(bool)]
        label = lambda r: f"{r['name']} ({r['augment']})"  # noqa: E731
        same = len(logged) == 1 and logged.index[0] == g.index[g.confirmed.astype(bool)][k]
        if len(logged) == 1 and pd.notna(logged.iloc[0].get("p_input_better", np.nan)):
            # `augment_tie`: the proposal's term named in place of its input; a choice of the
            # proposal that recomputes the same.
            same = tries(logged.assign(confirmed=True))[0][3] == t[k][3]
        out.append(dict(round=int(rnd), logged=label(logged.iloc[0]) if len(logged) else "",
                        recomputed=label(c.iloc[k]), changed=not same))
    return pd.DataFrame(out, columns=["round", "logged", "recomputed", "changed"])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", help="searched for */rounds.csv (each beside its config.toml)")
    ap.add_argument("--shrink-noise", type=float)
    ap.add_argument("--alpha", type=float)
    ap.add_argument("--min-shrink", type=float, help="=-inf: no 'beyond the floor first'")
    ap.add_argument("--tie-share", type=float,
                    help="default: each folder's config (0.5 where it predates tie_share; 0 replays the old rule)")
    ap.add_argument("--csv", help="write every round, recomputed, here")
    args = ap.parse_args()
    tables = []
    for folder in args.folders:
        for path in sorted(Path(folder).rglob("rounds.csv")):
            try:
                rounds = pd.read_csv(path)
            except pd.errors.EmptyDataError:  # a discovery with max_effects = 0
                continue
            d = load_config(path.with_name("config.toml")).discovery
            noise = d.shrink_noise if args.shrink_noise is None else args.shrink_noise
            alpha = d.alpha if args.alpha is None else args.alpha
            min_shrink = d.min_shrink if args.min_shrink is None else args.min_shrink
            share = d.tie_share if args.tie_share is None else args.tie_share
            tables.append(rechoose(rounds, noise, alpha, min_shrink, share).assign(world=str(path.parent)))
    if not tables:
        raise SystemExit(f"no rounds.csv under {args.folders}")
    table = pd.concat(tables, ignore_index=True)
    for r in table[table.changed].itertuples():
        print(f"{r.world}, round {r.round}: {r.logged} -> {r.recomputed}")
    worlds = table.world.nunique()
    changed = table[table.changed].world.nunique()
    print(f"{len(table)} rounds with a confirmed try in {worlds} worlds; the choice changes in "
          f"{int(table.changed.sum())} rounds of {changed} worlds")
    if args.csv:
        table.to_csv(args.csv, index=False)


if __name__ == "__main__":
    main()
