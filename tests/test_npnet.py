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
