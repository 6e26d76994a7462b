"""The embedded synthetic campaign: shape, physics trends and calibration to the paper,
all checked through the public pipeline (load_campaign -> build_databases), never by
reading the generator's amplitudes."""

import json

import numpy as np
import pandas as pd
import pytest

from pvvjax.analysis.databases import OUTPUT
from pvvjax.cli import main
from pvvjax.config import ConfigError
from pvvjax.data.campaign import load_campaign, validate_campaign
from pvvjax.synth import EFFECTS, EffectConfig, SynthConfig, _generate, generate, load_synth_config, write_synthetic

PAPER = {"T1-level-135": 0.10, "T1-descent-160": 0.25, "T1-climb-62": 0.12, "T1-turn45-145": 0.13}


def test_default_campaign_covers_the_paper_conditions(default_campaign, default_dbs):
    peaks = default_dbs["peaks"]
    assert len(peaks) >= 220
    kinds = set(default_campaign.counters.maneuver)
    assert kinds == {"level", "climb", "descent", "turn", "roll", "pushover", "pullup", "autorotation", "flare"}
    maneuver_fraction = (np.abs(peaks.mlf - 1) > 0.05).mean()
    assert 0.2 <= maneuver_fraction <= 0.35
    lv = peaks[peaks.maneuver == "level"]
    assert lv.airspeed_kt.min() < 15 and lv.airspeed_kt.max() > 160
    assert lv.gross_weight_lb.min() < 14500 and lv.gross_weight_lb.max() > 21500
    assert lv.density_ratio.min() < 0.8 and lv.density_ratio.max() >= 0.99
    rpm = lv.rotor_rpm / 257.8
    assert rpm.min() < 0.96 and rpm.max() > 1.04
    assert (peaks[peaks.maneuver == "descent"].airspeed_kt > 155).any()
    assert (peaks[peaks.maneuver == "descent"].airspeed_kt < 80).any()
    # every autorotation is two counters with shaft power cut and restored
    for cs in default_campaign.conditions().values():
        if default_campaign.counters.loc[cs[0], "maneuver"] == "autorotation":
            assert len(cs) == 2
            p1, p2 = (default_campaign.records[c].shaft_power_hp for c in cs)
            assert p1.iloc[0] > 300 and p1.iloc[-1] < 50 and p2.iloc[-1] > 300


def test_records_length_and_sampling(default_campaign):
    for name, r in default_campaign.records.items():
        t = r.time_s.to_numpy()
        assert 20.0 <= t[-1] + (t[1] - t[0]) <= 40.01, name
        samples_per_rev = 60.0 / (t[1] - t[0]) / r.rotor_rpm.max()
        assert samples_per_rev >= 64, (name, samples_per_rev)


@pytest.mark.parametrize("cid", list(PAPER))
def test_table1_conditions_match_the_paper(default_dbs, cid):
    row = default_dbs["peaks"].set_index("condition").loc[cid]
    assert row[OUTPUT] == pytest.approx(PAPER[cid], abs=0.02)


def test_pullup_11022_matches_the_paper(default_dbs):
    row = default_dbs["peaks"].set_index("condition").loc["11022"]
    assert row.counter == "11022"
    assert row.mlf == pytest.approx(2.0, abs=0.1)
    assert row[OUTPUT] == pytest.approx(0.22, abs=0.02)
    assert row.gross_weight_lb == 16055.0
    assert row.advance_ratio == pytest.approx(0.27, abs=0.015)
    assert row.collective_pct == pytest.approx(76, abs=4) and row.longitudinal_pct == pytest.approx(57, abs=4)


def test_autorotation_ar60_peaks_in_the_recovery_segment(default_dbs, default_campaign):
    row = default_dbs["peaks"].set_index("condition").loc["AR60"]
    assert default_campaign.conditions()["AR60"] == ["11539", "11540"]
    assert row.counter == "11540"
    assert row[OUTPUT] == pytest.approx(0.26, abs=0.03)
    assert row.peak_time_s > 10.0  # post-autorotation phase: power back after 10 s of segment 2
    p1 = default_campaign.records["11539"].set_index("time_s").shaft_power_hp
    assert p1.loc[:9.5].min() > 500 and p1.loc[12.0:].max() < 100  # power cut just before 10 s


def test_physical_trends_in_level_flight(default_dbs):
    pk = default_dbs["peaks"]
    sweep = pk[pk.condition.str.startswith("LS15k")].set_index("airspeed_kt")[OUTPUT].sort_index()
    v = sweep.index.to_numpy()
    transition = sweep[(v > 20) & (v < 55)].max()
    bucket = sweep[(v > 70) & (v < 120)].min()
    high = sweep[v > 155].max()
    assert bucket < 0.75 * transition and bucket < 0.5 * high
    heavy = pk[pk.condition.str.startswith("LS20k")].set_index("airspeed_kt")[OUTPUT].sort_index()
    assert (heavy.to_numpy() >= sweep.to_numpy() - 0.005).mean() > 0.8  # heavier: more vibration


def test_trim_sticks_vary_with_speed_and_weight(default_dbs):
    pk = default_dbs["peaks"]
    lv = pk[pk.condition.str.startswith("LS")]
    assert np.corrcoef(lv.airspeed_kt, lv.longitudinal_pct)[0, 1] > 0.95
    light, heavy = (lv[lv.gross_weight_lb == w].set_index("airspeed_kt") for w in (15000.0, 20000.0))
    assert (heavy.collective_pct - light.collective_pct).dropna().gt(0).all()
    # collective alone does not identify weight across the campaign (db3 really lacks it)
    level = pk[pk.maneuver == "level"]
    assert abs(np.corrcoef(level.collective_pct, level.gross_weight_lb)[0, 1]) < 0.6


def test_same_seed_same_data_and_subsets_match_the_full_campaign(default_campaign):
    cfg = SynthConfig(conditions=("11022", "R003"))
    a, b = generate(cfg)[1], generate(cfg)[1]
    for k in a:
        pd.testing.assert_frame_equal(a[k], b[k])
    full = default_campaign.records["11022"]
    np.testing.assert_allclose(a["11022"].az_g.to_numpy(), full.az_g.to_numpy(), rtol=1e-6)
    other = generate(SynthConfig(conditions=("11022",), seed=1))[1]["11022"]
    assert not np.allclose(other.az_g.to_numpy(), a["11022"].az_g.to_numpy())


def test_effects_change_vibration_only():
    base = generate(SynthConfig(conditions=("11022",)))[1]["11022"]
    off = {"dynamic_stall": EffectConfig(enabled=False)}
    no_stall = generate(SynthConfig(conditions=("11022",), effects=off))[1]["11022"]
    pd.testing.assert_frame_equal(base.drop(columns="az_g"), no_stall.drop(columns="az_g"))
    diff = (base.az_g - no_stall.az_g).abs()
    assert diff[base.time_s.between(12, 16)].max() > 0.05 and diff[base.time_s < 8].max() < 1e-6


def _harmonic(r, axis, k):
    """Amplitude of harmonic k of one axis over a whole record, g."""
    return 2 * abs(np.mean(r[axis] * np.exp(-1j * k * np.deg2rad(r.azimuth_deg))))


def test_the_horizontal_axes_are_switchable_effects_that_leave_the_vertical_alone():
    # A steady 45-degree turn: the lateral N/rev carries the bank effect; switching it off lowers the lateral
    # only. Track and balance is the 1/rev of both horizontal axes, at its set amplitude.
    cfg = lambda **e: SynthConfig(conditions=("T1-turn45-145",), noise_g=0.0, effects=e)  # noqa: E731
    base = generate(cfg())[1]["T1-turn45-145"]
    no_bank = generate(cfg(lateral_bank=EffectConfig(enabled=False)))[1]["T1-turn45-145"]
    no_tb = generate(cfg(track_balance=EffectConfig(enabled=False)))[1]["T1-turn45-145"]
    pd.testing.assert_frame_equal(base.drop(columns="ay_g"), no_bank.drop(columns="ay_g"))
    assert _harmonic(base, "ay_g", 4) - _harmonic(no_bank, "ay_g", 4) > 0.15  # 0.25·sin 45°, less the lag's ramp
    tb = EFFECTS["track_balance"].params
    for axis in "xy":
        assert _harmonic(base, f"a{axis}_g", 1) == pytest.approx(tb[f"a_{axis}"], rel=0.05)
        assert _harmonic(no_tb, f"a{axis}_g", 1) < 0.1 * tb[f"a_{axis}"]
    pd.testing.assert_frame_equal(base.drop(columns=["ax_g", "ay_g"]), no_tb.drop(columns=["ax_g", "ay_g"]))


def test_lateral_peaks_in_flares_and_turns_and_longitudinal_follows_the_vertical(default_dbs_axes):
    peaks = default_dbs_axes
    y = peaks["ay_g"].groupby("maneuver")[OUTPUT].median()
    assert y[["flare", "turn", "roll"]].min() > 2 * y["level"] and y.max() < 0.35
    z, x = peaks["az_g"], peaks["ax_g"]
    level = (z["maneuver"] == "level").to_numpy()
    # Longitudinal follows the vertical's advance-ratio trend in level flight, lower.
    assert np.corrcoef(z[OUTPUT][level], x[OUTPUT][level])[0, 1] > 0.8
    assert (x[OUTPUT] < z[OUTPUT]).mean() > 0.9


def test_vibration_weight_changes_the_vibration_only():
    # 11022 flies at 16055 lb: holding the vibration's weight there changes nothing; heavier, only
    # the acceleration changes, and its 4P grows (blade loading and its stall knee).
    cfg = lambda w: SynthConfig(conditions=("11022",), vibration_weight_lb=w)  # noqa: E731
    own, same, heavy = (generate(cfg(w))[1]["11022"] for w in (None, 16055.0, 21000.0))
    pd.testing.assert_frame_equal(own, same)
    accel = ["az_g", "ax_g", "ay_g"]
    pd.testing.assert_frame_equal(own.drop(columns=accel), heavy.drop(columns=accel))
    p4 = lambda r: abs(np.mean(r.az_g * np.exp(-4j * np.deg2rad(r.azimuth_deg))))  # noqa: E731
    assert p4(heavy) > 1.1 * p4(own)


def test_hidden_effect_scenario_writes_truth_outside_the_campaign(tmp_path):
    cfg_file = tmp_path / "scenario.toml"
    cfg_file.write_text('name = "hidden-sideslip"\nseed = 2\nconditions = ["R001", "T001"]\n'
                        '[effects.sideslip]\nenabled = true\nscale = 1.5\n')
    cfg = load_synth_config(cfg_file)
    folder, truth = write_synthetic(tmp_path / "camp", cfg)
    assert truth == tmp_path / "camp.truth.json" and truth.exists()
    assert not any("truth" in p.name for p in folder.rglob("*"))
    t = json.loads(truth.read_text())
    assert t["hidden"] == ["sideslip"]
    e = {x["name"]: x for x in t["effects"]}
    assert e["sideslip"]["enabled"] and e["sideslip"]["scale"] == 1.5 and e["sideslip"]["formula"]
    assert validate_campaign(folder) == []
    with pytest.raises(ValueError, match="must not be inside"):
        write_synthetic(tmp_path / "c2", cfg, truth_path=tmp_path / "c2" / "truth.json")


@pytest.mark.parametrize("text, needle", [
    ("[effects.stall]\nenabled = false", "effects.stall: unknown effect"),
    ("[effects.dynamic_lag.params]\ntau = 1.0", "effects.dynamic_lag.params: unknown ['tau']"),
    ("[counts]\nhover = 3", "counts.hover: unknown maneuver"),
    ("sample_rate_hz = 100.0", "fewer than 64 samples per revolution"),
    ("sample_rate_hz = 1e7", "sample_rate_hz 1e+07: at most 20000 Hz"),
    ("scatter = -1.0", "scatter is a standard deviation: must be >= 0"),
    ("vibration_weight_lb = 0.0", "vibration_weight_lb: must be > 0 lb, got 0.0"),
])
def test_generator_config_errors(tmp_path, text, needle):
    p = tmp_path / "s.toml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=None) as e:
        load_synth_config(p)
    assert needle in str(e.value) and str(p) in str(e.value)


def test_every_effect_is_documented_and_switchable():
    for e in EFFECTS.values():
        assert e.formula and e.physics and e.kind in ("additive", "gain", "lag", "once_per_rev")
    required = {"transition", "high_speed", "blade_loading", "dynamic_stall", "descent_bvi", "rotor_resonance",
                "dynamic_lag", "pitch_rate", "roll_rate"}
    assert required <= set(EFFECTS)


def test_synth_cli_with_plots(tmp_path, capsys):
    cfg_file = tmp_path / "s.toml"
    cfg_file.write_text('conditions = ["11022", "AR60", "LS15k-100", "LS20k-100"]\n')
    rc = main(["synth", "--out", str(tmp_path / "c"), "--config", str(cfg_file), "--seed", "4",
               "--plots", str(tmp_path / "fig")])
    assert rc == 0
    assert load_campaign(tmp_path / "c").provenance["seed"] == 4
    for f in ("pvv_vs_airspeed.png", "pullup_11022.png", "autorotation_AR60.png"):
        assert (tmp_path / "fig" / f).stat().st_size > 10_000


def test_shipped_scenario_configs_load_and_differ_from_default():
    from pathlib import Path

    from pvvjax.synth import ground_truth

    folder = Path(__file__).parents[1] / "experiments" / "configs" / "scenarios"
    hidden = {p.stem: ground_truth(load_synth_config(p))["hidden"] for p in sorted(folder.glob("*.toml"))}
    assert hidden == {"long-lag": ["dynamic_lag"], "null": [], "pitch-acceleration": ["pitch_acceleration"],
                      "sideslip": ["sideslip"]}


def test_concurrent_callers_generate_a_cached_campaign_once(tmp_path, monkeypatch):
    # Two test workers asking for the default campaign on a cold cache: the second waits for
    # the first's folder instead of generating it again.
    import threading
    import time

    from pvvjax.synth import cached_campaign

    calls, write = [], _generate.write_synthetic

    def slow(*args, **kwargs):
        calls.append(1)
        time.sleep(0.5)  # both callers are inside cached_campaign by then
        return write(*args, **kwargs)

    monkeypatch.setattr(_generate, "write_synthetic", slow)
    cfg = SynthConfig(name="pair", conditions=("11022",))
    got = []
    threads = [threading.Thread(target=lambda: got.append(cached_campaign(cfg, tmp_path))) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(calls) == 1 and got[0] == got[1] and len(load_campaign(got[0])) == 1
    assert cached_campaign(cfg, tmp_path) == got[0] and len(calls) == 1


# The JSBSim AH-1S's rotor (aircraft/ah1s: 44 ft diameter, 2 blades, 324 rpm, 2.25 ft chord).
AH1S = dict(blades=2, rotor_radius_ft=22.0, nominal_rpm=324.0, chord_ft=2.25, solidity=0.06511)


@pytest.mark.parametrize("blades", [2, 3, 4])
def test_the_rotors_low_harmonics_stay_below_the_blade_passage(blades):
    # The 1/rev and 2/rev of track and balance: on a two-bladed rotor 2/rev is N/rev, the
    # vibration law's alone, so only the 1/rev is left there.
    psi = np.linspace(0.0, 2 * np.pi * 16, 16 * 256, endpoint=False)
    low = _generate.rotor_harmonics(psi, blades, (0.03, 0.05), (0.4, 1.1))
    spectrum = np.abs(np.fft.rfft(low)) * 2 / psi.size  # amplitude at k/rev is bin 16 k
    expect = {1: 0.03, 2: 0.05 if blades > 2 else 0.0}
    for k in range(1, 9):
        assert spectrum[16 * k] == pytest.approx(expect.get(k, 0.0), abs=1e-12), k


@pytest.mark.check
def test_a_two_bladed_campaign_vibrates_at_2_per_rev_end_to_end(small_dbs):
    """synth -> harmonics -> databases on a 2-bladed rotor: 2/rev dominates the floor signal,
    the databases take it by default, and by similarity the peaks are the UH-60A campaign's."""
    from conftest import SMALL_COUNTS

    from pvvjax.analysis import analyze, build_databases
    from pvvjax.config import AnalysisConfig
    from pvvjax.data.batch import to_batch
    from pvvjax.synth import cached_campaign

    cfg = SynthConfig(name="small-2-bladed", counts=SMALL_COUNTS, sample_rate_hz=400.0, aircraft=AH1S)
    camp = load_campaign(cached_campaign(cfg))
    assert (camp.aircraft.blades, camp.aircraft.nominal_rpm, camp.aircraft.rotor_radius_ft) == (2, 324.0, 22.0)
    batch = to_batch(camp, [])
    level = {}
    for k in range(1, 9):
        w = analyze(batch, 8.0, harmonic=k)
        level[k] = float(np.median(np.asarray(w.amplitude)[np.asarray(w.valid)]))
    others = max(v for k, v in level.items() if k != 2)
    assert level[2] > 3 * others  # N/rev dominates
    assert level[4] > 5 * max(level[k] for k in (3, 5, 6, 7, 8))  # and 2N/rev is there (1P, 2P beside)
    dbs = build_databases(camp)  # the analysed harmonic defaults to the blade count
    peaks = dbs["peaks"].set_index("condition")
    uh60 = small_dbs["peaks"].set_index("condition").loc[peaks.index]
    ratio = (peaks[OUTPUT] / uh60[OUTPUT]).to_numpy()
    assert 0.95 < float(np.median(ratio)) < 1.05
    # Condition by condition too: the N/rev holds the vibration law alone (a 2/rev of random
    # phase per condition on it put a tenth of the conditions 18 % or more away).
    assert np.quantile(np.abs(ratio - 1.0), 0.9) < 0.06
    np.testing.assert_allclose(peaks.advance_ratio, uh60.advance_ratio, rtol=0.06)
    assert 0.55 < float(np.median(peaks.gross_weight_lb / uh60.gross_weight_lb)) < 0.57  # the same C_W/σ
    at_4 = build_databases(camp, AnalysisConfig(harmonic=4))["peaks"].set_index("condition")
    assert float(np.median(at_4[OUTPUT] / peaks[OUTPUT])) < 0.4


def test_aircraft_constants_are_checked():
    with pytest.raises(ValueError, match="aircraft.rotor_diameter_ft: unknown constant"):
        SynthConfig(aircraft=dict(rotor_diameter_ft=44.0))
    with pytest.raises(ValueError, match="aircraft.blades: must be a whole number"):
        SynthConfig(aircraft=dict(blades=2.5))
    with pytest.raises(ValueError, match="at least 397 Hz"):
        SynthConfig(aircraft=AH1S)  # 320 Hz is too slow for 64 samples per revolution at 324 rpm
