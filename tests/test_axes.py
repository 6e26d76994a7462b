"""Harmonics of three pilot-floor axes in one windowed pass, against numpy.fft and against
the one-axis analysis."""

import hashlib

import numpy as np
import pandas as pd
import pytest
from conftest import tiny_records

from pvvjax.analysis import (
    AXES,
    OUTPUT,
    analyze,
    analyze_axes,
    axes_database,
    axis_peak_tables,
    build_databases,
    resolved_harmonics,
)
from pvvjax.config import AnalysisConfig
from pvvjax.data.batch import to_batch
from pvvjax.data.campaign import campaign_from_frames

SPR, RPM, NREV = 64, 257.8, 48


def _three_axis_campaign(spr=SPR):
    """One counter sampled uniformly in azimuth, each axis its own 1/rev, 4/rev and 8/rev."""
    rng = np.random.default_rng(3)
    n = NREV * spr
    t = np.arange(n) / (spr * RPM / 60.0)
    psi = 2 * np.pi * np.arange(n) / spr
    axes = {
        "az_g": 1.0 + 0.03 * np.cos(psi + 1.0) + 0.12 * np.cos(4 * psi + 0.3) + 0.02 * np.cos(8 * psi - 1.0),
        "ax_g": -0.05 + 0.02 * np.cos(psi + 0.6) + 0.05 * np.cos(4 * psi - 2.0) + 0.01 * np.cos(8 * psi + 2.5),
        "ay_g": 0.01 + 0.035 * np.cos(psi + 2.2) + 0.2 * np.cos(4 * psi + 1.4) + 0.04 * np.cos(8 * psi),
    }
    axes = {k: v + 0.01 * rng.standard_normal(n) for k, v in axes.items()}
    rec = pd.DataFrame({"time_s": t, "azimuth_deg": np.mod(np.rad2deg(psi), 360.0), "rotor_rpm": RPM,
                        "airspeed_kt": 100.0, "pitch_rate_dps": 0.0, "roll_angle_deg": 0.0, "climb_rate_fpm": 0.0,
                        "collective_pct": 50.0, "lateral_pct": 50.0, "longitudinal_pct": 55.0, **axes})
    counters = pd.DataFrame([dict(counter="C1", maneuver="level", gross_weight_lb=16000.0, density_ratio=1.0)])
    return campaign_from_frames(counters, {"C1": rec}), axes


@pytest.mark.parametrize("L", [4, 8])
def test_every_axis_and_harmonic_matches_numpy_fft(L):
    campaign, axes = _three_axis_campaign()
    batch = to_batch(campaign, ["airspeed_kt"], axis=AXES)
    harmonics = (1, 4, 8)
    win = analyze_axes(batch, harmonics, float(L))
    amp, phase = np.asarray(win.amplitude)[0], np.asarray(win.phase)[0]  # (A, H, W)
    n = L * SPR
    for j in range(NREV // L):
        assert bool(np.asarray(win.valid)[0, j])
        for a, name in enumerate(AXES):
            X = np.fft.rfft(axes[name][j * n:(j + 1) * n])
            for h, k in enumerate(harmonics):
                np.testing.assert_allclose(amp[a, h, j], 2 * np.abs(X[k * L]) / n, rtol=2e-4, atol=2e-6)
                np.testing.assert_allclose(phase[a, h, j], np.angle(X[k * L]), atol=2e-4)


def test_one_pass_equals_the_one_axis_analysis_of_each_axis():
    campaign, _ = _three_axis_campaign()
    win = analyze_axes(to_batch(campaign, ["airspeed_kt"], axis=AXES), (4,), 8.0, 2.0)
    for a, name in enumerate(AXES):
        one = analyze(to_batch(campaign, ["airspeed_kt"], axis=name), 8.0, 2.0)
        sel = win.select(a, 0)
        np.testing.assert_allclose(sel.amplitude, one.amplitude, rtol=1e-5, atol=1e-7)
        np.testing.assert_array_equal(sel.valid, one.valid)
        np.testing.assert_allclose(sel.means, one.means, rtol=1e-6)


def test_harmonics_the_sampling_cannot_resolve_are_left_out():
    campaign, _ = _three_axis_campaign(spr=20)  # 20 samples per revolution: up to 9/rev
    batch = to_batch(campaign, [], axis=AXES)
    assert resolved_harmonics(batch, (1, 4, 8, 10, 16), 8.0) == (1, 4, 8)
    assert resolved_harmonics(batch, (1, 4), 0.5) == ()


# sha256 of the databases of tiny_records(3 counters, 20 s), computed before the analysis took
# other axes: a campaign with only az_g must give these databases bit for bit.
TODAY = "6e02dc07d9a712e57e1dbd2b30e5b0399128fe76bfe31d3e86bf60e6c1d0cc9d"


def _digest(dbs) -> str:
    h = hashlib.sha256()
    for name in sorted(dbs):
        df = dbs[name]
        h.update(name.encode())
        h.update(",".join(df.columns).encode())
        for col in df.columns:
            h.update(pd.util.hash_pandas_object(df[col], index=False).to_numpy().tobytes())
    return h.hexdigest()


def test_a_vertical_only_campaign_gives_todays_databases_bit_for_bit():
    c, r = tiny_records(n_counters=3, seconds=20.0)
    assert _digest(build_databases(campaign_from_frames(c, r))) == TODAY


def test_a_peak_table_per_axis_and_harmonic_equals_the_databases_of_that_axis():
    campaign, axes = _three_axis_campaign()
    tables = axis_peak_tables(campaign, AnalysisConfig())
    assert list(tables) == [(a, k) for a in AXES for k in (1, 4, 8)]
    for (axis, k), table in tables.items():
        peaks = build_databases(campaign, AnalysisConfig(axis=axis, harmonic=k))["peaks"]
        pd.testing.assert_frame_equal(table, peaks, rtol=1e-5)
    assert tables["ay_g", 4][OUTPUT].iloc[0] == pytest.approx(0.2, abs=0.01)
    assert tables["ax_g", 1][OUTPUT].iloc[0] == pytest.approx(0.02, abs=0.01)


def test_an_axis_the_campaign_lacks_is_an_error_naming_it():
    c, r = tiny_records(n_counters=2)
    with pytest.raises(ValueError, match="analysis.axis = 'ay_g': campaign .* has no ay_g"):
        build_databases(campaign_from_frames(c, r), AnalysisConfig(axis="ay_g"))
    assert list(axis_peak_tables(campaign_from_frames(c, r))) == [("az_g", 1), ("az_g", 4), ("az_g", 8)]


def test_the_axes_database_has_each_axis_peak_row_with_every_axis_in_that_window():
    campaign, _ = _three_axis_campaign()
    rows = axes_database(campaign)
    tables = axis_peak_tables(campaign, harmonics=(4,))
    assert list(rows.peak_axis) == list(AXES)  # one condition: one row per axis
    for axis in AXES:
        row = rows[rows.peak_axis == axis].iloc[0]
        peak = tables[axis, 4].iloc[0]
        assert row[axis] == pytest.approx(peak[OUTPUT], rel=1e-6)
        assert row.peak_time_s == pytest.approx(peak.peak_time_s) and row.advance_ratio == pytest.approx(
            peak.advance_ratio, rel=1e-6)
        # an axis's value in another axis's peak window is no more than its own peak
        assert (rows[axis] <= row[axis] + 1e-7).all()


def test_the_dynamic_models_sequences_and_the_replay_records_analyse_the_configured_axis():
    from pvvjax.analysis import STATE_CHANNELS
    from pvvjax.dynamics import window_sequences
    from pvvjax.replay.quasistatic import prepare

    campaign, _ = _three_axis_campaign()
    seq = window_sequences(campaign, ["advance_ratio"], window_revs=2.0, hop_revs=1.0, axis="ay_g")
    one = analyze(to_batch(campaign, STATE_CHANNELS, axis="ay_g"), 2.0, 1.0)
    valid = np.asarray(one.valid)[0]
    np.testing.assert_allclose(seq.amplitude[0][seq.mask[0]], np.asarray(one.amplitude)[0][valid], rtol=1e-6)
    assert seq.amplitude[0][seq.mask[0]].mean() == pytest.approx(0.2, abs=0.02)  # the lateral 4/rev, not the vertical
    batch = to_batch(campaign, STATE_CHANNELS, axis="ay_g")
    cols = np.asarray(prepare(batch).columns.cols)  # (B, T, n): acceleration x cos, x sin, cos, sin, the acceleration
    np.testing.assert_array_equal(cols[0, :, 4], np.asarray(batch.accel)[0])
