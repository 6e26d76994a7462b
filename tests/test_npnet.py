import subprocess
import sys

import jax
import numpy as np

from pvvjax.nets.networks import mlp_apply, mlp_init, mlp_pad, rbf_apply, rbf_fit, scaling
from pvvjax.nets.sweep import save_params
from pvvjax.realtime.npnet import NumpyNet


def test_numpy_evaluator_equals_jax_net(tmp_path):
    rng = np.random.default_rng(0)
    x = rng.normal([0.25, 16000, 257, 0.9, 1.2, 0], [0.1, 2000, 5, 0.05, 0.3, 800], (50, 6)).astype(np.float32)
    y = rng.uniform(0.05, 0.3, 50).astype(np.float32)
    p = mlp_pad(mlp_init(jax.random.key(0), 6, (10, 5), scale=scaling(x, y)), (32, 8), 8)
    x8 = np.c_[x, np.zeros((50, 2), np.float32)]
    save_params(tmp_path / "net.npz", jax.tree.map(np.asarray, p), dict(inputs=["a", "b", "c", "d", "e", "f"]))
    net = NumpyNet.load(tmp_path / "net.npz")
    assert net.inputs == ["a", "b", "c", "d", "e", "f"] and [w.shape for w in net.w] == [(6, 10), (10, 5), (5,)]
    np.testing.assert_allclose(net(x), mlp_apply(p, x8), atol=1e-6)
    assert abs(net(x[3]) - float(mlp_apply(p, x8[3]))) < 1e-6  # single sample

    r = rbf_fit(jax.random.key(1), x, y, 12)
    save_params(tmp_path / "rbf.npz", jax.tree.map(np.asarray, r), {})
    np.testing.assert_allclose(NumpyNet.load(tmp_path / "rbf.npz")(x), rbf_apply(r, x), atol=1e-6)


def test_numpy_evaluator_imports_no_jax():
    code = "import sys, pvvjax.realtime.npnet; assert 'jax' not in sys.modules, 'jax imported'; print('ok')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr


def test_a_gru_evaluates_as_the_recurrent_model_and_steps_window_by_window(tmp_path):
    """A saved `rnn` model (a GRU with its standardisation) evaluates as `dynamics.rnn_apply`
    along a sequence from a zero state, and `step` from `initial_state` gives the same
    windows one at a time."""
    import jax.numpy as jnp

    from pvvjax.dynamics import rnn_apply, rnn_init

    rng = np.random.default_rng(1)
    x = rng.normal([0.25, 16000, 0.0], [0.1, 2000, 3.0], (4, 40, 3))
    scale = dict(x_shift=jnp.array([0.25, 16000, 0.0]), x_scale=jnp.array([0.1, 2000, 3.0]),
                 y_shift=jnp.array(0.1), y_scale=jnp.array(0.05))
    p = rnn_init(jax.random.key(2), 3, 6, scale=scale)
    save_params(tmp_path / "gru.npz", jax.tree.map(np.asarray, p), {})
    net = NumpyNet.load(tmp_path / "gru.npz")
    assert net.stateful and net.hidden == 6 and net.n_in == 3
    want = np.asarray(rnn_apply(p, jnp.asarray(x, jnp.float32)))
    np.testing.assert_allclose(net(x), want, atol=1e-6)
    h, got = net.initial_state(), []
    for w in range(x.shape[1]):
        h, y = net.step(h, x[1, w])
        got.append(y)
    np.testing.assert_allclose(got, net(x)[1], rtol=0, atol=1e-12)
    assert np.ptp(want[1]) > 1e-3  # the state moves the prediction
