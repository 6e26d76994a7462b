"""The public functions check their arguments as the CLI checks a config's keys: a value no
computation could use (a wrong type, a number out of range, a string where a list of names
goes) is one `ArgumentError` that names the function and the argument, before any work; a
NumPy scalar is taken wherever a Python number is. A property test over drawn bad values
keeps it so."""

import math

import jax
import numpy as np
import pandas as pd
import pytest
from conftest import tiny_records
from hypothesis import given, settings
from hypothesis import strategies as st

import pvvjax as P
from pvvjax import ArgumentError


@pytest.fixture(scope="module")
def campaign():
    return P.campaign_from_frames(*tiny_records(n_counters=3, seconds=8.0))


@pytest.fixture(scope="module")
def batch(campaign):
    return P.to_batch(campaign, ["airspeed_kt"])


def _not_a_number():
    return st.one_of(st.text(max_size=4), st.none(), st.booleans(), st.lists(st.integers(), max_size=2),
                     st.sampled_from([math.nan, math.inf, -math.inf, np.float64(math.nan)]))


def _non_positive():
    return st.one_of(_not_a_number(), st.floats(max_value=0.0, allow_nan=False), st.integers(max_value=0),
                     st.integers(min_value=-(2**62), max_value=0).map(np.int64))


def _negative():
    return st.one_of(_not_a_number(), st.floats(max_value=-1e-9, allow_nan=False), st.integers(max_value=-1))


def _not_whole():
    return st.one_of(_not_a_number(), st.floats(allow_nan=False).filter(lambda v: not float(v).is_integer()),
                     st.floats(min_value=1.0, max_value=9.0).map(np.float32))


def _not_a_campaign():
    return st.one_of(st.integers(), st.text(max_size=6), st.none(), st.lists(st.integers(), max_size=2),
                     st.dictionaries(st.text(max_size=2), st.integers(), max_size=1))


def _not_names():
    return st.one_of(st.text(min_size=1, max_size=6), st.integers(), st.none(),
                     st.lists(st.integers(), min_size=1, max_size=2))


# (function, argument, strategy of values it must refuse by name): each call gets the
# argument's drawn value and good values for the rest.
CASES = {
    "to_batch.campaign": (lambda c, b, v: P.to_batch(v, ["airspeed_kt"]), "campaign", _not_a_campaign()),
    "to_batch.channels": (lambda c, b, v: P.to_batch(c, v), "channels", _not_names()),
    "to_batch.min_length": (lambda c, b, v: P.to_batch(c, ["airspeed_kt"], min_length=v), "min_length",
                            st.one_of(_negative(), _not_whole())),
    "peak_table.campaign": (lambda c, b, v: P.peak_table(v), "campaign", _not_a_campaign()),
    "build_databases.analysis": (lambda c, b, v: P.build_databases(c, v), "analysis", _not_a_campaign()),
    "discover.campaign": (lambda c, b, v: P.discover(v), "campaign",
                          _not_a_campaign().filter(lambda v: not isinstance(v, str))),
    "discover.cfg": (lambda c, b, v: P.discover(c, v), "cfg", _not_a_campaign()),
    "load_campaign.folder": (lambda c, b, v: P.load_campaign(v), "folder",
                             _not_a_campaign().filter(lambda v: not isinstance(v, str))),
    "analyze.window_revs": (lambda c, b, v: P.analyze(b, v), "window_revs", _non_positive()),
    "analyze.harmonic": (lambda c, b, v: P.analyze(b, harmonic=v), "harmonic",
                         st.one_of(_not_whole(), st.integers(max_value=0))),
    "make_settings.max_window_revs": (lambda c, b, v: P.make_settings(b, max_window_revs=v), "max_window_revs",
                                      _non_positive()),
    "make_settings.hop_revs": (lambda c, b, v: P.make_settings(b, hop_revs=v), "hop_revs", _negative()),
    "mlp_init.n_in": (lambda c, b, v: P.mlp_init(jax.random.key(0), v, (4,)), "n_in",
                      st.one_of(_not_whole(), st.integers(max_value=0))),
    "mlp_init.hidden": (lambda c, b, v: P.mlp_init(jax.random.key(0), 3, v), "hidden",
                        st.one_of(st.text(min_size=1, max_size=3), st.integers(), st.none(),
                                  st.lists(st.one_of(st.integers(max_value=0), st.floats(0.5, 3.5)), min_size=1,
                                           max_size=2))),
    "condition_folds.k": (lambda c, b, v: P.condition_folds(["a", "b", "c", "d"], v, 0), "k",
                          st.one_of(_not_whole(), st.integers(max_value=2), st.integers(min_value=5))),
}


@pytest.mark.parametrize("case", sorted(CASES))
@settings(max_examples=15, deadline=None)
@given(data=st.data())
def test_a_bad_argument_is_one_error_naming_the_function_and_the_argument(case, campaign, batch, data):
    call, name, bad = CASES[case]
    value = data.draw(bad, label=name)
    with pytest.raises(ArgumentError, match=f"{name} = "):
        call(campaign, batch, value)


def test_numpy_scalars_are_numbers(campaign, batch):
    s = P.make_settings(batch, max_window_revs=np.float32(8.0), min_window_revs=np.int64(4), hop_revs=np.float64(1))
    assert s.plan.n_windows >= 1
    net = P.mlp_init(jax.random.key(0), np.int64(3), (np.int32(4),), n_out=np.int64(1))
    assert net["layers"][0]["w"].shape == (3, 4)
    folds = P.condition_folds(["a", "b", "c", "d"], np.int64(3), np.int64(0))
    assert sorted(set(folds)) == [0, 1, 2]
    assert len(P.to_batch(campaign, np.array(["airspeed_kt"]), min_length=np.int64(0)).channels) == 1


def test_the_error_is_a_type_error_and_a_value_error_and_public():
    # Code that caught a TypeError (a wrong type) or a ValueError (a value out of range) before
    # still catches it.
    assert issubclass(ArgumentError, TypeError) and issubclass(ArgumentError, ValueError)
    assert P.ArgumentError is P.config.ArgumentError


def test_a_batch_beyond_the_machines_memory_is_refused_with_its_estimate_before_any_work(campaign):
    from pvvjax.data.batch import machine_memory

    assert machine_memory() > 2**28
    with pytest.raises(MemoryError, match=r"3 record\(s\) padded to \d+ samples need [\d.e+]+ GiB as one batch, more "
                                          r"than 25% of this machine's"):
        P.to_batch(campaign, ["airspeed_kt"], min_length=10**13)


def test_one_long_record_padding_the_rest_is_warned_about_by_name(monkeypatch):
    # Where a batch pads every record to one long record's length (the replay and discovery batch the whole
    # campaign at once), the long record is named with the memory it costs the rest.
    import warnings

    import pvvjax.data.batch as batch
    from pvvjax.data.campaign import CampaignWarning, campaign_from_frames

    c, r = tiny_records(n_counters=6, seconds=4.0)
    r["C3"] = pd.concat([r["C3"]] * 10, ignore_index=True).assign(time_s=lambda d: np.arange(len(d)) * 0.0036)
    monkeypatch.setattr(batch, "_PADDING_WARN_BYTES", 0)
    with pytest.warns(CampaignWarning, match=r"counter 'C3' \(\d+ samples\) pads the 5 other record\(s\) to its "
                                             r"length: [\d.e+-]+ GiB, [\d.]+x what their samples need"):
        P.to_batch(campaign_from_frames(c, r), ["airspeed_kt"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        P.to_batch(campaign_from_frames(*tiny_records(n_counters=6, seconds=4.0)), ["airspeed_kt"])
