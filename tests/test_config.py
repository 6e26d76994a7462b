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
    ("[discovery]\ntrain_rows = 'windows'", "discovery.train_rows: unknown key; allowed: database, ensemble"),
    ("[discovery]\nseeds = 4", "discovery.seeds: unknown key"),
    ("[discovery.ensemble]\nseed = 4", "discovery.ensemble.seed: unknown key (did you mean 'seeds'?)"),
    ("[discovery.ensemble]\nfolds = 2", "discovery.ensemble.folds = 2: must lie within 3 to 50"),
    ("[discovery.ensemble]\nhidden = [10, 0]", "discovery.ensemble.hidden = [10, 0]: give 1 to 8 layers of 1 to "
                                               "1024 units"),
    ("[discovery]\nlevel = 1.5", "discovery.level must lie in (0, 1) (a family-wise error rate), got 1.5"),
    ("[discovery]\nlevel = 'five percent'", "discovery.level: expected"),
    ("[discovery.selection]\nalpha = 0.05", "discovery.selection: unknown key"),
    ("[discovery.offset]\nbounds = [2.0, 1.0]", "discovery.offset.bounds must be [lo, hi] with lo < hi"),
    ("[discovery]\nlevels = 0.05", "discovery.levels: unknown key (did you mean 'level'?)"),
    ("[discovery]\nsimulation = 'sim_g'", "discovery.simulation and discovery.simulation_inputs go together"),
    ("[discovery]\nsimulation = 'sim_g'\nsimulation_inputs = ['sim_g']", "'sim_g' is the simulation's own output"),
    ("[discovery]\ndatabase = 'db4'", "discovery.database: unknown ['db4']; use db1, db2, db3"),
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


def test_config_hash_is_the_hash_of_every_setting_nested_sections_included(tmp_path):
    cfg = ExperimentConfig()
    assert config_hash(cfg) == config_hash(load_config(_write(tmp_path, "")))
    alpha = cfg.with_(discovery=dataclasses.replace(
        cfg.discovery, ensemble=dataclasses.replace(cfg.discovery.ensemble, seeds=5)))
    assert config_hash(alpha) != config_hash(cfg)
    p = _write(tmp_path, """
        [discovery.ensemble]
        seeds = 5
    """)
    assert load_config(p) == alpha and config_hash(load_config(p)) == config_hash(alpha)


def test_numpy_scalars_are_numbers_like_pythons():
    import numpy as np

    from pvvjax.config import AnalysisConfig, TrainConfig, from_dict

    cfg = from_dict(TrainConfig, {"max_steps": np.int64(50), "learning_rate": np.float32(0.01)})
    assert cfg.max_steps == 50 and type(cfg.max_steps) is int and type(cfg.learning_rate) is float
    assert from_dict(AnalysisConfig, {"window_revs": np.int32(8)}).window_revs == 8.0
    with pytest.raises(ConfigError, match="expected an integer"):
        from_dict(TrainConfig, {"max_steps": np.float64(50.5)})
    with pytest.raises(ConfigError, match="expected an integer"):
        from_dict(TrainConfig, {"max_steps": np.bool_(True)})
