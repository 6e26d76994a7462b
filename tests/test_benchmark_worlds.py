"""The discovery benchmark's drawn worlds (research/benchmark_worlds.py): the plan's
tuning and fresh seeds never overlap, every seed gives a null and its hidden worlds on
one base, the families are dealt evenly with a fifth of the hidden worlds carrying two,
each judged truth is the planted draw, and a config's mistake is an error naming it."""

import json
from pathlib import Path

import pytest
from conftest import research

from pvvjax.config import ConfigError

ROOT = Path(__file__).parents[1]
CONFIG = ROOT / "research" / "configs" / "worlds.toml"


@pytest.fixture(scope="module")
def bw():
    return research("benchmark_worlds")


def test_the_fresh_table_has_sixty_nulls_sixty_hidden_worlds_and_a_fifth_with_two_effects(bw):
    plan = bw.load_plan(CONFIG)
    fresh, tuning = bw.worlds(plan, fresh=True), bw.worlds(plan)
    assert sum(w["truth"] is None for w in fresh) >= 60 and sum(w["truth"] is not None for w in fresh) >= 60
    assert not {w["seed"] for w in fresh} & {w["seed"] for w in tuning}
    hidden = [w for w in fresh if w["truth"]]
    two = [w for w in hidden if "also" in w["truth"]]
    assert len(two) == len(hidden) // 5
    assert all(w["truth"]["also"]["effect"] != w["truth"]["effect"] for w in two)
    dealt = [w["truth"]["effect"] for w in hidden]
    counts = [dealt.count(f.name) for f in plan.family]
    assert max(counts) - min(counts) <= 1  # every family about equally often
    assert bw.worlds(plan, fresh=True) == fresh  # the same plan gives the same worlds


def test_no_two_worlds_of_a_draw_are_the_same_world(bw):
    plan = bw.load_plan(CONFIG)
    for ws in (bw.worlds(plan), bw.worlds(plan, fresh=True)):
        names = [w["name"] for w in ws]
        assert len(set(names)) == len(names)
        synth = [repr(w["synth"]) for w in ws]
        assert len(set(synth)) == len(synth)
    Card = type("Card", (), {"__init__": lambda self, name: setattr(self, "name", name)})
    deck = [Card(n) for n in "AABCBC"]  # seed 1 dealt A twice
    dealt = [c.name for c in bw._one_of_each_per_seed(deck, 2)]
    assert sorted(dealt) == sorted("AABCBC")
    assert all(dealt[i] != dealt[i + 1] for i in range(0, 6, 2))
    with pytest.raises(ValueError, match="hidden_per_seed = 2"):
        bw._one_of_each_per_seed([Card("A")] * 4, 2)


def test_a_hidden_world_is_its_seeds_null_plus_what_it_plants(bw):
    plan = bw.load_plan(CONFIG)
    ws = bw.worlds(plan)
    nulls = {w["seed"]: w for w in ws if w["truth"] is None}
    for w in ws:
        if w["truth"] is None:
            assert not any(k.startswith("planted.") for k in w["drawn"])
            continue
        null = nulls[w["seed"]]
        base = {k: v for k, v in w["drawn"].items() if not k.startswith("planted.")}
        assert base == null["drawn"]
        planted = {k.split(".")[1] for k in w["drawn"] if k.startswith("planted.")}
        assert {n for n, e in w["synth"].effects.items() if e != null["synth"].effects.get(n)} == planted


def test_the_judged_truth_is_the_planted_draw_in_the_fitted_parameters_unit(bw):
    plan = bw.load_plan(CONFIG)
    fams = {f.name: f for f in plan.family}
    seen = set()
    for w in bw.worlds(plan) + bw.worlds(plan, fresh=True):
        t = w["truth"]
        if not t or "parameter" not in t:
            continue
        fam = fams[t["effect"]]
        drawn = w["drawn"][f"planted.{fam.planted.effect}.{fam.truth}"]
        span = fam.planted.params[fam.truth]
        assert span.lo <= drawn <= span.hi
        if fam.per_cent_of_rpm:
            assert t["value"] == pytest.approx(drawn / 100 * w["synth"].aircraft_constants().nominal_rpm)
        else:
            assert t["value"] == drawn
        seen.add(t["effect"])
    assert {"slow-lag", "rotor-band", "collective-knee", "stick-knee"} <= seen


def test_the_truth_file_holds_the_ground_truth_the_draws_and_the_judged_truth(bw, tmp_path):
    w = next(w for w in bw.worlds(bw.load_plan(CONFIG)) if w["truth"])
    truth = bw.world_truth(w)
    assert truth["drawn"] == w["drawn"] and truth["judged"] == w["truth"]
    assert set(truth["hidden"]) >= {k.split(".")[1] for k in w["drawn"] if k.startswith("planted.")}
    json.dumps(truth)  # a file


@pytest.mark.parametrize("old, new, needle", [
    ("fresh = { first = 9200", "fresh = { first = 105", "overlap"),
    ('name = "sideslip"', 'name = "yaw-rate"', "each name once"),
    ('truth = "tau_s"', 'truth = "tau"', "truth 'tau' is not a drawn parameter"),
    ("law = 0.3 ", "lawn = 0.3 ", "lawn"),
    ("[protocol]", "[protocl]", "protocl"),
])
def test_a_plans_mistake_is_an_error_naming_it(bw, tmp_path, old, new, needle):
    text = CONFIG.read_text()
    assert old in text
    path = tmp_path / "worlds.toml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(ConfigError, match=needle):
        bw.load_plan(path)
