"""JSBSim as the element's host: the property table gives the data contract's channels in their
units, the AH-1S's rotor constants are read from its model, and the example flies the script's
flights with the element (and the C element) in the loop. Needs the `jsbsim` package (the sim
extra, which make test installs)."""

import math

import numpy as np
import pytest
from conftest import SMALL_COUNTS, experiment

from pvvjax.data.constants import KT_TO_FT_S
from pvvjax.realtime import CHANNELS
from pvvjax.realtime.jsbsim import JSBSIM_CHANNELS, frame_channels, jsbsim_aircraft, quiet_stdout

jsbsim = pytest.importorskip("jsbsim", reason="jsbsim is in the sim extra (make test installs it)")


def _fdm_at(t_s: float):
    """The AH-1S script's test variant 1 run to t_s (lifted off, accelerating and climbing)."""
    with quiet_stdout():
        fdm = jsbsim.FGFDMExec(jsbsim.get_default_root_dir())
        fdm.set_debug_level(0)
        fdm.load_script("scripts/ah1s_flight_test.xml")
        fdm["simulation/test-variant"] = 1
        fdm.run_ic()
        while fdm.get_sim_time() < t_s:
            fdm.run()
    return fdm


def test_jsbsim_frames_in_the_data_contract_units():
    fdm = _fdm_at(160.0)
    t, x = frame_channels(fdm)
    ch = dict(zip(CHANNELS, x))
    assert tuple(JSBSIM_CHANNELS) == CHANNELS and t == pytest.approx(160.0, abs=0.01)
    # Each channel against other JSBSim properties than the ones the table reads.
    assert ch["airspeed_kt"] == pytest.approx(fdm["velocities/vt-fps"] / KT_TO_FT_S, rel=1e-3)
    assert ch["climb_rate_fpm"] == pytest.approx(-60.0 * fdm["velocities/v-down-fps"], abs=1.0)
    assert ch["density_ratio"] == pytest.approx(fdm["atmosphere/rho-slugs_ft3"] / fdm["atmosphere/rho-sl-slugs_ft3"])
    assert ch["pitch_rate_dps"] == pytest.approx(math.degrees(fdm["velocities/q-rad_sec"]))
    assert ch["roll_angle_deg"] == pytest.approx(math.degrees(fdm["attitude/phi-rad"]))
    assert 0.95 < ch["rotor_rpm"] / 324.0 < 1.05 and ch["gross_weight_lb"] == pytest.approx(8500.0)
    assert 40.0 < ch["airspeed_kt"] < 80.0 and ch["climb_rate_fpm"] > 300.0
    for stick in ("collective_pct", "lateral_pct", "longitudinal_pct"):  # percent of travel, not fractions
        assert 5.0 < ch[stick] < 95.0


def test_rotor_constants_read_from_the_model(tmp_path):
    root = jsbsim.get_default_root_dir()
    assert jsbsim_aircraft(root, "ah1s") == dict(rotor_radius_ft=22.0, blades=2, nominal_rpm=324.0, chord_ft=2.25,
                                                 solidity=0.06511)
    # A model that does not state its solidity: blades x chord / (pi R), from a rotor in metres.
    folder = tmp_path / "aircraft" / "heli"
    (folder / "Engines").mkdir(parents=True)
    (folder / "heli.xml").write_text('<fdm_config><propulsion><engine file="e"><thruster file="main"/></engine>'
                                     '</propulsion></fdm_config>')
    (folder / "Engines" / "main.xml").write_text(
        '<rotor><diameter unit="M">12.0</diameter><numblades>4</numblades><nominalrpm>300</nominalrpm>'
        '<chord unit="M">0.5</chord></rotor>')
    got = jsbsim_aircraft(tmp_path, "heli")
    assert got["rotor_radius_ft"] == pytest.approx(6.0 / 0.3048) and got["blades"] == 4
    assert got["solidity"] == pytest.approx(4 * 0.5 / (math.pi * 6.0))
    with pytest.raises(ValueError, match="no rotor thruster"):
        jsbsim_aircraft(root, "c172x")


def _fly(tmp_path, monkeypatch, campaign_dir, cfg: dict):
    """Run experiments/jsbsim_flight.py on `cfg` in `tmp_path`; its results folder."""
    import tomli_w

    tmp_path.mkdir(parents=True, exist_ok=True)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PVVJAX_CACHE", str(campaign_dir.parents[1]))
    (tmp_path / "flight.toml").write_text(tomli_w.dumps(cfg))
    assert experiment("jsbsim_flight").main(["flight.toml"]) == 0
    return tmp_path / "runs" / cfg["name"]


# 40 s of a pitch pulse: the micro twins' flight.
_PULSE = {"pitch-pulse": dict(variant=1, end_s=40.0, pulse_at_s=25.0, pulse_s=3.0, pulse_rad=0.3)}


@pytest.mark.check
@pytest.mark.heavy
def test_the_example_flies_the_ah1s_briefly_with_the_axes_element(tmp_path, monkeypatch, small_campaign_dir):
    """The micro twin of the research check below: the axes element (nets of a hundred steps)
    through a short pitch pulse; every seat axis written, the C element equal where there is
    a compiler."""
    import pandas as pd

    out = _fly(tmp_path, monkeypatch, small_campaign_dir,
               dict(name="ah1s", out_dir="runs", counts=SMALL_COUNTS, model="axes",
                    axes=dict(hidden=[4], seeds=1, folds=3), train=dict(max_steps=100), flights=_PULSE))
    table = pd.read_csv(out / "flights.csv").set_index("flight")
    assert list(table.index) == ["pitch-pulse"] and (table.rejected == 0).all()
    assert (table.frame_rate_hz.round(1) == 133.3).all()
    flight = pd.read_parquet(out / "pitch-pulse.parquet")
    assert flight.ready.any() and np.isfinite(flight.shake_g).all() and (out / "flights.png").is_file()
    assert {"pvv_x_g", "pvv_y_g", "pvv_z_g", "shake_y_g"} <= set(flight.columns)
    assert flight[flight.time_s > 25.0].pitch_rate_dps.max() > 4.0
    if "c_minus_numpy_g" in table:
        assert (table.c_minus_numpy_g < 1e-6).all()


@pytest.mark.check
@pytest.mark.heavy
def test_the_example_flies_the_ah1s_briefly_with_the_dynamic_model(tmp_path, monkeypatch, small_campaign_dir):
    """The micro twin of the research check below, through the same short pitch pulse."""
    import pandas as pd

    out = _fly(tmp_path, monkeypatch, small_campaign_dir,
               dict(name="ah1s-dyn", out_dir="runs", counts=SMALL_COUNTS, model="dynamic", train=dict(max_steps=100),
                    dynamic=dict(models=["window_static", "dynamic"], seeds=1, folds=3, kind_holdout=False),
                    flights=_PULSE))
    spec = __import__("json").loads((out / "element" / "element.json").read_text())
    best = pd.read_csv(out / "dynamic" / "comparison.csv").query("best").model.iloc[0]
    assert ("response" in spec) == (best == "dynamic")
    flight = pd.read_parquet(out / "pitch-pulse.parquet")
    assert flight.ready.any() and np.isfinite(flight.pvv_g).all() and (~flight.rejected).all()
    if "c_pvv_g" in flight:
        assert np.abs(flight.c_pvv_g - flight.pvv_g).max() < 1e-6


@pytest.mark.check
def test_the_example_flies_the_ah1s_with_the_element_in_the_loop(tmp_path, monkeypatch, small_campaign_dir):
    """`model = "axes"` (the shipped config's): `pvvjax axes` on the AH-1S campaign, its nets of three
    outputs as the element, three flights; every seat axis written, the C element equal on each."""
    out = _fly(tmp_path, monkeypatch, small_campaign_dir,
               dict(name="ah1s", out_dir="runs", counts=SMALL_COUNTS, model="axes",
                    axes=dict(hidden=[4], seeds=1, folds=3), train=dict(max_steps=200),
                    flights={"flight-test": dict(variant=1, end_s=200.0),
                             "pitch-pulse": dict(variant=1, end_s=200.0, pulse_at_s=180.0, pulse_s=3.0, pulse_rad=0.3),
                             "autorotation": dict(variant=3, end_s=300.0)}))
    import pandas as pd

    table = pd.read_csv(out / "flights.csv").set_index("flight")
    assert list(table.index) == ["flight-test", "pitch-pulse", "autorotation"]
    assert (table.frame_rate_hz.round(1) == 133.3).all() and (table.rejected == 0).all()
    assert (table.out_of_envelope_share > 0).all()  # hover and the autorotation lie outside the campaign
    if "c_minus_numpy_g" in table:
        assert (table.c_minus_numpy_g < 1e-6).all()
    pulse, plain = pd.read_parquet(out / "pitch-pulse.parquet"), pd.read_parquet(out / "flight-test.parquet")
    late = lambda df: df[df.time_s > 180.0]  # noqa: E731
    assert late(pulse).pitch_rate_dps.max() > 4.0 > late(plain).pitch_rate_dps.abs().max()
    auto = pd.read_parquet(out / "autorotation.parquet")
    assert auto.ready.any() and np.isfinite(auto.shake_g).all()
    ready = auto[auto.ready]
    assert (ready[["pvv_x_g", "pvv_y_g", "pvv_z_g"]] > 0).all().all() and (ready.pvv_z_g == ready.pvv_g).all()
    shake_y = ready.shake_y_g.to_numpy()
    assert np.isfinite(shake_y).all() and shake_y.std() > 0
    governed, free = auto[auto.time_s.between(200, 235)], auto[auto.time_s > 245]  # power lost at 240 s
    assert governed.rotor_rpm.std() < 1.0 < free.rotor_rpm.std()
    assert (out / "flights.png").is_file()


@pytest.mark.check
def test_the_example_flies_the_ah1s_with_the_dynamic_model(tmp_path, monkeypatch, small_campaign_dir):
    """`model = "dynamic"`: `pvvjax dynamic` on the AH-1S campaign, its `best` model (the
    window map or the physics-shaped model) exported as the element, through a pitch
    pulse; the C element, where there is a compiler, equals it."""
    import pandas as pd

    out = _fly(tmp_path, monkeypatch, small_campaign_dir,
               dict(name="ah1s-dyn", out_dir="runs", counts=SMALL_COUNTS, model="dynamic", train=dict(max_steps=100),
                    dynamic=dict(models=["window_static", "dynamic"], seeds=1, folds=3, kind_holdout=False),
                    flights={"pitch-pulse": dict(variant=1, end_s=200.0, pulse_at_s=180.0, pulse_s=3.0,
                                                 pulse_rad=0.3)}))
    spec = __import__("json").loads((out / "element" / "element.json").read_text())
    best = pd.read_csv(out / "dynamic" / "comparison.csv").query("best").model.iloc[0]
    assert ("response" in spec) == (best == "dynamic")
    assert spec["window_revs"] == 2.0 and spec["aircraft"]["blades"] == 2
    flight = pd.read_parquet(out / "pitch-pulse.parquet")
    assert flight.ready.any() and np.isfinite(flight.pvv_g).all() and (~flight.rejected).all()
    if "c_pvv_g" in flight:
        assert np.abs(flight.c_pvv_g - flight.pvv_g).max() < 1e-6
