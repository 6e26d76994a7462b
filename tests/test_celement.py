"""The C element (`pvvjax export --format c`) and its FMU (`--format fmu`): frame by frame they
equal the NumPy element within 1e-6 g on one record of every maneuver kind, with a stick lag,
out-of-envelope windows and rejected frames; FMPy validates the FMU and simulates it as a host.
Needs a C compiler (skipped with the reason where there is none); the FMU tests need FMPy."""

import jax
import numpy as np
import pytest
from conftest import rbf_nets

from pvvjax.analysis.databases import DB_INPUTS, OUTPUT
from pvvjax.data.campaign import load_campaign
from pvvjax.nets.networks import mlp_init, mlp_pad, scaling
from pvvjax.realtime.cexport import CElement, CSourceLimits, c_compiler, compile_shared, write_c_element
from pvvjax.realtime.element import CHANNELS, VibrationElement
from pvvjax.realtime.npnet import NumpyNet

pytestmark = pytest.mark.skipif(c_compiler() is None, reason="no C compiler (set CC or install cc/gcc/clang)")

KINDS = ["pullup", "pushover", "roll", "autorotation", "flare", "level", "turn", "climb", "descent"]
SETTINGS = dict(window_revs=8.0, hop_revs=1.0, offset_s=0.6, stick_offset_s=-0.3)
TOL = 1e-6  # g
AXES = ("pvv_x_g", "pvv_y_g", "pvv_z_g", "shake_x_g", "shake_y_g", "shake_z_g")


@pytest.fixture(scope="module")
def element(small_campaign_dir, small_dbs, tmp_path_factory):
    """Two RBF and two padded MLP nets of db1 (an even count: the median of the middle two), a
    narrowed envelope (some windows flagged), seat-shake harmonics, and the compiled C element."""
    camp = load_campaign(small_campaign_dir)
    params, (lo, hi) = rbf_nets(small_dbs, "db1", n=2)
    db = small_dbs["db1"]
    x = db[list(DB_INPUTS["db1"])].to_numpy(np.float32)
    y = db[OUTPUT].to_numpy(np.float32)
    for seed in (0, 1):
        p = mlp_pad(mlp_init(jax.random.key(seed), x.shape[1], (10, 5), scale=scaling(x, y)), (12, 8), x.shape[1])
        params.append(jax.tree.map(np.asarray, p))
    nets = [NumpyNet(p) for p in params]
    envelope = (lo, lo + 0.8 * (hi - lo))
    spec = dict(inputs=list(DB_INPUTS["db1"]), envelope=dict(lo=list(envelope[0]), hi=list(envelope[1])),
                phase_rad=0.3, harmonics={"1": [0.2, 0.5], "8": [0.1, -1.0]}, aircraft=dict(blades=4), **SETTINGS)
    folder = write_c_element(tmp_path_factory.mktemp("c"), spec, nets, source="test nets")
    lib = compile_shared([folder / "pvv_element.c"], folder / "libpvv.so",
                         flags=("-O2", "-Wall", "-Wextra", "-pedantic", "-Werror"))
    reference = lambda: VibrationElement(nets, DB_INPUTS["db1"], envelope=envelope, phase_rad=0.3,  # noqa: E731
                                         harmonics={1: (0.2, 0.5), 8: (0.1, -1.0)}, **SETTINGS)
    return dict(camp=camp, spec=spec, nets=nets, lib=lib, reference=reference, folder=folder)


def _frames(camp, kind):
    counter = camp.counters.index[camp.counters.maneuver == kind][0]
    rec = camp.records[counter]
    return rec.time_s.to_numpy(), rec.azimuth_deg.to_numpy(), rec[list(CHANNELS)].to_numpy(float)


def _compare(ref, c, frames):
    """Step both over frames (t, az or None, x); the largest PVV and shake difference and the flags."""
    worst, flags = 0.0, []
    for t, az, x in frames:
        a, b = ref.step(t, az, x), c.step(t, az, x)
        worst = max(worst, *(abs(getattr(a, k) - b[k]) for k in ("pvv_g", "shake_g", "amplitude_g") + AXES))
        assert (a.ready, a.out_of_envelope, a.rejected) == (b["ready"], b["out_of_envelope"], b["rejected"])
        flags.append(a.out_of_envelope)
    return worst, flags


@pytest.mark.parametrize("kind", KINDS)
def test_c_element_equals_the_numpy_element(element, kind):
    T, AZ, X = _frames(element["camp"], kind)
    frames = list(zip(T, AZ, X))
    # A frame with a NaN channel and one whose time does not advance are rejected by both.
    frames.insert(400, (T[400], AZ[400], np.where(np.arange(X.shape[1]) == 3, np.nan, X[400])))
    frames.insert(600, (T[598], AZ[598], X[598]))
    worst, flags = _compare(element["reference"](), CElement(element["lib"]), frames)
    assert worst < TOL
    if kind == "pullup":
        assert any(flags) and not all(flags)  # windows inside and outside the envelope


def test_c_element_integrates_the_rotor_speed_and_resets(element):
    T, AZ, X = _frames(element["camp"], "autorotation")  # the rotor speed changes
    ref, c = element["reference"](), CElement(element["lib"])
    worst, _ = _compare(ref, c, [(t, None, x) for t, x in zip(T, X)])
    assert worst < TOL
    ref.reset()
    c.reset()
    worst, _ = _compare(ref, c, list(zip(T[:3000], AZ[:3000], X[:3000])))
    assert worst < TOL


def test_c_element_settings_and_overflow(element, tmp_path):
    with pytest.raises(ValueError, match="outside its limits"):
        CElement(element["lib"], window_revs=40.0)
    with pytest.raises(ValueError, match="outside its limits"):
        CElement(element["lib"], hop_revs=9.0)  # more than the window
    # Sized for 40 frames/s, fed 320: the oldest frames go, the element says so and keeps going.
    folder = write_c_element(tmp_path, element["spec"], element["nets"], CSourceLimits(max_rate_hz=40.0))
    small = CElement(compile_shared([folder / "pvv_element.c"], tmp_path / "small.so"))
    T, AZ, X = _frames(element["camp"], "level")
    outs = [small.step(t, az, x) for t, az, x in zip(T[:4000], AZ[:4000], X[:4000])]
    assert outs[-1]["overflow"] and not outs[0]["overflow"]
    assert all(np.isfinite(o["pvv_g"]) and np.isfinite(o["shake_g"]) for o in outs)


def test_c_source_is_self_contained(element):
    src = (element["folder"] / "pvv_element.c").read_text() + (element["folder"] / "pvv_element.h").read_text()
    includes = sorted({line.split()[1] for line in src.splitlines() if line.startswith("#include")})
    assert includes == ['"pvv_element.h"', "<math.h>"]
    assert "malloc" not in src and "calloc" not in src and "memmove" not in src
    assert src.count("static void net") == 4


@pytest.fixture(scope="module")
def fmu(element, tmp_path_factory):
    pytest.importorskip("fmpy", reason="FMPy is in the sim extra (make test installs it)")
    from pvvjax.realtime.fmu import build_fmu

    return build_fmu(tmp_path_factory.mktemp("fmu") / "pvv_element.fmu", element["spec"], element["nets"])


def test_fmu_passes_fmpy_validation(fmu):
    import fmpy
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu))
    assert md.fmiVersion == "2.0" and md.coSimulation.modelIdentifier == "pvv_element"
    by = {v.name: v for v in md.modelVariables}
    assert [v.name for v in md.modelVariables if v.causality == "input"] == [
        "airspeed_kt", "gross_weight_lb", "rotor_rpm", "density_ratio", "pitch_rate_dps", "roll_angle_deg",
        "climb_rate_fpm", "azimuth_deg"]  # db1's channels (and what its features need)
    assert (by["airspeed_kt"].unit, by["climb_rate_fpm"].unit, by["pvv_g"].unit) == ("kt", "ft/min", "g")
    assert {v.name for v in md.modelVariables if v.causality == "output"} == {
        "pvv_g", "shake_g", "amplitude_g", "window_time_s", "ready", "out_of_envelope", "rejected", "overflow", *AXES}
    assert {by[k].unit for k in AXES} == {"g"}
    assert float(by["offset_s"].start) == 0.6 and float(by["window_revs"].max) == 16.0


def _fmu_input(fmu, T, AZ, X):
    """FMPy's input signal for the FMU's inputs: the record's frames (times T, azimuth AZ,
    channels X)."""
    import fmpy

    names = [v.name for v in fmpy.read_model_description(str(fmu)).modelVariables if v.causality == "input"]
    signal = np.zeros(len(T), [("time", float)] + [(k, float) for k in names])
    signal["time"] = T
    for k in names:
        signal[k] = AZ if k == "azimuth_deg" else X[:, CHANNELS.index(k)]
    return signal


@pytest.mark.parametrize("kind", ["pullup", "autorotation"])
def test_fmpy_simulation_equals_the_numpy_element(element, fmu, kind):
    """FMPy as the host: the recorded counter at the campaign's frame rate; the output after the
    step from t is the element's output for the frame at t."""
    import fmpy

    T, AZ, X = _frames(element["camp"], kind)
    dt = float(np.median(np.diff(T)))
    assert np.allclose(np.diff(T), dt)
    signal = _fmu_input(fmu, T, AZ, X)
    res = fmpy.simulate_fmu(str(fmu), start_time=T[0], stop_time=T[-1], step_size=dt, output_interval=dt,
                            input=signal, output=["pvv_g", "shake_g", "out_of_envelope", "ready"],
                            start_values={"stick_offset_s": -0.3})
    ref = element["reference"]()
    outs = [ref.step(t, az, x) for t, az, x in zip(T, AZ, X)]
    want = np.array([(o.pvv_g, o.shake_g, o.out_of_envelope) for o in outs])
    got = np.stack([res["pvv_g"], res["shake_g"], res["out_of_envelope"]], 1)[1:]
    n = len(got)
    assert n >= len(T) - 1 and res["ready"][-1]
    np.testing.assert_allclose(got[:, :2], want[:n, :2], rtol=0, atol=TOL)
    assert (got[:, 2] == want[:n, 2]).all()


RESPONSE = dict(omega_n_rad_s=2 * np.pi * 0.5, zeta=0.4, delay_s=0.3)
DYNAMIC = dict(window_revs=2.0, hop_revs=1.0, offset_s=0.0, stick_offset_s=0.0)


@pytest.fixture(scope="module")
def dynamic_element(element, tmp_path_factory):
    """The same nets as a dynamic model's element: 2-rev windows and a delayed second-order
    response, compiled as C (window limits widened to its window) and built as an FMU."""
    spec = {**element["spec"], **DYNAMIC, "response": RESPONSE}
    limits = CSourceLimits(window_revs=(2.0, 16.0))
    folder = write_c_element(tmp_path_factory.mktemp("cdyn"), spec, element["nets"], limits, source="test nets")
    lib = compile_shared([folder / "pvv_element.c"], folder / "libpvv.so",
                         flags=("-O2", "-Wall", "-Wextra", "-pedantic", "-Werror"))
    env = spec["envelope"]
    reference = lambda: VibrationElement(element["nets"], DB_INPUTS["db1"], envelope=(env["lo"], env["hi"]),  # noqa
                                         phase_rad=0.3, harmonics={1: (0.2, 0.5), 8: (0.1, -1.0)},
                                         response=RESPONSE, **DYNAMIC)
    return dict(spec=spec, lib=lib, reference=reference, limits=limits)


@pytest.mark.parametrize("kind", ["pullup", "autorotation", "roll"])
def test_dynamic_c_element_equals_the_numpy_element(element, dynamic_element, kind):
    T, AZ, X = _frames(element["camp"], kind)
    worst, _ = _compare(dynamic_element["reference"](), CElement(dynamic_element["lib"]), list(zip(T, AZ, X)))
    assert worst < TOL
    quasi = VibrationElement(element["nets"], DB_INPUTS["db1"], **DYNAMIC)
    dyn = dynamic_element["reference"]()
    assert max(abs(quasi.step(t, az, x).pvv_g - dyn.step(t, az, x).pvv_g) for t, az, x in zip(T, AZ, X)) > 1e-3


def test_dynamic_fmu_simulation_equals_the_numpy_element(element, dynamic_element, tmp_path):
    fmpy = pytest.importorskip("fmpy", reason="FMPy is in the sim extra (make test installs it)")
    from pvvjax.realtime.fmu import build_fmu

    fmu = build_fmu(tmp_path / "pvv_element.fmu", dynamic_element["spec"], element["nets"], dynamic_element["limits"])
    T, AZ, X = _frames(element["camp"], "pullup")
    dt = float(np.median(np.diff(T)))
    signal = _fmu_input(fmu, T, AZ, X)
    res = fmpy.simulate_fmu(str(fmu), start_time=T[0], stop_time=T[-1], step_size=dt, output_interval=dt,
                            input=signal, output=["pvv_g"])
    ref = dynamic_element["reference"]()
    want = np.array([ref.step(t, az, x).pvv_g for t, az, x in zip(T, AZ, X)])
    got = res["pvv_g"][1:]
    np.testing.assert_allclose(got, want[:len(got)], atol=TOL)


THREE = ("az_g", "ax_g", "ay_g")
SHAKE = [dict(phase_rad=0.3, harmonics={"8": [0.2, -1.0]}, once_g=0.01, once_phase_rad=1.1),
         dict(phase_rad=-0.7, once_g=0.02, once_phase_rad=0.6), dict(phase_rad=2.0, once_g=0.035, once_phase_rad=2.2)]


@pytest.fixture(scope="module")
def three_axis(element, small_dbs, tmp_path_factory):
    """Three padded MLP nets of three outputs (az_g, ax_g, ay_g) on db1, each axis with its
    N/rev phase and a 1/rev of track and balance; quasi-static and dynamic, compiled as C."""
    db = small_dbs["db1"]
    x = db[list(DB_INPUTS["db1"])].to_numpy(np.float32)
    y = np.stack([db[OUTPUT], 0.5 * db[OUTPUT], 0.3 + db.advance_ratio], 1).astype(np.float32)
    nets = [NumpyNet(jax.tree.map(np.asarray, mlp_pad(mlp_init(jax.random.key(s), x.shape[1], (8, 4),
                                                              scale=scaling(x, y), n_out=3), (10, 6), x.shape[1])))
            for s in range(3)]
    out = {}
    for name, extra in (("quasi", SETTINGS), ("dynamic", {**DYNAMIC, "response": RESPONSE})):
        spec = {**element["spec"], **extra, "outputs": list(THREE), "shake": SHAKE}
        limits = CSourceLimits(window_revs=(2.0, 16.0))
        folder = write_c_element(tmp_path_factory.mktemp(f"c3{name}"), spec, nets, limits, source="test nets")
        lib = compile_shared([folder / "pvv_element.c"], folder / "libpvv.so",
                             flags=("-O2", "-Wall", "-Wextra", "-pedantic", "-Werror"))
        out[name] = dict(spec=spec, lib=lib, limits=limits)
    out["nets"] = nets
    return out


def _three_reference(element, three, name):
    s = three[name]["spec"]
    env = s["envelope"]
    return VibrationElement(three["nets"], s["inputs"], envelope=(env["lo"], env["hi"]), outputs=THREE, shake=SHAKE,
                            response=s.get("response"), **{k: s[k] for k in SETTINGS})


@pytest.mark.parametrize("name, kind", [("quasi", "pullup"), ("quasi", "turn"), ("dynamic", "roll")])
def test_each_axis_of_a_three_axis_c_element_equals_the_numpy_element(element, three_axis, name, kind):
    T, AZ, X = _frames(element["camp"], kind)
    ref = _three_reference(element, three_axis, name)
    worst, _ = _compare(ref, CElement(three_axis[name]["lib"]), list(zip(T, AZ, X)))
    assert worst < TOL
    last = ref.step(T[-1] + 0.01, AZ[-1], X[-1])
    assert last.pvv_z_g == last.pvv_g and min(last.pvv_x_g, last.pvv_y_g) > 0 and last.shake_z_g == last.shake_g


def test_a_three_axis_fmu_declares_and_computes_every_axis(element, three_axis, tmp_path):
    fmpy = pytest.importorskip("fmpy", reason="FMPy is in the sim extra (make test installs it)")
    from fmpy.validation import validate_fmu

    from pvvjax.realtime.fmu import build_fmu

    q = three_axis["quasi"]
    fmu = build_fmu(tmp_path / "pvv_element.fmu", q["spec"], three_axis["nets"], q["limits"])
    assert validate_fmu(str(fmu)) == []
    T, AZ, X = _frames(element["camp"], "flare")
    dt = float(np.median(np.diff(T)))
    res = fmpy.simulate_fmu(str(fmu), start_time=T[0], stop_time=T[-1], step_size=dt, output_interval=dt,
                            input=_fmu_input(fmu, T, AZ, X), output=list(AXES))
    ref = _three_reference(element, three_axis, "quasi")
    want = np.array([[getattr(o, k) for k in AXES] for o in (ref.step(t, az, x) for t, az, x in zip(T, AZ, X))])
    got = np.stack([res[k] for k in AXES], 1)[1:]
    np.testing.assert_allclose(got, want[:len(got)], rtol=0, atol=TOL)


@pytest.fixture(scope="module")
def sequence_elements(element, tmp_path_factory):
    """The elements of the `_rates` map (MLPs on db1's inputs and their rates) and of the GRU
    (on the same inputs, its state carried from window to window), with 2-rev windows and an
    envelope that flags some windows, compiled as C."""
    from pvvjax.dynamics import rnn_init, window_sequences
    from pvvjax.nets.networks import scaling

    camp = element["camp"]
    seq = window_sequences(camp, DB_INPUTS["db1"], window_revs=2.0, hop_revs=1.0, rates=True)
    x, y = seq.inputs[seq.mask].astype(np.float32), seq.amplitude[seq.mask].astype(np.float32)
    lo, hi = x.min(0), x.max(0)
    env = (lo, lo + 0.7 * (hi - lo))
    out = {}
    for model in ("window_static_rates", "rnn"):
        params = [mlp_init(jax.random.key(s), x.shape[1], (8, 4), scale=scaling(x, y)) if model != "rnn"
                  else rnn_init(jax.random.key(s), x.shape[1], 5, scale=scaling(x, y)) for s in range(3)]
        nets = [NumpyNet(jax.tree.map(np.asarray, p)) for p in params]
        spec = {**element["spec"], **DYNAMIC, "inputs": list(seq.names),
                "envelope": dict(lo=[float(v) for v in env[0]], hi=[float(v) for v in env[1]])}
        limits = CSourceLimits(window_revs=(2.0, 16.0))
        folder = write_c_element(tmp_path_factory.mktemp(model), spec, nets, limits, source="test nets")
        lib = compile_shared([folder / "pvv_element.c"], folder / "libpvv.so",
                             flags=("-O2", "-Wall", "-Wextra", "-pedantic", "-Werror"))
        reference = (lambda nets=nets: VibrationElement(nets, seq.names, envelope=env, phase_rad=0.3,  # noqa: E731
                                                        harmonics={1: (0.2, 0.5), 8: (0.1, -1.0)}, **DYNAMIC))
        out[model] = dict(spec=spec, nets=nets, lib=lib, reference=reference, limits=limits)
    return out


@pytest.mark.parametrize("model, kind", [("window_static_rates", "pullup"), ("window_static_rates", "roll"),
                                         ("rnn", "pullup"), ("rnn", "autorotation")])
def test_a_c_element_of_rates_or_a_gru_equals_the_numpy_element(element, sequence_elements, model, kind):
    """Frame by frame within 1e-6 g, with rejected frames and a reset part-way (the rates
    and the GRU's state start again from the first window)."""
    T, AZ, X = _frames(element["camp"], kind)
    frames = list(zip(T, AZ, X))
    frames.insert(300, (T[300], AZ[300], np.where(np.arange(X.shape[1]) == 0, np.inf, X[300])))
    ref, c = sequence_elements[model]["reference"](), CElement(sequence_elements[model]["lib"])
    worst, flags = _compare(ref, c, frames)
    assert worst < TOL and any(flags)
    ref.reset()
    c.reset()
    worst, _ = _compare(ref, c, frames[:400])
    assert worst < TOL


def test_an_fmu_of_the_gru_element_simulates_as_the_numpy_element(element, sequence_elements, tmp_path):
    fmpy = pytest.importorskip("fmpy", reason="FMPy is in the sim extra (make test installs it)")
    from pvvjax.realtime.fmu import build_fmu

    e = sequence_elements["rnn"]
    fmu = build_fmu(tmp_path / "pvv_element.fmu", e["spec"], e["nets"], e["limits"])
    T, AZ, X = _frames(element["camp"], "roll")
    dt = float(np.median(np.diff(T)))
    res = fmpy.simulate_fmu(str(fmu), start_time=T[0], stop_time=T[-1], step_size=dt, output_interval=dt,
                            input=_fmu_input(fmu, T, AZ, X), output=["pvv_g"])
    ref = e["reference"]()
    want = np.array([ref.step(t, az, x).pvv_g for t, az, x in zip(T, AZ, X)])
    got = res["pvv_g"][1:]
    np.testing.assert_allclose(got, want[:len(got)], rtol=0, atol=TOL)
