import jax.numpy as jnp
import numpy as np
import pandas as pd
import pytest
from conftest import tiny_records, write_tiny

from pvvjax.analysis.databases import DB_INPUTS, META_COLUMNS, OUTPUT, build_databases, condition_peaks, peak_table
from pvvjax.cli import main
from pvvjax.config import AnalysisConfig
from pvvjax.data.campaign import campaign_from_frames


def test_condition_peaks_against_brute_force():
    rng = np.random.default_rng(0)
    B, W, K = 17, 9, 6
    amp = rng.uniform(0, 1, (B, W))
    valid = rng.uniform(0, 1, (B, W)) > 0.3
    valid[:, 0] = True
    cond = rng.integers(0, K, B)
    cond[:K] = np.arange(K)
    pk = condition_peaks(jnp.asarray(amp), jnp.asarray(valid), jnp.asarray(cond), num_conditions=K)
    for k in range(K):
        best = max(((amp[b, w], b, w) for b in range(B) for w in range(W) if cond[b] == k and valid[b, w]))
        assert float(pk.value[k]) == pytest.approx(best[0])
        assert (int(pk.counter[k]), int(pk.window[k])) == (best[1], best[2])


def _two_segment_campaign():
    c, r = tiny_records(n_counters=3, seconds=16.0)
    c["condition"] = ["AR", "AR", "LV"]
    c["segment"] = [1, 2, 1]
    c["maneuver"] = ["autorotation", "autorotation", "level"]
    # segment 2 holds the condition's peak, in its third window, with a pitch rate there
    rec = r["C2"]
    w = rec.time_s.between(3.75, 5.5)
    rec.loc[w, "az_g"] += 0.2 * np.cos(4 * 2 * np.pi * 257.8 / 60 * rec.time_s[w] + 0.4)
    rec.loc[w, "pitch_rate_dps"] = 9.6
    return campaign_from_frames(c, r)


def test_peak_of_a_condition_spanning_two_counters():
    camp = _two_segment_campaign()
    peaks, windows = peak_table(camp)
    ar = peaks.set_index("condition").loc["AR"]
    assert ar.counter == "C2"
    assert ar[OUTPUT] == pytest.approx(windows[windows.condition == "AR"].pvv_g.max())
    assert ar[OUTPUT] > 0.25
    assert 3.75 < ar.peak_time_s < 5.5
    assert ar.pitch_rate_dps > 5.0 and ar.mlf > 1.5  # inputs taken at the peak window
    assert peaks.set_index("condition").loc["LV", "counter"] == "C3"


def test_inputs_mean_vs_center():
    camp = _two_segment_campaign()
    mean = peak_table(camp, AnalysisConfig(inputs="mean"))[0].set_index("condition").loc["AR"]
    center = peak_table(camp, AnalysisConfig(inputs="center"))[0].set_index("condition").loc["AR"]
    assert mean[OUTPUT] == center[OUTPUT]
    # the pitch-rate pulse covers most but not all of the window: the mean is lower than the centre value
    assert center.pitch_rate_dps == pytest.approx(9.6)
    assert 5.0 < mean.pitch_rate_dps < 9.6


def test_databases_have_exactly_the_contract_columns():
    dbs = build_databases(_two_segment_campaign())
    for name, inputs in DB_INPUTS.items():
        assert list(dbs[name].columns) == list(META_COLUMNS) + list(inputs) + [OUTPUT]
        assert len(dbs[name]) == 2
    assert DB_INPUTS["db3"] == tuple(i for i in DB_INPUTS["db2"] if i != "gross_weight_lb")
    assert dbs["db1"].window_revs.eq(8.0).all()


def test_build_db_cli_writes_csv_and_parquet(tmp_path, capsys):
    folder = write_tiny(tmp_path / "camp")
    out = tmp_path / "dbs"
    assert main(["build-db", "--campaign", str(folder), "--out", str(out)]) == 0
    for name in ("db1", "db2", "db3"):
        a = pd.read_csv(out / f"{name}.csv")
        b = pd.read_parquet(out / f"{name}.parquet")
        pd.testing.assert_frame_equal(a, b, check_dtype=False)
    assert (out / "config.toml").exists()
    text = capsys.readouterr().out
    assert "wrote db1, db2, db3" in text and "az_g 4/rev: " in text
    # The tiny campaign has only az_g: its 1/rev, 4/rev and 8/rev peak tables; 4/rev's are db1's peaks.
    assert sorted(p.name for p in (out / "axes").glob("*.csv")) == [f"peaks-az_g-{k}rev.csv" for k in (1, 4, 8)]
    pd.testing.assert_frame_equal(pd.read_csv(out / "axes" / "peaks-az_g-4rev.csv")[["condition", OUTPUT]],
                                  pd.read_csv(out / "peaks.csv")[["condition", OUTPUT]], rtol=1e-5)


def test_validate_cli_exit_codes(tmp_path, capsys):
    folder = write_tiny(tmp_path / "ok")
    assert main(["validate", "--campaign", str(folder)]) == 0
    c, r = tiny_records()
    c.loc[0, "maneuver"] = "hover"
    r["C2"].loc[5, "rotor_rpm"] = -1.0
    bad = write_tiny(tmp_path / "bad", c, r)
    assert main(["validate", "--campaign", str(bad)]) == 1
    out = capsys.readouterr().out
    assert "2 problem(s)" in out and "'maneuver', row 1" in out
    assert "timeseries/C2.csv, column 'rotor_rpm', row 6" in out
    assert main(["build-db", "--campaign", str(bad), "--out", str(tmp_path / "x")]) == 2
    assert "2 problem(s)" in capsys.readouterr().err


def test_cli_config_error_is_a_message_not_a_traceback(tmp_path, capsys):
    cfgfile = tmp_path / "bad.toml"
    cfgfile.write_text("[analysis]\nwindow_revz = 8\n")
    assert main(["validate", "--campaign", str(tmp_path), "--config", str(cfgfile)]) == 2
    err = capsys.readouterr().err
    assert "bad.toml: analysis.window_revz: unknown key" in err and "Traceback" not in err


def test_one_long_record_costs_its_own_memory_and_moves_no_other_peak(small_campaign_dir, monkeypatch):
    # A recording twelve times as long as the others: batched alone (memory in proportion to the samples,
    # not the longest record times every record) by the databases and by every axis table build-db writes,
    # and every other condition's peak is bitwise unchanged.
    import pvvjax.analysis.databases as databases
    from pvvjax.analysis import PADDING_LIMIT, axes_database, axis_peak_tables, length_groups, peak_table
    from pvvjax.data.campaign import load_campaign

    lengths = np.array([6000] * 70 + [72000])
    keys = length_groups(lengths)
    padded = sum(lengths[keys == k].max() * (keys == k).sum() for k in np.unique(keys))
    assert lengths.max() * len(lengths) > PADDING_LIMIT * lengths.sum() and padded <= 2 * lengths.sum()
    assert (length_groups([6000, 7000, 9000]) == 0).all()  # alike: one batch

    campaign = load_campaign(small_campaign_dir)
    before, _ = peak_table(campaign)
    k = "T1-level-135"
    r = campaign.records[k]
    turns = np.unwrap(np.deg2rad(r.azimuth_deg.to_numpy()))
    span = turns[-1] - turns[0] + (turns[1] - turns[0])
    long = pd.concat([r] * 12, ignore_index=True)
    long["time_s"] = np.arange(len(long)) * float(r.time_s.iloc[1] - r.time_s.iloc[0])
    long["azimuth_deg"] = np.rad2deg(np.concatenate([turns + i * span for i in range(12)])) % 360.0
    tables = axis_peak_tables(campaign)
    campaign.records[k] = long
    shapes = []
    to_batch = databases.to_batch
    monkeypatch.setattr(databases, "to_batch", lambda *a, **kw: shapes.append(to_batch(*a, **kw).time.shape)
                        or to_batch(*a, **kw))
    samples = sum(len(r) for r in campaign.records.values())

    def padded(run):  # the samples of every batch `run` builds, padding included
        shapes.clear()
        out = run()
        assert sum(b * t for b, t in shapes) <= 2 * samples, shapes
        return out

    after, _ = padded(lambda: peak_table(campaign))
    others = (before.condition != campaign.counters.loc[k, "condition"]).to_numpy()
    np.testing.assert_array_equal(before[others].peak_pvv_g.to_numpy(), after[others].peak_pvv_g.to_numpy())
    for key, table in padded(lambda: axis_peak_tables(campaign)).items():
        keep = table.condition != campaign.counters.loc[k, "condition"]
        np.testing.assert_array_equal(tables[key][keep].peak_pvv_g, table[keep].peak_pvv_g, err_msg=str(key))
    padded(lambda: axes_database(campaign))


# Every channel the analysis reads from a time series: the acceleration axes, the azimuth and time, and the
# state channels the databases take at the peak window.
READ_CHANNELS = ("time_s", "azimuth_deg", "az_g", "ax_g", "ay_g", "airspeed_kt", "rotor_rpm", "pitch_rate_dps",
                 "roll_angle_deg", "climb_rate_fpm", "collective_pct", "lateral_pct", "longitudinal_pct")


def test_one_sample_glitch_in_one_record_moves_no_other_conditions_row_for_any_channel(small_campaign_dir):
    # A logger glitch in one sample of one record, in each channel the analysis reads, inside that condition's
    # peak window: the databases' and every axis table's rows of every other condition are bitwise unchanged
    # (each record's window plan and the harmonics resolved come from each record's own typical sampling).
    from pvvjax.analysis import axis_peak_tables
    from pvvjax.data.campaign import load_campaign

    campaign = load_campaign(small_campaign_dir).subset(
        ["T1-level-135", "11022", "T1-climb-62", "T1-descent-160", "T1-turn45-145"])

    def tables(c):
        out = build_databases(c)
        out.update({f"{a} {k}/rev": t for (a, k), t in axis_peak_tables(c).items()})
        return out

    base = tables(campaign)
    k = "11022"
    rec = campaign.records[k]
    i = int(np.searchsorted(rec.time_s.to_numpy(), base["peaks"].set_index("counter").peak_time_s[k]))
    moved = []
    for channel in READ_CHANNELS:
        col = rec[channel].to_numpy().copy()
        if channel == "time_s":
            col[i] += 0.3 * (col[i + 1] - col[i])
        elif channel == "azimuth_deg":
            col[i] = 0.0  # the logger glitch of the trial that found it
        else:
            col[i] = 1.5 * col[i] + 1.0
        glitched = campaign.subset(campaign.names)
        glitched.records[k] = rec.assign(**{channel: col})
        out = tables(glitched)
        assert set(out) == set(base), channel
        for name, before in base.items():
            after = out[name]
            pd.testing.assert_frame_equal(before[before.condition != k].reset_index(drop=True),
                                          after[after.condition != k].reset_index(drop=True),
                                          check_exact=True, obj=f"{name} with {channel} glitched")
        if not all(out[name][out[name].condition == k].equals(t[t.condition == k]) for name, t in base.items()):
            moved.append(channel)
    assert moved == list(READ_CHANNELS)  # each glitch reached its own record: the test can fail
