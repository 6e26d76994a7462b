"""The dynamic response (pvvjax.dynamics): the JAX recurrence against the generator's plain
NumPy filter, its steady gain and step response against the continuous theory, gradients
against finite differences, and padding that holds the state."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pvvjax.dynamics import delayed, second_order
from pvvjax.synth import SynthConfig, generate
from pvvjax.synth._vibration import second_order_response


def _times(rng, shape, mean=0.23):
    steps = rng.uniform(0.5, 1.5, shape) * mean  # windows of whole revolutions at a varying rotor speed
    return np.concatenate([np.zeros(shape[:-1] + (1,)), np.cumsum(steps, axis=-1)], axis=-1)


def test_the_recurrence_equals_a_plain_numpy_filter():
    rng = np.random.default_rng(0)
    t = _times(rng, (3, 59))
    t[1, 40:] = t[1, 40]  # a padded record: steps of 0 s hold the state
    u = 0.1 + 0.05 * rng.standard_normal((3, 60))
    got = np.asarray(jax.jit(second_order)(u, t, 2 * np.pi * 0.5, 0.4))
    want = second_order_response(u, np.diff(t, axis=-1), 2 * np.pi * 0.5, 0.4)
    np.testing.assert_allclose(got, want, atol=2e-6)
    assert np.all(got[1, 40:] == got[1, 40])


def test_steady_gain_one_and_the_step_response_of_the_continuous_mode():
    t = np.arange(0.0, 20.0, 0.005)
    u = np.where(t > 1.0, 0.2, 0.1)
    with jax.enable_x64(True):
        y = np.asarray(second_order(jnp.asarray(u), jnp.asarray(t), 2 * np.pi * 0.5, 0.3))
        flat = np.asarray(second_order(jnp.full(50, 0.1), jnp.arange(50.0) * 0.23, 5.0, 0.7))
    np.testing.assert_allclose(flat, 0.1, rtol=1e-12)  # trimmed flight: the static map's value
    assert y[-1] == pytest.approx(0.2, rel=1e-6)
    overshoot = (y.max() - 0.2) / 0.1
    assert overshoot == pytest.approx(np.exp(-np.pi * 0.3 / np.sqrt(1 - 0.3**2)), rel=0.01)
    t_peak = t[np.argmax(y)] - 1.0
    assert t_peak == pytest.approx(np.pi / (2 * np.pi * 0.5 * np.sqrt(1 - 0.3**2)), abs=0.01)


def test_gradients_of_frequency_damping_and_delay_match_finite_differences():
    rng = np.random.default_rng(1)
    t = _times(rng, (2, 79))
    u = 0.1 + 0.05 * np.sin(t) + 0.01 * rng.standard_normal(t.shape)
    target = 0.1 + 0.05 * np.sin(t - 0.5)

    def loss(p):
        w, z, d = p
        return jnp.mean((second_order(delayed(u, t, d), t, w, z) - target) ** 2)

    loss = jax.jit(loss)
    with jax.enable_x64(True):
        p = jnp.array([3.0, 0.45, 0.37])
        g = np.asarray(jax.grad(loss)(p))
        eps = 1e-6
        fd = np.array([(loss(p.at[i].add(eps)) - loss(p.at[i].add(-eps))) / (2 * eps) for i in range(3)])
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-12)


def test_a_delay_is_the_sequence_interpolated_earlier_its_first_value_held():
    rng = np.random.default_rng(2)
    t = _times(rng, (2, 29))
    u = rng.standard_normal(t.shape)
    got = np.asarray(delayed(u, t, 0.4))
    for i in range(2):
        np.testing.assert_allclose(got[i], np.interp(t[i] - 0.4, t[i], u[i]), atol=1e-5)  # float32 times
    assert np.allclose(got[:, 0], u[:, 0])


def test_the_generators_second_order_response_is_off_by_default_and_shapes_the_vibration_when_on():
    assert SynthConfig().effect_settings()["second_order"][0] is False
    from pvvjax.config import from_dict

    on = from_dict(SynthConfig, {"conditions": ["11022"], "effects": {"second_order": {"enabled": True}}})
    plain = generate(SynthConfig(conditions=("11022",)))[1]["11022"]
    shaped = generate(on)[1]["11022"]
    assert not np.allclose(plain.az_g, shaped.az_g)
    accel = ["az_g", "ax_g", "ay_g"]  # the mode shapes every axis's vibration, and nothing else
    np.testing.assert_array_equal(plain.drop(columns=accel), shaped.drop(columns=accel))


def test_window_sequences_against_a_brute_force_analysis_of_each_window():
    from conftest import tiny_records

    from pvvjax.data.campaign import campaign_from_frames
    from pvvjax.dynamics import window_sequences

    counters, records = tiny_records(seconds=20.0)
    for name, df in records.items():
        records[name] = df.assign(airspeed_kt=100.0 + 2.0 * df.time_s)  # a steady acceleration: 2 kt/s
    camp = campaign_from_frames(counters, records)
    seq = window_sequences(camp, ["airspeed_kt", "rotor_rpm"], window_revs=2.0, hop_revs=0.5, rates=True)
    assert seq.names == ("airspeed_kt", "rotor_rpm", "d_airspeed_kt_dt", "d_rotor_rpm_dt")
    for r, name in enumerate(seq.counters):
        df = records[name]
        rev = (df.rotor_rpm * df.time_s / 60.0).to_numpy()
        psi = 2 * np.pi * rev
        n = int(seq.mask[r].sum())
        assert n == int(np.floor((rev[-1] - 2.0) / 0.5)) + 1  # every window inside the record
        for k in (0, n // 2, n - 1):
            inside = (rev >= 0.5 * k) & (rev < 0.5 * k + 2.0)
            amp = 2 * abs(np.mean(df.az_g.to_numpy()[inside] * np.exp(-4j * psi[inside])))
            assert seq.amplitude[r, k] == pytest.approx(amp, rel=0.02)
            assert seq.inputs[r, k, 0] == pytest.approx(df.airspeed_kt.to_numpy()[inside].mean(), abs=0.05)
            assert seq.t_start[r, k] == pytest.approx(df.time_s.to_numpy()[inside][0], abs=2e-3)
        np.testing.assert_allclose(seq.inputs[r, 1:n, 2], 2.0, rtol=1e-3)  # the rate, kt/s (causal)
        assert seq.inputs[r, 0, 2] == 0.0  # nothing before the first window
        assert set(seq.record[r]) == {name}
        np.testing.assert_allclose(seq.inputs[r, :n, 3], 0.0, atol=1e-6)
        assert np.all(seq.time[r, n:] == seq.time[r, n - 1])  # past the last window: a step of 0 s
    with pytest.raises(ValueError, match="hop_revs 2: must lie in"):
        window_sequences(camp, ["airspeed_kt"], hop_revs=2.0)


def test_one_long_record_moves_no_other_records_sequence():
    # One record twelve times as long as the others: the analysis batches the records by length
    # (one long record costs its own memory, not every record padded to it), and every other
    # record's windows keep their numbers.
    from conftest import tiny_records

    from pvvjax.analysis import length_groups
    from pvvjax.data.campaign import campaign_from_frames
    from pvvjax.dynamics import window_sequences

    counters, records = tiny_records(n_counters=6, seconds=4.0)
    before = window_sequences(campaign_from_frames(counters, records), ["airspeed_kt"])
    grown = {**records, "C2": tiny_records(n_counters=6, seconds=48.0)[1]["C2"]}
    assert len(set(length_groups([len(grown[c]) for c in counters.counter]))) == 2  # batched apart
    after = window_sequences(campaign_from_frames(counters, grown), ["airspeed_kt"])
    j = after.counters.index("C2")
    assert before.counters == after.counters and after.mask[j].sum() > 10 * before.mask[j].sum()
    for i in set(range(6)) - {j}:
        n = int(before.mask[i].sum())
        assert int(after.mask[i].sum()) == n
        np.testing.assert_allclose(after.amplitude[i, :n], before.amplitude[i, :n], rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(after.inputs[i, :n], before.inputs[i, :n], rtol=1e-6)
        np.testing.assert_array_equal(after.t_start[i, :n], before.t_start[i, :n])


def test_chained_segments_form_one_flight():
    from conftest import tiny_records

    from pvvjax.data.campaign import campaign_from_frames
    from pvvjax.dynamics import window_sequences

    counters, records = tiny_records(seconds=12.0)
    counters = counters.iloc[:2].assign(condition="one", segment=[1, 2])
    records = {c: records[c] for c in counters.counter}
    camp = campaign_from_frames(counters, records)
    single = window_sequences(camp, ["airspeed_kt"], rates=True)
    joined = window_sequences(camp, ["airspeed_kt"], rates=True, chain=True)
    n = single.mask.sum(axis=1)
    assert joined.counters == ("+".join(single.counters),) and joined.mask.sum() == n.sum()
    np.testing.assert_array_equal(joined.amplitude[0, :n.sum()], np.concatenate([single.amplitude[i, :n[i]]
                                                                                 for i in range(2)]))
    np.testing.assert_array_equal(joined.record[0, :n.sum()], np.repeat(single.counters, n))
    t1 = records["C1"].time_s.to_numpy()
    shift = t1[-1] + (t1[1] - t1[0])  # the second segment's clock continues the first's
    np.testing.assert_allclose(joined.time[0, n[0]:n.sum()], single.time[1, :n[1]] + shift)
    assert np.all(np.diff(joined.time[0]) >= 0)


def _sequences(rng, R=24, W=100):
    """Maneuver-like input steps at window times of a varying rotor speed; their static map."""
    t = np.concatenate([np.zeros((R, 1)), np.cumsum(rng.uniform(0.2, 0.26, (R, W - 1)), 1)], 1)
    x = np.zeros((R, W, 2))
    for r in range(R):
        for c in range(2):
            k, levels = np.sort(rng.choice(W, 5, replace=False)), rng.uniform(-1.5, 1.5, 6)
            x[r, :, c] = levels[np.searchsorted(k, np.arange(W), side="right")]
    return t, x, 0.1 + 0.05 * np.tanh(x[..., 0]) + 0.02 * x[..., 1]


def test_the_dynamic_model_recovers_the_delay_frequency_and_damping_it_was_given():
    from pvvjax.config import TrainConfig
    from pvvjax.dynamics import dynamic_apply, dynamic_init, identified
    from pvvjax.nets import train
    from pvvjax.nets.networks import mlp_init, scaling

    rng = np.random.default_rng(0)
    t, x, static = _sequences(rng)
    with jax.enable_x64(True):
        y = np.asarray(second_order(delayed(static, t, 0.3), t, 2 * np.pi * 0.5, 0.4))
    y = y + 0.002 * rng.standard_normal(y.shape)
    X = np.concatenate([x, t[..., None]], -1).astype(np.float32)
    val = np.arange(len(t)) % 4 == 0
    sc = scaling(x[~val].reshape(-1, 2), y[~val].reshape(-1))
    p0 = dynamic_init(mlp_init(jax.random.key(1), 2, (8,), scale=sc))  # starts at 1 Hz, ζ 0.7, 0.1 s
    ones = lambda m: np.ones((int(m.sum()), t.shape[1]), np.float32)  # noqa: E731
    data = train.Data(X[~val], y[~val].astype(np.float32), ones(~val), X[val], y[val].astype(np.float32), ones(val))
    cfg = TrainConfig(max_steps=2000, learning_rate=1e-2, patience=20)
    fit = jax.jit(lambda p, d: train.fit(p, d, cfg, apply=dynamic_apply))(p0, data)
    got = identified(fit.params)
    assert got["f_n_hz"] == pytest.approx(0.5, rel=0.15) and got["zeta"] == pytest.approx(0.4, rel=0.15)
    assert got["delay_s"] == pytest.approx(0.3, rel=0.15) and float(fit.best_val_rms) < 0.004


def test_in_trimmed_flight_the_dynamic_model_is_its_static_map():
    from pvvjax.dynamics import dynamic_apply, dynamic_init
    from pvvjax.nets.networks import mlp_apply, mlp_init

    static = mlp_init(jax.random.key(3), 2, (5,))
    x = np.broadcast_to(np.array([0.3, -0.7], np.float32), (3, 40, 2))
    t = np.broadcast_to(np.arange(40, dtype=np.float32) * 0.23, (3, 40))
    got = dynamic_apply(dynamic_init(static, omega_n=4.0, zeta=0.3, delay_s=0.5), np.concatenate([x, t[..., None]], -1))
    np.testing.assert_allclose(got, np.asarray(mlp_apply(static, x)), rtol=1e-6)
