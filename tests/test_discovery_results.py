"""Discovery's outcome as typed records: frozen, and an effect's discovery.json entry keeps
the fields its readers know and adds its test and its parameters' intervals; a model worse
with its named effects than without is flagged."""

import dataclasses

import pandas as pd
import pytest

from pvvjax.discovery import Candidate, Discovery, Effect, Round, summary


def _effect(**kw):
    c = Candidate("threshold", ("collective_pct",), {"knee": 62.3456789})
    base = dict(rank=1, round=1, name="collective knee", operator="threshold", channels=("collective_pct",),
                parameters={"knee": 62.3456789, "side": "above"}, explained_fraction=0.123456, p_value=0.0012345,
                region={"where": "pullup", "before_rms_g": 0.0412345678, "after_rms_g": 0.0301234567}, key=c.key,
                candidate=c, found_in="all", statistic=4.56789, intervals={"knee": (61.01234567, 63.7654321)},
                tied=("threshold:shaft_power_hp:knee=900",))
    return Effect(**{**base, **kw})


def test_an_effects_entry_keeps_discovery_json_fields_and_adds_its_test():
    js = _effect().summary()
    assert list(js) == ["rank", "name", "operator", "channels", "parameters", "explained_fraction", "p_value",
                        "region", "kind", "statistic", "adjusted_p", "intervals", "tied"]
    assert js["channels"] == ["collective_pct"] and js["parameters"] == {"knee": 62.345679, "side": "above"}
    assert js["explained_fraction"] == 0.1235 and js["p_value"] == 0.0012 and js["adjusted_p"] == round(0.0012345, 6)
    assert js["region"] == {"where": "pullup", "before_rms_g": 0.041235, "after_rms_g": 0.030123}
    assert js["kind"] == "missing" and js["statistic"] == 4.5679
    assert js["intervals"] == {"knee": [61.012346, 63.765432]} and js["tied"] == ["threshold:shaft_power_hp:knee=900"]


def test_the_records_are_frozen():
    e = _effect()
    res = Discovery("w", "db1", None, None, {}, {}, (e,), pd.DataFrame(), {}, pd.DataFrame(), {},
                    rounds=(Round(1, pd.DataFrame({"round": [1]}), e),))
    for obj, field in ((e, "rank"), (res, "effects"), (res.rounds[0], "named")):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(obj, field, None)


def test_a_model_worse_with_its_named_effects_than_without_is_flagged_in_the_summary():
    m = lambda rms: {"rms_g": rms, "peak_error_g": 0.1, "phase_error_s": 0.5}  # noqa: E731
    worse = Discovery("w", "db1", None, None, m(0.040), m(0.045), (_effect(),), pd.DataFrame(), {}, pd.DataFrame(), {})
    better = dataclasses.replace(worse, after=m(0.030))
    empty = dataclasses.replace(worse, effects=(), after=m(0.045))
    assert summary(worse)["augmented"]["worse_than_baseline"] is True
    assert summary(better)["augmented"]["worse_than_baseline"] is False
    assert summary(empty)["augmented"]["worse_than_baseline"] is False  # nothing named: nothing added
