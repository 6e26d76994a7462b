import dataclasses
import textwrap

import pytest

from pvvjax.config import AnalysisConfig, ColumnMap, ConfigError, ExperimentConfig, config_hash, load_config
from pvvjax.data.units import conversion_factor


def _write(tmp_path, text):
    p = tmp_path / "exp.toml"
    p.write_text(textwrap.dedent(text))
    return p


def test_full_config_round_trip(tmp_path):
    p = _write(tmp_path, """
        name = "x"
        seed = 3
        [campaign]
        path = "some/dir"
        [campaign.columns.V_ms]
        to = "airspeed_kt"
        unit = "m/s"
        [analysis]
        window_revs = 6.5
        taper_revs = 0.5
        inputs = "center"
    """)
    cfg = load_config(p)
    assert cfg.name == "x" and cfg.seed == 3
    assert cfg.analysis.window_revs == 6.5 and cfg.analysis.hop == 6.5
    assert cfg.campaign.columns["V_ms"].factor() == pytest.approx(1.943844, rel=1e-6)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.seed = 4


@pytest.mark.parametrize("text, needle", [
    ("nmae = 'x'", "nmae: unknown key (did you mean 'name'?)"),
    ("[analysis]\nwindow_rev = 8.0", "analysis.window_rev: unknown key (did you mean 'window_revs'?)"),
    ("[analysis]\nwindow_revs = 'eight'", "analysis.window_revs: expected a number"),
    ("[analysis]\nharmonic = 4.5", "analysis.harmonic: expected an integer"),
    ("[analysis]\nwindow_revs = -1.0", "window_revs must be > 0"),
    ("[analysis]\ninputs = 'median'", "analysis.inputs: 'median' is not one of"),
    ("[campaign.columns.V]\nto = 'airspeed_kt'\nunit = 'deg'", "cannot be converted"),
    ("[campaign.columns.V]\nto = 'airspeed_kt'\nunit = 'furlong/fortnight'", "unknown unit"),
    ("seed = true", "seed: expected an integer"),
    ("[discovery]\ntrain_rows = 'window'", "discovery.train_rows: 'window' is not one of 'peaks', 'windows'"),
    ("[discovery]\nband_shape = 'cauchy'", "discovery.band_shape: 'cauchy' is not one of 'gaussian', 'lorentzian'"),
    ("[discovery]\ntrain_stride = 0", "discovery.train_stride must be >= 1"),
    ("[discovery]\nlag_test_taus = [0.5, 1.0]", "discovery.lag_test_taus must be > 0 with at least one above "
                                               "discovery.lag_fast_s (1.0), got [0.5, 1.0]"),
    ("[discovery]\nlag_test = 'yes'", "discovery.lag_test: expected"),
    ("[discovery]\nlag_slow_s = 0.0", "discovery.lag_slow_s must be > 0 s, got 0.0"),
    ("[discovery]\nlag_learn_steps = 0", "discovery.lag_learn_steps must be >= 1, got 0"),
    ("[discovery]\nshrink_noise = 1.5", "discovery.shrink_noise must lie in [0, 1), got 1.5"),
    ("[discovery]\ntie_share = -0.1", "discovery.tie_share must lie in [0, 1], got -0.1"),
    ("[discovery]\nfloor_refinements = -1", "discovery.floor_refinements must be >= 0, got -1"),
    ("[discovery]\nalpha = 1.5", "discovery.alpha must lie in (0, 1), got 1.5"),
    ("[discovery]\nprobe_alpha = 0", "discovery.probe_alpha must lie in (0, 1), got 0"),
    ("[discovery]\ndatabase = 'db4'", "discovery.database: unknown ['db4']; use db1, db2, db3"),
    ("[discovery]\ncandidate_offsets_s = [0.5, -1.0]", "discovery.candidate_offsets_s must be >= 0 s, got [0.5, -1.0]"),
    ("name = ", "not valid TOML"),
])
def test_config_errors_name_file_and_key(tmp_path, text, needle):
    p = _write(tmp_path, text)
    with pytest.raises(ConfigError) as e:
        load_config(p)
    assert str(p) in str(e.value)
    assert needle in str(e.value)


def test_missing_config_file(tmp_path):
    with pytest.raises(ConfigError, match="no such config file"):
        load_config(tmp_path / "nope.toml")


def test_config_hash_stable_and_sensitive():
    a, b = ExperimentConfig(), ExperimentConfig()
    assert config_hash(a) == config_hash(b)
    assert config_hash(a) != config_hash(a.with_(analysis=AnalysisConfig(window_revs=7.0)))


@pytest.mark.parametrize("unit, canonical, value, expected", [
    ("m/s", "airspeed_kt", 1.0, 1.943844),
    ("rad/s", "pitch_rate_dps", 1.0, 57.29578),
    ("rad/s", "rotor_rpm", 27.0, 257.831),
    ("m/s", "climb_rate_fpm", 1.0, 196.8504),
    ("kg", "gross_weight_lb", 1000.0, 2204.623),
    ("fraction", "collective_pct", 0.5, 50.0),
    ("m/s^2", "az_g", 9.80665, 1.0),
    ("kW", "shaft_power_hp", 745.69987, 1000.0),
])
def test_unit_conversions(unit, canonical, value, expected):
    assert value * conversion_factor(unit, canonical) == pytest.approx(expected, rel=1e-5)


def test_column_map_refuses_wrong_dimension():
    with pytest.raises(ValueError, match="cannot be converted"):
        ColumnMap(to="rotor_rpm", unit="m/s")


def test_a_setting_added_later_at_its_earlier_behaviour_leaves_the_hash_of_tables_written_before_it(tmp_path):
    # A results table written before `encompassing` existed stores a config without it (and
    # without its margin); a config with it off, margin 0 (the earlier behaviour) is the same
    # run; the default (on, margin 0.1) is another rule.
    from pvvjax._strict import to_dict
    from pvvjax.config import load_written_config

    cfg = ExperimentConfig()
    old = cfg.with_(discovery=dataclasses.replace(cfg.discovery, encompassing=False, encompassing_margin=0.0))
    before = to_dict(old)
    del before["discovery"]["encompassing"], before["discovery"]["encompassing_margin"]
    assert config_hash(before) == config_hash(old)
    assert config_hash(cfg) != config_hash(old)
    assert config_hash(cfg.with_(discovery=dataclasses.replace(cfg.discovery, alpha=0.05))) != config_hash(cfg)
    # Read back from such a folder, the missing settings take their earlier values, not
    # today's defaults; a hand-written config that leaves them out gets the defaults.
    p = _write(tmp_path, """
        [discovery]
        alpha = 0.02
    """)
    written = load_written_config(p).discovery
    assert (written.encompassing, written.encompassing_margin, written.alpha) == (False, 0.0, 0.02)
    assert (load_config(p).discovery.encompassing, load_config(p).discovery.encompassing_margin) == (True, 0.1)
    with pytest.raises(ConfigError, match="encompassing_margin"):
        load_config(_write(tmp_path, """
            [discovery]
            encompassing_margin = -0.1
        """))
