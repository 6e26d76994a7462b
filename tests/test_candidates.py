"""Candidate library: window means against dense numerical integration, the spread against
NumPy's standard deviation, operators against their formulas, the library's contents."""

import numpy as np
import pandas as pd
import pytest

from pvvjax.discovery import _model, candidates
from pvvjax.discovery.candidates import Candidate, describe, from_key, interval_means, library, values, window_table


def test_interval_means_integrate_the_linear_interpolant():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.5, 1.5, 200)) * 0.01
    s = np.sin(7 * t) + rng.normal(0, 0.1, t.size)
    t0 = rng.uniform(t[0], t[-1] - 0.3, 25)
    t1 = t0 + rng.uniform(0.01, 0.3, 25)
    dense = []
    for a, b in zip(t0, t1):
        tt = np.linspace(a, b, 20001)
        dense.append(np.trapezoid(np.interp(tt, t, s), tt) / (b - a))
    np.testing.assert_allclose(interval_means(s, t, t0, t1), dense, atol=1e-7)
    two = interval_means(np.stack([s, 2 * s], 1), t, t0, t1)
    np.testing.assert_allclose(two[:, 1], 2 * two[:, 0], rtol=1e-12)


def _campaign(tiny):
    from pvvjax.data.campaign import campaign_from_frames

    counters, recs = tiny
    for r in recs.values():  # channels that vary, and one that takes both signs
        r["pitch_rate_dps"] = 3.0 * np.sin(0.9 * r.time_s)
        r["airspeed_kt"] = r.airspeed_kt + 5.0 * r.time_s
    return campaign_from_frames(counters, recs)


def test_window_table_columns_match_numpy(tiny):
    c = _campaign(tiny)
    name = c.names[0]
    rec = c.records[name]
    t = rec.time_s.to_numpy()
    iv = pd.DataFrame({"counter": name, "t0": [t[10], t[200]], "t1": [t[10] + 1.0, t[200] + 0.5]})
    tab = window_table(c, iv)
    x = rec.pitch_rate_dps.to_numpy(float)
    # Sample-exact intervals: the interpolant's mean is the trapezoid mean.
    for j, (a, b) in enumerate(zip(iv.t0, iv.t1)):
        sel = (t >= a - 1e-12) & (t <= b + 1e-12)
        if abs(t[sel][-1] - b) > 1e-9:
            continue
        assert tab["x:pitch_rate_dps"].iloc[j] == pytest.approx(np.trapezoid(x[sel], t[sel]) / (b - a), abs=1e-9)
    assert {"x:advance_ratio", "x:blade_loading", "rate:roll_angle_deg", "spread:rotor_rpm"} <= set(tab.columns)
    assert "x:az_g" not in tab.columns and "x:time_s" not in tab.columns
    # The spread of a window is the standard deviation of the interpolant: for a constant, 0.
    assert np.all(tab["spread:gross_weight_lb"] == 0.0)


def test_spread_of_a_ramp():
    t = np.linspace(0, 1, 1001)
    x = 3.0 * t
    m = interval_means(np.stack([x, x * x], 1), t, np.array([0.0]), np.array([1.0]))[0]
    assert np.sqrt(m[1] - m[0] ** 2) == pytest.approx(3.0 / np.sqrt(12.0), rel=1e-5)


def test_operators_and_names():
    tab = pd.DataFrame({"x:collective_pct": [50.0, 60.0, 70.0], "abs:roll_rate_dps": [1.0, 2.0, 3.0],
                        "x:rotor_rpm": [250.0, 258.0, 270.0], "x:advance_ratio": [0.1, 0.2, 0.3]})
    th = Candidate("threshold", ("collective_pct",), {"knee": 62.0, "above": True, "softness": 1e-6})
    np.testing.assert_allclose(values(th, tab), [0.0, 0.0, 8.0], atol=1e-5)
    res = Candidate("resonance", ("rotor_rpm",), {"center": 258.0, "width": 4.0})
    np.testing.assert_allclose(values(res, tab), np.exp(-0.5 * ((tab["x:rotor_rpm"] - 258.0) / 4.0) ** 2))
    pr = Candidate("product", ("collective_pct", "advance_ratio"))
    np.testing.assert_allclose(values(pr, tab), [5.0, 12.0, 21.0])
    mag = Candidate("input", ("roll_rate_dps",), {"transform": "abs"})
    assert describe(mag) == "roll rate magnitude"
    assert describe(Candidate("abs_rate", ("pitch_rate_dps",))) == "pitch acceleration magnitude"
    assert describe(th) == "collective knee (above 62)"
    assert describe(Candidate("abs_rate", ("roll_angle_deg",))) == "roll angle rate magnitude"
    assert th.key == "threshold:collective_pct:above=True,knee=62,softness=1e-06"


def test_names_tell_every_channels_candidates_apart():
    # A name shared by two candidates (the roll-rate channel and the rate of the roll angle
    # were both "roll rate") makes a round's proposals and runners-up unreadable.
    _WORDS = candidates._WORDS

    chans = [*_WORDS, "rotor_torque_pct"]  # and a channel without words of its own
    cands = [c for ch in chans for c in (
        Candidate("input", (ch,)), Candidate("input", (ch,), {"transform": "abs"}), Candidate("rate", (ch,)),
        Candidate("abs_rate", (ch,)), Candidate("window", (ch,)),
        Candidate("threshold", (ch,), {"knee": 1.5, "above": True}), Candidate("resonance", (ch,), {"center": 1.5}))]
    cands += [Candidate("product", (a, b)) for a in chans for b in chans if a < b]
    names = {}
    for c in cands:
        assert names.setdefault(describe(c), c.key) == c.key, (describe(c), names[describe(c)], c.key)


def test_from_key_reads_back_every_operators_key(tiny):
    lib = library(window_table(_campaign(tiny), pd.DataFrame({"counter": [_campaign(tiny).names[0]] * 3,
                                                               "t0": [0.5, 1.5, 2.5], "t1": [2.5, 3.5, 4.5]})))
    more = [Candidate("lag", (), {"tau_s": 2.0}), Candidate("product", ("collective_pct", "advance_ratio")),
            Candidate("threshold", ("shaft_power_hp",), {"knee": 1339.2, "above": False, "softness": 35.11}),
            Candidate("resonance", ("rotor_rpm",), {"center": 270.7, "width": 3.222, "gain_unit": 10.0,
                                                    "shape": "lorentzian"})]
    for c in [*lib, *more]:
        back = from_key(c.key)
        assert (back.operator, back.channels, back.key) == (c.operator, c.channels, c.key)
        for k, v in c.parameters.items():  # floats to the key's four digits, flags and words as they were
            assert type(back.parameters[k]) is (float if isinstance(v, (int, float)) and not isinstance(v, bool)
                                                else type(v))
            if isinstance(v, float):
                assert back.parameters[k] == pytest.approx(v, rel=5e-4)
            else:
                assert back.parameters[k] == v
    assert from_key("lag::tau_s=3").channels == ()
    # at full precision from the parameters the rounds table keeps beside the key
    knee = Candidate("threshold", ("collective_pct",), {"knee": 63.258312, "above": True,
                                                          "softness": np.float32(0.9405), "n": np.int64(3)})
    back = from_key(knee.key, knee.parameters_json)
    assert back.parameters == {"knee": 63.258312, "above": True, "softness": float(np.float32(0.9405)), "n": 3}
    assert from_key(knee.key).parameters["knee"] == 63.26  # the key alone: four digits
    for bad in ("threshold", "threshold:x:knee", ":x", "a:b:c:d"):
        with pytest.raises(ValueError, match="candidate key"):
            from_key(bad)


def test_library_leaves_out_the_model_inputs_as_plain_inputs(tiny):
    c = _campaign(tiny)
    iv = pd.DataFrame({"counter": [n for n in c.names for _ in range(5)],
                       "t0": np.tile(np.linspace(0.5, 5, 5), len(c.names))}).assign(t1=lambda d: d.t0 + 2.0)
    tab = window_table(c, iv)
    lib = library(tab, model_inputs=("advance_ratio", "rotor_rpm"))
    keys = {x.key for x in lib}
    assert "input:advance_ratio" not in keys and "input:airspeed_kt" in keys
    assert "input:pitch_rate_dps:transform=abs" in keys  # a signed channel's magnitude
    assert {x.operator for x in lib} >= {"input", "rate", "abs_rate", "window", "threshold"}
    assert all(x.operator != "resonance" or x.channels == ("rotor_rpm",) for x in lib)
    # Lorentzian bands carry their shape (the Gaussian's keys stay as they were).
    bands = [x for x in lib if x.operator == "resonance"]
    assert bands and all("shape" not in x.parameters for x in bands)
    lor = [x for x in library(tab, model_inputs=("advance_ratio",), resonance_shape="lorentzian")
           if x.operator == "resonance"]
    assert [x.parameters["shape"] for x in lor] == ["lorentzian"] * len(bands)
    assert [x.parameters["center"] for x in lor] == [x.parameters["center"] for x in bands]
    u = (tab["x:rotor_rpm"].to_numpy() - lor[0].parameters["center"]) / lor[0].parameters["width"]
    np.testing.assert_allclose(values(lor[0], tab), 1.0 / (1.0 + u * u))


def test_rate_over_a_revolution_follows_the_maneuver_not_the_sensor_noise():
    _rate = candidates._rate

    rng = np.random.default_rng(1)
    t = np.arange(0, 20, 1 / 320)  # the synthetic campaigns' sample rate
    q = 8.0 * np.sin(2 * np.pi * 0.2 * t)  # a pitch maneuver, deg/s
    qdot = 8.0 * 2 * np.pi * 0.2 * np.cos(2 * np.pi * 0.2 * t)
    noisy = q + rng.normal(0, 0.1, t.size)  # 0.1 deg/s of sensor noise
    inner = (t > 1) & (t < 19)
    true = np.mean(np.abs(qdot[inner]))
    # Sample-to-sample differences: the noise dominates the magnitude of the derivative.
    assert np.mean(np.abs(np.gradient(noisy, t)[inner])) > 3 * true
    # Over one revolution (0.233 s): within 3 % of the true mean |q̇|, and exact for a ramp.
    assert np.mean(np.abs(_rate(noisy, t, 60 / 257.8)[inner])) == pytest.approx(true, rel=0.03)
    np.testing.assert_allclose(_rate(2.5 * t, t, 0.25), 2.5, rtol=1e-9)


def test_rate_of_many_columns_equals_numpys_interpolation_column_by_column():
    _rate = candidates._rate

    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.002, 0.004, 3000))  # uneven samples
    t[100:103] = t[100] + 0.0025 * np.arange(3)  # evenly spaced: span edges land on samples
    x = np.stack([np.sin(t), rng.standard_normal(t.size), 1e4 + t**2], 1)
    span = 0.005
    lo, hi = np.clip(t - span / 2, t[0], t[-1]), np.clip(t + span / 2, t[0], t[-1])
    for c in range(x.shape[1]):
        ref = (np.interp(hi, t, x[:, c]) - np.interp(lo, t, x[:, c])) / np.maximum(hi - lo, 1e-12)
        np.testing.assert_array_equal(_rate(x, t, span)[:, c], ref)  # the same numbers, not close ones
        np.testing.assert_array_equal(_rate(x[:, c], t, span), ref)


def test_window_tables_of_several_offsets_equal_one_table_each(tiny):
    _Windows = _model._Windows
    from pvvjax.discovery.candidates import window_tables

    c = _campaign(tiny)
    rows = []
    for name in c.names:
        t = c.records[name].time_s.to_numpy()
        rows += [(name, a, a + 0.8) for a in np.arange(t[0] + 0.3, t[-1] - 1.0, 0.45)]
    iv = pd.DataFrame(rows, columns=["counter", "t0", "t1"], index=np.arange(len(rows))[::-1])  # any index
    moved = iv.assign(t0=iv.t0 - 0.37, t1=iv.t1 - 0.37)
    both = window_tables(c, [iv, moved])
    for tab, ref in zip(both, (window_table(c, iv), window_table(c, moved))):
        pd.testing.assert_frame_equal(tab, ref, check_exact=True)
        assert tab.attrs == ref.attrs
    with pytest.raises(ValueError, match="share their index"):
        window_tables(c, [iv, moved.iloc[1:]])
    # Discovery's replayed windows fetch the tables of a round's offsets in one pass.
    win = _Windows(iv.assign(maneuver="level"), (1, len(iv)), (), c, offset=0.2)
    win.prefetch([0.2, 0.57, 0.57])
    assert win._cands is not None and set(win._shifted) == {0.57}
    pd.testing.assert_frame_equal(win.at(0.57), window_table(c, win._shift(0.57)), check_exact=True)
    pd.testing.assert_frame_equal(win.cands, window_table(c, iv), check_exact=True)


def test_a_few_windows_of_a_long_record_equal_the_same_windows_of_the_whole_record(tiny):
    # One window per record (discovery's training windows) integrates only the samples it and
    # its rates reach; against the same windows among others spanning each record (integrated
    # from its start): the same means, rates and spreads, at the record's ends as well.
    c = _campaign(tiny)
    (a, b), (ta, tb) = c.names[:2], (c.records[n].time_s.to_numpy() for n in c.names[:2])
    few = pd.DataFrame({"counter": [a, a, b], "t0": [ta[0] - 0.3, 2.0, tb[-1] - 0.6],
                        "t1": [ta[0] + 0.7, 2.9, tb[-1] + 0.4]})
    fill = [(n, s, s + 1.0) for n in (a, b) for s in np.arange(0.0, c.records[n].time_s.iloc[-1], 0.5)]
    whole = pd.concat([few, pd.DataFrame(fill, columns=["counter", "t0", "t1"])], ignore_index=True)
    got, ref = window_table(c, few), window_table(c, whole).iloc[:3]
    assert np.abs(got["rate:pitch_rate_dps"]).min() > 0.1 and np.abs(got["spread:airspeed_kt"]).min() > 0.1
    np.testing.assert_allclose(got.to_numpy(), ref.to_numpy(), rtol=1e-9, atol=1e-9)
    # A window without times is NaN, and leaves the others as they were.
    blank = pd.concat([few, pd.DataFrame({"counter": [b], "t0": [np.nan], "t1": [np.nan]})], ignore_index=True)
    out = window_table(c, blank)
    assert out.iloc[3].isna().all()
    np.testing.assert_allclose(out.iloc[:3].to_numpy(), ref.to_numpy(), rtol=1e-9, atol=1e-9)
