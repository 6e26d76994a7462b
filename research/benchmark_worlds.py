"""The worlds of the discovery benchmark, drawn at random (`pvvjax.synth.draw_campaign`).

A plan (the `[world]`, `[protocol]` and `[[family]]` tables of a benchmark config) names
the ranges of the base world, the hidden-effect families with the spans their parameters
are drawn over, and two disjoint sets of seeds: the tuning seeds, on which rules and
defaults are chosen, and the fresh seeds, run once after the rules are frozen. Each seed
gives one null world and `hidden_per_seed` hidden worlds on the same base, so every hidden
world's gap is measured against the null of its own seed. The families are dealt to the
hidden worlds in a seeded shuffle, each about equally often, and every `1 / two_effects`-th
hidden world carries a second family (another one, drawn) besides its first.

    python research/benchmark_worlds.py research/configs/benchmark.toml [--fresh] [--truth DIR]

lists the worlds (and with --truth writes each one's truth file: the generator's ground
truth and what was drawn), without running discovery.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pvvjax.config import from_dict, load_toml
from pvvjax.synth import CampaignDraw, Planted, draw_campaign, ground_truth


@dataclass(frozen=True)
class Family:
    """A hidden-effect family: what it plants and how a discovery is judged against it.

    Attributes:
        name: the family's name in the tables.
        planted: the generator effect and the spans of its scale and parameters.
        accept: the named effects that count as right: operator[:channel] forms.
        parameter: the fitted parameter a right effect is compared on ("" for none).
        truth: the planted parameter that is its truth ("" for none).
        per_cent_of_rpm: the truth is in % of the aircraft's nominal rotor speed and the
            fitted parameter in rpm.
        gap_metric: the metric whose gap the attributable shrink measures.
        database: the model's database.
    """

    name: str
    planted: Planted
    accept: tuple[str, ...]
    parameter: str = ""
    truth: str = ""
    per_cent_of_rpm: bool = False
    gap_metric: str = "ensemble_rms_g"
    database: str = "db1"

    def __post_init__(self):
        if bool(self.parameter) != bool(self.truth):
            raise ValueError(f"family {self.name!r}: give both parameter and truth, or neither")
        if self.truth and self.truth not in self.planted.params:
            raise ValueError(f"family {self.name!r}: truth {self.truth!r} is not a drawn parameter of "
                             f"{self.planted.effect} ({', '.join(self.planted.params) or 'none'})")


@dataclass(frozen=True)
class Seeds:
    """A run of consecutive seeds."""

    first: int
    count: int

    def __post_init__(self):
        if self.count < 1 or self.first < 0:
            raise ValueError(f"seeds: first >= 0 and count >= 1, got {self.first}, {self.count}")

    def range(self) -> range:
        return range(self.first, self.first + self.count)


@dataclass(frozen=True)
class Protocol:
    """Which seeds choose the rules and which judge them, and how worlds are dealt.

    Attributes:
        tuning: the seeds rules and defaults are chosen on.
        fresh: the seeds of the reported table, run once after the rules are frozen.
        hidden_per_seed: hidden worlds per seed, beside its null.
        two_effects: the share of hidden worlds that carry two families.
    """

    tuning: Seeds
    fresh: Seeds
    hidden_per_seed: int = 2
    two_effects: float = 0.2

    def __post_init__(self):
        t, f = set(self.tuning.range()), set(self.fresh.range())
        if t & f:
            raise ValueError(f"protocol: tuning and fresh seeds overlap ({min(t & f)}...)")
        if self.hidden_per_seed < 1 or not 0 <= self.two_effects <= 1:
            raise ValueError("protocol: hidden_per_seed >= 1 and two_effects within 0 to 1")


@dataclass(frozen=True)
class Plan:
    """A benchmark config's worlds: the base's ranges, the protocol, the families and the
    families left out with the reason."""

    world: CampaignDraw
    protocol: Protocol
    family: tuple[Family, ...] = field(metadata={"repeats": True})  # names checked below
    dropped: dict[str, str] = field(default_factory=dict)

    def __post_init__(self):
        names = [f.name for f in self.family]
        if len(set(names)) != len(names) or len(names) < 2:
            raise ValueError(f"family: at least two, each name once; got {names}")


def load_plan(path) -> Plan:
    """The plan of a benchmark config (strict: an unknown key is an error naming it)."""
    raw = load_toml(path)
    return from_dict(Plan, raw, where=str(path))


def _truth(fam: Family, drawn: dict, cfg) -> dict:
    out = dict(effect=fam.name, accept=list(fam.accept), gap_metric=fam.gap_metric)
    if fam.parameter:
        value = drawn[f"planted.{fam.planted.effect}.{fam.truth}"]
        if fam.per_cent_of_rpm:
            value = value / 100.0 * cfg.aircraft_constants().nominal_rpm
        out.update(parameter=fam.parameter, value=float(value))
    return out


def _one_of_each_per_seed(deck: list, per_seed: int) -> list:
    """The deck reordered so that no seed is dealt one family twice: a seed's worlds share
    their base and a family's draws depend on the seed alone, so a family dealt twice at one
    seed would be the same world twice. A repeated card is swapped with the first later card
    whose family the seed does not hold and whose seed does not hold the repeated family (the
    counts per family stay as dealt)."""
    deck = list(deck)
    block = lambda j: range(j - j % per_seed, min(j - j % per_seed + per_seed, len(deck)))  # noqa: E731

    def others(j):  # the families of j's seed other than card j's
        return {deck[i].name for i in block(j) if i != j}

    for k in range(len(deck)):
        if deck[k].name not in {deck[i].name for i in block(k) if i < k}:
            continue
        swap = next((j for j in range(block(k)[-1] + 1, len(deck))
                     if deck[j].name not in others(k) and deck[k].name not in others(j)), None)
        if swap is None:
            raise ValueError(f"protocol.hidden_per_seed = {per_seed}: the deck cannot give each seed "
                             f"{per_seed} different families")
        deck[k], deck[swap] = deck[swap], deck[k]
    return deck


def worlds(plan: Plan, fresh: bool = False) -> list[dict]:
    """The worlds of the tuning (or fresh) seeds, each seed's null before its hidden
    worlds: each a dict of name, seed, database, truth (None for a null), synth (its
    `SynthConfig`), drawn (its draws) and alone. A two-effect world's truth holds the second
    family under `also`, in the order dealt, and `alone` the world with each family alone
    (family name -> `SynthConfig`): which of the two is the larger is measured when it is
    scored."""
    seeds = (plan.protocol.fresh if fresh else plan.protocol.tuning).range()
    p = plan.protocol
    n_hidden = len(seeds) * p.hidden_per_seed
    rng = np.random.default_rng([seeds.start, len(seeds), 7])
    deck = [plan.family[i % len(plan.family)] for i in rng.permutation(max(n_hidden, len(plan.family)))][:n_hidden]
    deck = _one_of_each_per_seed(deck, p.hidden_per_seed)
    every = int(round(1 / p.two_effects)) if p.two_effects > 0 else 0
    out, k = [], 0
    for seed in seeds:
        cfg, drawn = draw_campaign(plan.world, seed, name=f"null-{seed}")
        out.append(dict(name=f"null-{seed}", seed=seed, database="db1", truth=None, synth=cfg, drawn=drawn, alone={}))
        for _ in range(p.hidden_per_seed):
            fams = [deck[k]]
            if every and (k + 1) % every == 0:
                others = [f for f in plan.family if f.name != deck[k].name]
                fams.append(others[int(rng.integers(len(others)))])
            k += 1
            name = "+".join(f.name for f in fams) + f"-{seed}"
            cfg, drawn = draw_campaign(plan.world, seed, [f.planted for f in fams], name=name)
            truth = _truth(fams[0], drawn, cfg)
            alone = {}
            if len(fams) > 1:
                truth["also"] = _truth(fams[1], drawn, cfg)
                alone = {f.name: draw_campaign(plan.world, seed, [f.planted])[0] for f in fams}
            out.append(dict(name=name, seed=seed, database=fams[0].database, truth=truth, synth=cfg, drawn=drawn,
                            alone=alone))
    return out


def world_truth(world: dict) -> dict:
    """A world's truth file: the generator's ground truth, what was drawn and the judged truth."""
    return {**ground_truth(world["synth"]), "drawn": world["drawn"], "judged": world["truth"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("config")
    ap.add_argument("--fresh", action="store_true", help="the fresh seeds (default: the tuning seeds)")
    ap.add_argument("--truth", default=None, help="write each world's truth file into this folder")
    args = ap.parse_args()
    plan = load_plan(args.config)
    for w in worlds(plan, args.fresh):
        d = w["drawn"]
        print(f"{w['name']:40s} {d['aircraft']:6s} {d['conditions']:4d} conditions, noise {d['noise_g']:.3f} g, "
              f"scatter {d['scatter']:.3f}", *(f"{k.split('.', 1)[1]}={v:.3g}" for k, v in d.items()
                                                  if k.startswith("planted.")))
        if args.truth:
            Path(args.truth).mkdir(parents=True, exist_ok=True)
            (Path(args.truth) / f"{w['name']}.truth.json").write_text(json.dumps(world_truth(w), indent=1))
    for name, why in plan.dropped.items():
        print(f"dropped {name}: {why}")


if __name__ == "__main__":
    main()
