"""Campaign loading and validation (data-contract §1): one test per bad-input kind."""

import numpy as np
import pandas as pd
import pytest
from conftest import tiny_records, write_tiny

from pvvjax.config import ColumnMap
from pvvjax.data.campaign import CampaignError, campaign_from_frames, load_campaign, validate_campaign


def _problems(folder, **kw):
    return [str(p) for p in validate_campaign(folder, **kw)]


def _only(problems, *needles):
    assert len(problems) == 1, problems
    for n in needles:
        assert n in problems[0], problems[0]


def test_valid_campaign_loads_with_constants_broadcast_and_azimuth(tmp_path):
    folder = write_tiny(tmp_path / "c")
    assert validate_campaign(folder) == []
    camp = load_campaign(folder)
    assert len(camp) == 2 and camp.names == ("C1", "C2")
    r = camp.records["C1"]
    assert (r.gross_weight_lb == 16000.0).all() and (r.density_ratio == 1.0).all()
    # azimuth integrated from rotor speed: 257.8 rpm -> 1546.8 deg/s
    dt = r.time_s.diff().iloc[1]
    assert np.diff(np.unwrap(r.azimuth_deg, period=360.0))[:5] == pytest.approx(257.8 * 6 * dt, rel=1e-6)
    assert r.azimuth_deg.between(0, 360).all()
    assert camp.counters.loc["C1", "condition"] == "C1" and camp.counters.loc["C1", "segment"] == 1


def test_parquet_and_csv_give_the_same_campaign(tmp_path):
    a = load_campaign(write_tiny(tmp_path / "csv", fmt="csv"))
    b = load_campaign(write_tiny(tmp_path / "pq", fmt="parquet"))
    ra, rb = a.records["C2"], b.records["C2"]
    pd.testing.assert_frame_equal(ra.drop(columns="azimuth_deg"), rb.drop(columns="azimuth_deg"), rtol=1e-6, atol=1e-9)
    unwrap = lambda s: np.unwrap(s.to_numpy(), period=360.0)  # noqa: E731  (360 deg and 0 deg are one azimuth)
    np.testing.assert_allclose(unwrap(ra.azimuth_deg), unwrap(rb.azimuth_deg), atol=1e-4)


def test_given_azimuth_is_kept(tmp_path):
    c, r = tiny_records()
    r["C1"]["azimuth_deg"] = np.mod(np.arange(len(r["C1"])) * 5.625 + 10.0, 360.0)
    camp = load_campaign(write_tiny(tmp_path / "c", c, r))
    assert camp.records["C1"].azimuth_deg.iloc[0] == 10.0


def test_missing_required_column(tmp_path):
    c, r = tiny_records()
    r["C2"] = r["C2"].drop(columns="airspeed_kt")
    _only(_problems(write_tiny(tmp_path / "c", c, r)), "timeseries/C2.csv", "'airspeed_kt'", "required column missing")


def test_missing_counter_column(tmp_path):
    c, r = tiny_records()
    _only(_problems(write_tiny(tmp_path / "c", c.drop(columns="maneuver"), r)), "counters.csv", "'maneuver'", "missing")


def test_weight_missing_everywhere(tmp_path):
    c, r = tiny_records()
    _only(_problems(write_tiny(tmp_path / "c", c.drop(columns="gross_weight_lb").iloc[:1], {"C1": r["C1"]})),
          "'gross_weight_lb'", "or as a constant in counters.csv")


def test_channel_in_both_places(tmp_path):
    c, r = tiny_records()
    r["C1"]["density_ratio"] = 1.0
    _only(_problems(write_tiny(tmp_path / "c", c, r)), "timeseries/C1.csv", "'density_ratio'",
          "both here and in counters.csv")


def test_duplicate_counter(tmp_path):
    c, r = tiny_records()
    c = pd.concat([c, c.iloc[[0]]], ignore_index=True)
    _only(_problems(write_tiny(tmp_path / "c", c, r)), "counters.csv", "'counter', row 3", "duplicate counter 'C1'")


def test_counter_without_timeseries_file(tmp_path):
    c, r = tiny_records()
    del r["C2"]
    _only(_problems(write_tiny(tmp_path / "c", c, r)), "counters.csv", "row 2", "'C2' has no file")


def test_timeseries_file_without_counter(tmp_path):
    c, r = tiny_records()
    _only(_problems(write_tiny(tmp_path / "c", c.iloc[:1], r)), "timeseries/C2.csv", "no counter 'C2'")


@pytest.mark.parametrize("value, needle", [("abc", "non-numeric value 'abc'"),
                                           (np.nan, "missing, NaN or infinite value (nan)"),
                                           (np.inf, "missing, NaN or infinite value (inf)")])
def test_bad_values_in_required_channel(tmp_path, value, needle):
    c, r = tiny_records()
    df = r["C1"].astype({"pitch_rate_dps": object})
    df.loc[41, "pitch_rate_dps"] = value
    r["C1"] = df
    _only(_problems(write_tiny(tmp_path / "c", c, r)), "timeseries/C1.csv", "'pitch_rate_dps', row 42", needle)


def test_time_not_strictly_increasing(tmp_path):
    c, r = tiny_records()
    t = r["C1"].time_s.to_numpy().copy()
    t[100] = t[99]
    r["C1"]["time_s"] = t
    _only(_problems(write_tiny(tmp_path / "c", c, r)), "'time_s', row 101", "not strictly increasing")


def test_time_not_uniform(tmp_path):
    c, r = tiny_records()
    t = r["C1"].time_s.to_numpy().copy()
    t[500:] += 0.5 * (t[1] - t[0])
    r["C1"]["time_s"] = t
    _only(_problems(write_tiny(tmp_path / "c", c, r)), "'time_s', row 501", "not uniform")


def test_record_shorter_than_one_window(tmp_path):
    c, r = tiny_records()
    r["C1"] = r["C1"].iloc[:300]  # 300 samples at 64/rev < 8 revs
    _only(_problems(write_tiny(tmp_path / "c", c, r)), "timeseries/C1.csv", "shorter than one analysis window (8 revs)")
    assert validate_campaign(tmp_path / "c", window_revs=4.0) == []


@pytest.mark.parametrize("column, value, where", [
    ("collective_pct", 101.0, "timeseries"), ("lateral_pct", -1.0, "timeseries"),
    ("longitudinal_pct", 120.0, "timeseries"),
    ("rotor_rpm", 0.0, "timeseries"), ("roll_angle_deg", 95.0, "timeseries"),
    ("density_ratio", 1.4, "counters"), ("density_ratio", 0.2, "counters"), ("gross_weight_lb", 0.0, "counters"),
])
def test_values_outside_physical_ranges(tmp_path, column, value, where):
    c, r = tiny_records()
    if where == "counters":
        c.loc[1, column] = value
        expect = ("counters.csv", f"'{column}', row 2")
    else:
        r["C2"].loc[7, column] = value
        expect = ("timeseries/C2.csv", f"'{column}', row 8")
    _only(_problems(write_tiny(tmp_path / "c", c, r)), *expect, "outside the physical range")


def test_unknown_maneuver(tmp_path):
    c, r = tiny_records()
    c.loc[1, "maneuver"] = "loop"
    _only(_problems(write_tiny(tmp_path / "c", c, r)), "counters.csv", "'maneuver', row 2", "unknown maneuver 'loop'")


def test_every_problem_is_reported_at_once(tmp_path):
    c, r = tiny_records()
    c.loc[0, "maneuver"] = "hover"
    r["C1"] = r["C1"].drop(columns="az_g")
    r["C2"].loc[3, "collective_pct"] = 150.0
    r["C3"] = r["C2"]
    probs = _problems(write_tiny(tmp_path / "c", c, r))
    assert len(probs) == 4, probs
    with pytest.raises(CampaignError) as e:
        load_campaign(tmp_path / "c")
    assert len(e.value.problems) == 4 and "4 problem(s)" in str(e.value)


def test_missing_folder_and_counters_file(tmp_path):
    _only(_problems(tmp_path / "nothing"), "campaign folder not found")
    (tmp_path / "empty" / "timeseries").mkdir(parents=True)
    _only(_problems(tmp_path / "empty"), "counters.csv", "file missing")


def test_campaign_toml_overrides_aircraft_and_refuses_unknown_keys(tmp_path):
    folder = write_tiny(tmp_path / "c")
    (folder / "campaign.toml").write_text("[aircraft]\nrotor_radius_ft = 20.0\n[provenance]\nsource = 'x'\n")
    camp = load_campaign(folder)
    assert camp.aircraft.rotor_radius_ft == 20.0 and camp.aircraft.blades == 4 and camp.provenance["source"] == "x"
    (folder / "campaign.toml").write_text("[aircraft]\nrotor_radius = 20.0\n")
    _only(_problems(folder), "campaign.toml", "aircraft.rotor_radius: unknown key")


def test_column_mapping_renames_and_converts(tmp_path):
    c, r = tiny_records()
    for df in r.values():
        df["V_ms"] = df.pop("airspeed_kt") / 1.943844
        df["q_rads"] = np.deg2rad(df.pop("pitch_rate_dps") + 3.0)
    c = c.rename(columns={"gross_weight_lb": "mass_kg"})
    c["mass_kg"] = c["mass_kg"] * 0.45359237
    folder = write_tiny(tmp_path / "c", c, r)
    assert any("airspeed_kt" in str(p) for p in validate_campaign(folder))
    mapping = {"V_ms": ColumnMap("airspeed_kt", "m/s"), "q_rads": ColumnMap("pitch_rate_dps", "rad/s"),
               "mass_kg": ColumnMap("gross_weight_lb", "kg")}
    camp = load_campaign(folder, mapping)
    rec = camp.records["C2"]
    assert rec.airspeed_kt.to_numpy() == pytest.approx(101.0, rel=1e-6)
    assert rec.pitch_rate_dps.to_numpy() == pytest.approx(3.0, rel=1e-6)
    assert rec.gross_weight_lb.to_numpy() == pytest.approx(16000.0, rel=1e-9)


def test_mapping_onto_an_existing_column_is_refused(tmp_path):
    c, r = tiny_records()
    r["C1"]["V_ms"] = 50.0
    folder = write_tiny(tmp_path / "c", c, r)
    probs = _problems(folder, mapping={"V_ms": ColumnMap("airspeed_kt", "m/s")})
    _only(probs, "timeseries/C1.csv", "'V_ms'", "maps to 'airspeed_kt', which the file also has")


def test_in_memory_campaign_has_same_checks():
    c, r = tiny_records()
    camp = campaign_from_frames(c, r)
    assert camp.names == ("C1", "C2")
    r["C1"] = r["C1"].drop(columns="az_g")
    with pytest.raises(CampaignError, match="'az_g'"):
        campaign_from_frames(c, r)


def test_conditions_group_segments_in_order():
    c, r = tiny_records(n_counters=3)
    c["condition"] = ["A", "A", "B"]
    c["segment"] = [2, 1, 1]
    camp = campaign_from_frames(c, r)
    assert camp.conditions() == {"A": ["C2", "C1"], "B": ["C3"]}


def test_horizontal_axes_are_optional_channels_checked_and_kept(tmp_path):
    """`ax_g`/`ay_g` in g (about 0 g, a vibration below the vertical's) validate and load; the
    vertical's databases are those of the same campaign without them."""
    from pvvjax.analysis.databases import build_databases

    c, r = tiny_records(n_counters=3)
    plain = load_campaign(write_tiny(tmp_path / "plain", c, r))
    rng = np.random.default_rng(0)
    three = {k: v.assign(ax_g=0.5 * (v.az_g - 1.0) + 0.002 * rng.standard_normal(len(v)),
                         ay_g=0.05 + 0.3 * (v.az_g - 1.0)) for k, v in r.items()}
    folder = write_tiny(tmp_path / "three", c, three)
    assert [p for p in validate_campaign(folder) if not p.warning] == []
    camp = load_campaign(folder)
    assert {"ax_g", "ay_g"} <= set(camp.records["C1"].columns)
    for name, df in build_databases(plain).items():
        pd.testing.assert_frame_equal(build_databases(camp)[name], df)
