"""The NumPy real-time element: frame by frame it equals the offline replay (every maneuver
kind), imports no JAX, and survives what simulators send (missed frames, bad values,
out-of-envelope inputs, resets)."""

import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import rbf_nets

from pvvjax.analysis.databases import DB_INPUTS, STATE_CHANNELS
from pvvjax.data.batch import to_batch
from pvvjax.data.campaign import load_campaign
from pvvjax.realtime.element import CHANNELS, VibrationElement
from pvvjax.realtime.npnet import NumpyNet
from pvvjax.replay import quasistatic as R

KINDS = ["pullup", "pushover", "roll", "autorotation", "flare", "level", "turn", "climb", "descent"]


@pytest.fixture(scope="module")
def setup(small_campaign_dir, small_dbs):
    params, envelope = rbf_nets(small_dbs, "db1")
    camp = load_campaign(small_campaign_dir)
    return camp, params, envelope


def _frames(camp, counter):
    rec = camp.records[counter]
    return rec.time_s.to_numpy(), rec.azimuth_deg.to_numpy(), rec[list(CHANNELS)].to_numpy(float)


def _stream(el, T, AZ, X, every=1):
    """Feed frames; return {window index: pvv} at the frame each window became ready."""
    out = {}
    for i in range(0, len(T), every):
        o = el.step(T[i], AZ[i], X[i])
        assert np.isfinite(o.pvv_g) and np.isfinite(o.shake_g)
        if o.ready:
            out.setdefault(el._j - 1, o.pvv_g)
    return out


@pytest.mark.parametrize("kind", KINDS)
def test_streaming_equals_offline_replay(setup, kind):
    camp, params, _ = setup
    counter = camp.counters.index[camp.counters.maneuver == kind][0]
    tau, tau_s, L, hop = 0.6, -0.3, 8.0, 1.0
    with jax.enable_x64(True):
        batch = to_batch(camp, STATE_CHANNELS, [counter], dtype=np.float64)
        rec = jax.tree.map(lambda a: a[0], R.prepare(batch))
        settings = R.make_settings(batch, min_window_revs=L, max_window_revs=L, hop_revs=hop, stick_lag=True)
        stacked = jax.tree.map(lambda *a: jnp.stack([jnp.asarray(v, jnp.float64) for v in a]), *params)
        model = dict(params=stacked, idx=jnp.asarray(R.input_index("db1")))
        # jitted: one compilation per record instead of one per operation and shape
        offline = np.asarray(jax.jit(R.replay, static_argnames="settings")(model, rec, tau, L, tau_s,
                                                                          settings=settings).predicted)
    el = VibrationElement([NumpyNet(p) for p in params], DB_INPUTS["db1"], window_revs=L, hop_revs=hop, offset_s=tau,
                          stick_offset_s=tau_s)
    streamed = _stream(el, *_frames(camp, counter))
    assert len(streamed) >= 10
    j = np.array(sorted(streamed))
    np.testing.assert_allclose([streamed[k] for k in j], offline[j], rtol=0, atol=1e-9)


def test_missed_frames_and_bad_values(setup):
    camp, params, envelope = setup
    counter = camp.counters.index[camp.counters.maneuver == "pullup"][0]
    T, AZ, X = _frames(camp, counter)
    make = lambda: VibrationElement([NumpyNet(p) for p in params], DB_INPUTS["db1"], offset_s=0.5)  # noqa: E731
    full = _stream(make(), T, AZ, X)
    # Half the frame rate (every other frame missed): the same windows to within the
    # integration error of the coarser samples.
    half = _stream(make(), T, AZ, X, every=2)
    common = sorted(set(full) & set(half))
    assert len(common) > 10
    assert max(abs(full[k] - half[k]) for k in common) < 2e-3
    # The frame rate halving mid-record, with jitter of the frame times: still the same windows.
    rng = np.random.default_rng(0)
    idx = np.r_[np.arange(0, len(T) // 2), np.arange(len(T) // 2, len(T), 2)]
    tj = T[idx] + rng.uniform(-0.3, 0.3, idx.size) * np.median(np.diff(T))
    keep = np.r_[True, np.diff(tj) > 0]
    el = make()
    mixed = {}
    for i in np.flatnonzero(keep):
        if el.step(tj[i], AZ[idx[i]], X[idx[i]]).ready:
            mixed.setdefault(el._j - 1, el._pvv)
    common = sorted(set(full) & set(mixed))
    assert len(common) > 10 and max(abs(full[k] - mixed[k]) for k in common) < 5e-3
    # A NaN value and a time that does not advance are rejected without changing the state.
    el, ref = make(), make()
    for i in range(600):
        if i == 300:
            assert el.step(T[i], AZ[i], np.where(np.arange(X.shape[1]) == 2, np.nan, X[i])).rejected
            assert el.step(T[i - 1], AZ[i - 1], X[i - 1]).rejected
        a, b = el.step(T[i], AZ[i], X[i]), ref.step(T[i], AZ[i], X[i])
        assert a == b
    # Reset: the record again gives the same values.
    el.reset()
    again = _stream(el, T, AZ, X)
    assert again == full


def test_out_of_envelope_is_flagged_and_clipped(setup):
    camp, params, envelope = setup
    counter = camp.counters.index[camp.counters.maneuver == "pullup"][0]
    T, AZ, X = _frames(camp, counter)
    lo, hi = envelope
    narrow = (lo, lo + 0.1 * (hi - lo))  # almost every window is outside
    nets = [NumpyNet(p) for p in params]
    el = VibrationElement(nets, DB_INPUTS["db1"], offset_s=0.5, envelope=narrow)
    flags, vals = [], []
    for i in range(len(T)):
        o = el.step(T[i], AZ[i], X[i])
        if o.ready:
            flags.append(o.out_of_envelope)
            vals.append(o.pvv_g)
    assert any(flags) and np.all(np.isfinite(vals))
    # An input far outside is clipped onto the envelope (and flagged); without clipping it
    # would be extrapolated.
    x = X[len(X) // 2].copy()
    x[CHANNELS.index("airspeed_kt")] = 1e4
    z, flag = el._net_inputs(x, 0.0)
    assert flag and np.all(z >= narrow[0]) and np.all(z <= narrow[1])
    free = VibrationElement(nets, DB_INPUTS["db1"], envelope=narrow, clip=False)
    z2, flag2 = free._net_inputs(x, 0.0)
    assert flag2 and z2.max() > narrow[1].max()


def test_rotor_speed_only_frames_follow_the_azimuth(setup):
    camp, params, _ = setup
    counter = camp.counters.index[camp.counters.maneuver == "autorotation"][0]  # rotor speed changes
    T, AZ, X = _frames(camp, counter)
    nets = [NumpyNet(p) for p in params]
    by_az = _stream(VibrationElement(nets, DB_INPUTS["db1"], offset_s=0.5), T, AZ, X)
    el = VibrationElement(nets, DB_INPUTS["db1"], offset_s=0.5)
    by_rpm = {}
    for i in range(len(T)):
        if el.step(T[i], None, X[i]).ready:
            by_rpm.setdefault(el._j - 1, el._pvv)
    common = sorted(set(by_az) & set(by_rpm))
    assert len(common) > 10 and max(abs(by_az[k] - by_rpm[k]) for k in common) < 5e-3


def test_element_imports_no_jax():
    code = ("import sys, numpy as np; from pvvjax.realtime.element import VibrationElement, CHANNELS; "
            "print('jax' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@pytest.mark.parametrize("kind", ["pullup", "autorotation"])
def test_a_dynamic_element_equals_the_offline_response_of_the_replay(setup, kind):
    """With the dynamic model's response, each window is the replay's static prediction
    delayed and passed through the second-order response (`pvvjax.dynamics`), offline in
    float64 against the element stepped frame by frame."""
    from pvvjax.dynamics import delayed, second_order

    camp, params, _ = setup
    counter = camp.counters.index[camp.counters.maneuver == kind][0]
    L, hop, resp = 2.0, 1.0, dict(omega_n_rad_s=2 * np.pi * 0.5, zeta=0.4, delay_s=0.3)
    with jax.enable_x64(True):
        batch = to_batch(camp, STATE_CHANNELS, [counter], dtype=np.float64)
        rec = jax.tree.map(lambda a: a[0], R.prepare(batch))
        settings = R.make_settings(batch, min_window_revs=L, max_window_revs=L, hop_revs=hop)
        stacked = jax.tree.map(lambda *a: jnp.stack([jnp.asarray(v, jnp.float64) for v in a]), *params)
        model = dict(params=stacked, idx=jnp.asarray(R.input_index("db1")))
        rep = jax.jit(R.replay, static_argnames="settings")(model, rec, 0.0, L, settings=settings)
        n = int(np.sum(np.asarray(rep.weight) > 0))
        t, u = rep.time[:n], rep.predicted[:n]
        offline = np.asarray(second_order(delayed(u, t, resp["delay_s"]), t, resp["omega_n_rad_s"], resp["zeta"]))
    el = VibrationElement([NumpyNet(p) for p in params], DB_INPUTS["db1"], window_revs=L, hop_revs=hop,
                          response=resp)
    streamed = _stream(el, *_frames(camp, counter))
    j = np.array([k for k in sorted(streamed) if k < n])
    assert len(j) > 50
    np.testing.assert_allclose([streamed[k] for k in j], offline[j], rtol=0, atol=1e-6)
    static = _stream(VibrationElement([NumpyNet(p) for p in params], DB_INPUTS["db1"], window_revs=L,
                                      hop_revs=hop), *_frames(camp, counter))
    assert max(abs(streamed[k] - static[k]) for k in j) > 1e-3  # the response acts


def _output(params, i):
    """The one-output net computing output i of a net of several outputs."""
    last = params["layers"][-1]
    return {**params, "layers": (*params["layers"][:-1], dict(w=last["w"][:, i:i + 1], b=last["b"][i:i + 1])),
            "y_shift": params["y_shift"][i], "y_scale": params["y_scale"][i]}


@pytest.mark.parametrize("response", [None, dict(omega_n_rad_s=3.0, zeta=0.4, delay_s=0.2)])
def test_each_axis_of_a_three_axis_element_is_the_element_of_that_output(setup, small_dbs, response):
    """A three-output element predicts, frame by frame, each axis as the one-output element of
    that output's net does (which equals the offline replay, above): PVV within 1e-9 g, and each
    seat axis shakes its N/rev at its phase plus its constant 1/rev."""
    from pvvjax.analysis.databases import OUTPUT
    from pvvjax.nets.networks import mlp_init, scaling

    camp, _, _ = setup
    db = small_dbs["db1"]
    x = db[list(DB_INPUTS["db1"])].to_numpy(np.float32)
    y = np.stack([db[OUTPUT], 0.5 * db[OUTPUT], 0.3 + db.advance_ratio], 1).astype(np.float32)
    params = [jax.tree.map(np.asarray, mlp_init(jax.random.key(s), x.shape[1], (8, 4), scale=scaling(x, y), n_out=3))
              for s in range(3)]
    outputs = ("ay_g", "az_g", "ax_g")  # any order: each output names the seat axis it shakes
    shake = [dict(phase_rad=0.1 * i, once_g=0.01 * (i + 1), once_phase_rad=i) for i in range(3)]
    kw = dict(window_revs=8.0, hop_revs=1.0, offset_s=0.6, response=response)
    three = VibrationElement([NumpyNet(p) for p in params], DB_INPUTS["db1"], outputs=outputs, shake=shake, **kw)
    ones = [VibrationElement([NumpyNet(_output(p, i)) for p in params], DB_INPUTS["db1"], outputs=(outputs[i],),
                             shake=[shake[i]], **kw) for i in range(3)]
    T, AZ, X = _frames(camp, camp.counters.index[camp.counters.maneuver == "turn"][0])
    for t, az, x_ in zip(T, AZ, X):
        o = three.step(t, az, x_)
        for axis, one in zip(outputs, ones):
            a = one.step(t, az, x_)
            seat = {"ax_g": "x", "ay_g": "y", "az_g": "z"}[axis]
            assert abs(getattr(o, f"pvv_{seat}_g") - a.pvv_g) < 1e-9
            assert abs(getattr(o, f"shake_{seat}_g") - a.shake_g) < 1e-9
    assert o.ready and o.pvv_g == o.pvv_y_g  # the first output is pvv_g
    with pytest.raises(ValueError, match="each one of ax_g, ay_g, az_g, at most once"):
        VibrationElement([], DB_INPUTS["db1"], outputs=("az_g", "az_g"))


@pytest.mark.parametrize("model", ["window_static_rates", "rnn"])
def test_an_element_of_rates_and_a_recurrent_state_equals_the_model_on_the_training_windows(setup, model):
    """An element whose nets take the inputs' rates (an MLP) or carry a state (a GRU) predicts,
    window by window, what the model predicts on `dynamics.window_sequences` of the record:
    the rates are backward differences of the window averages over their centre times (0 at
    the first window), and the GRU's state runs from zero along the windows."""
    import jax.numpy as jnp

    from pvvjax.dynamics import rnn_apply, rnn_init, window_sequences
    from pvvjax.nets.networks import mlp_apply, mlp_init, scaling

    camp, _, _ = setup
    counter = camp.counters.index[camp.counters.maneuver == "pullup"][0]
    seq = window_sequences(camp, DB_INPUTS["db1"], window_revs=2.0, hop_revs=1.0, rates=True, counters=[counter])
    n = int(seq.mask[0].sum())
    x = seq.inputs[0, :n]
    sc = scaling(x.astype(np.float32), seq.amplitude[0, :n].astype(np.float32))
    params = [jax.tree.map(np.asarray, mlp_init(jax.random.key(s), x.shape[1], (8, 4), scale=sc) if model != "rnn"
                           else rnn_init(jax.random.key(s), x.shape[1], 6, scale=sc)) for s in range(3)]
    apply = rnn_apply if model == "rnn" else mlp_apply
    offline = np.median([np.asarray(apply(p, jnp.asarray(x, jnp.float32))) for p in params], axis=0)
    el = VibrationElement([NumpyNet(p) for p in params], seq.names, window_revs=2.0, hop_revs=1.0)
    streamed = _stream(el, *_frames(camp, counter))
    j = np.array(sorted(streamed))
    assert len(j) == n
    np.testing.assert_allclose([streamed[k] for k in j], offline, rtol=0, atol=2e-5)
    assert np.ptp(np.diff(offline)) > 1e-3
    with pytest.raises(ValueError, match="d_<name>_dt"):
        VibrationElement(el.nets, ["d_airspeed_dt"])
