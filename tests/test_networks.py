import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pvvjax.nets.networks import architecture_name, mlp_apply, mlp_init, mlp_pad, n_weights, rbf_apply, rbf_fit, scaling


def _numpy_mlp(params, x):
    """Independent NumPy forward pass."""
    h = (x - np.asarray(params["x_shift"])) / np.asarray(params["x_scale"])
    for layer in params["layers"][:-1]:
        h = np.tanh(h @ np.asarray(layer["w"]) + np.asarray(layer["b"]))
    out = h @ np.asarray(params["layers"][-1]["w"]) + np.asarray(params["layers"][-1]["b"])
    return out[:, 0] * float(params["y_scale"]) + float(params["y_shift"])


def test_mlp_matches_numpy_reference_with_scaling():
    rng = np.random.default_rng(0)
    x = rng.normal(50, 10, (40, 6)).astype(np.float32)
    y = rng.uniform(0.05, 0.3, 40).astype(np.float32)
    p = mlp_init(jax.random.key(0), 6, (10, 5), scale=scaling(x, y))
    np.testing.assert_allclose(mlp_apply(p, x), _numpy_mlp(p, x), rtol=1e-5, atol=1e-6)
    assert architecture_name(6, (10, 5)) == "6-10-5-1" and n_weights(6, (10, 5)) == 131


@pytest.mark.parametrize("hidden, max_hidden, n_in, n_pad", [((10, 5), (32, 8), 6, 8), ((3,), (16,), 7, 8)])
def test_padded_net_equals_unpadded_twin_gradients_included(hidden, max_hidden, n_in, n_pad):
    rng = np.random.default_rng(1)
    x = rng.normal(size=(30, n_in)).astype(np.float32)
    y = rng.normal(size=30).astype(np.float32)
    p = mlp_init(jax.random.key(2), n_in, hidden, scale=scaling(x, y))
    pp = mlp_pad(p, max_hidden, n_pad)
    xp = np.concatenate([x, rng.normal(size=(30, n_pad - n_in)).astype(np.float32)], 1)  # junk in padded inputs
    apply = jax.jit(mlp_apply)  # jitted: one program each, not hundreds of op-by-op ones
    np.testing.assert_allclose(apply(pp, xp), apply(p, x), rtol=1e-6, atol=1e-7)

    loss = lambda layers, params, xx: jnp.mean((mlp_apply({**params, "layers": layers}, xx) - y) ** 2)  # noqa: E731
    grad = jax.jit(jax.grad(loss))
    g = grad(p["layers"], p, x)
    gp = grad(pp["layers"], pp, xp)
    for a, b in zip(g, gp):
        for k in ("w", "b"):
            real = b[k][tuple(slice(0, s) for s in a[k].shape)]
            np.testing.assert_allclose(real, a[k], rtol=1e-5, atol=1e-7)
            padded = np.asarray(b[k]).copy()
            padded[tuple(slice(0, s) for s in a[k].shape)] = 0
            assert not padded.any()  # padded units and inputs receive exactly zero gradient


def test_init_with_max_hidden_is_a_padded_init():
    p = mlp_init(jax.random.key(3), 8, (4, 5), max_hidden=(16, 5), in_mask=np.r_[np.ones(6), 0, 0])
    assert p["layers"][0]["w"].shape == (8, 16)
    assert np.asarray(p["masks"][0]).sum() == 4 and np.asarray(p["in_mask"]).sum() == 6
    with pytest.raises(ValueError, match="does not fit"):
        mlp_init(jax.random.key(3), 8, (20, 5), max_hidden=(16, 5))


def test_rbf_network_fits_a_smooth_function_and_matches_least_squares():
    rng = np.random.default_rng(4)
    x = rng.uniform(-2, 2, (200, 2)).astype(np.float32)
    y = (np.sin(x[:, 0]) + 0.5 * x[:, 1] ** 2).astype(np.float32)
    p = rbf_fit(jax.random.key(0), x, y, 25)
    xt = rng.uniform(-2, 2, (200, 2)).astype(np.float32)
    yt = np.sin(xt[:, 0]) + 0.5 * xt[:, 1] ** 2
    assert np.sqrt(np.mean((np.asarray(rbf_apply(p, xt)) - yt) ** 2)) < 0.06 * yt.std()  # held-out points
    # output weights are the ridge least-squares solution (ridge 1e-3) for the fitted centres and widths
    z = (x - np.asarray(p["x_shift"])) / np.asarray(p["x_scale"])
    d2 = ((z[:, None, :] - np.asarray(p["centers"])) ** 2).sum(-1)
    phi = np.exp(-0.5 * d2 / np.exp(2 * np.asarray(p["log_width"])))
    A = np.c_[phi, np.ones(len(x))]
    t = (y - float(p["y_shift"])) / float(p["y_scale"])
    sol = np.linalg.solve(A.T @ A + 1e-3 * np.eye(A.shape[1]), A.T @ t)
    np.testing.assert_allclose(A @ np.r_[np.asarray(p["w"]), float(p["b"])], A @ sol, atol=2e-3)


def test_the_flax_modules_own_their_variables_and_apply_as_the_functions_do():
    # `MLP.init` makes the variables of the allocation (layers to train; masks, input mask and
    # scaling as constants) with the same padding-invariant draw as `mlp_init`, from the key
    # linen derives for the layers; the functions apply the modules to the flat dicts.
    from pvvjax.nets.networks import MLP, RBF

    x = np.random.default_rng(5).normal(size=(20, 8)).astype(np.float32)
    module = MLP(8, (4, 5), (16, 5))
    variables = module.init(jax.random.key(0), x)
    assert set(variables) == {"params", "constants"} and list(variables["params"]) == ["layers"]
    assert [layer["w"].shape for layer in variables["params"]["layers"]] == [(8, 16), (16, 5), (5, 1)]
    assert np.asarray(variables["constants"]["masks"][0]).sum() == 4
    flat = {**variables["params"], **variables["constants"]}
    np.testing.assert_array_equal(module.apply(variables, x), mlp_apply(flat, x))
    p = mlp_init(jax.random.key(1), 8, (4, 5), max_hidden=(16, 5))
    ref = MLP(8, (4, 5), (16, 5)).apply({"params": {"layers": p["layers"]},
                                         "constants": {k: v for k, v in p.items() if k != "layers"}}, x)
    np.testing.assert_array_equal(ref, mlp_apply(p, x))
    # variables of another allocation are refused, naming the layers
    with pytest.raises(Exception, match="layers"):
        MLP(8, (4, 5), (8, 5)).apply(variables, x)
    r = rbf_fit(jax.random.key(2), x, x[:, 0] ** 2, 6)
    assert RBF(6, 8).init(jax.random.key(0), x)["params"]["centers"].shape == (6, 8)
    np.testing.assert_array_equal(rbf_apply(r, x), jax.jit(RBF(6, 8).apply)(  # rbf_apply is jitted: the same program
        {"params": {k: r[k] for k in ("centers", "log_width", "w", "b")},
         "constants": {k: r[k] for k in ("in_mask", "x_shift", "x_scale", "y_shift", "y_scale")}}, x))


def test_a_multi_output_net_matches_numpy_and_its_padded_twin_trains_the_same():
    # Three outputs at once (e.g. the N/rev of the three pilot-floor axes), each scaled on its own.
    from pvvjax.config import TrainConfig
    from pvvjax.nets.train import fit, make_data

    rng = np.random.default_rng(4)
    x = rng.normal(size=(40, 6)).astype(np.float32)
    y = np.stack([np.tanh(x[:, 0]) * 0.1 + 0.2, 0.05 * np.tanh(x[:, 1]), 0.02 * x[:, 2] + 0.1], 1).astype(np.float32)
    sc = scaling(x, y)
    np.testing.assert_allclose(sc["y_shift"], y.mean(0), rtol=1e-5)
    np.testing.assert_allclose(sc["y_scale"], y.std(0), rtol=1e-4)
    p = mlp_init(jax.random.key(5), 6, (8, 4), scale=sc, n_out=3)
    h = (x - np.asarray(sc["x_shift"])) / np.asarray(sc["x_scale"])
    for layer in p["layers"][:-1]:
        h = np.tanh(h @ np.asarray(layer["w"]) + np.asarray(layer["b"]))
    ref = (h @ np.asarray(p["layers"][-1]["w"]) + np.asarray(p["layers"][-1]["b"])) * np.asarray(sc["y_scale"]) \
        + np.asarray(sc["y_shift"])
    assert mlp_apply(p, x).shape == (40, 3) and architecture_name(6, (8, 4), 3) == "6-8-4-3"
    np.testing.assert_allclose(mlp_apply(p, x), ref, rtol=1e-5, atol=1e-6)
    assert n_weights(6, (8, 4), 3) == sum(a * b + b for a, b in ((6, 8), (8, 4), (4, 3)))

    pp = mlp_pad(p, (16, 8), 8)
    xp = np.concatenate([x, rng.normal(size=(40, 2)).astype(np.float32)], 1)
    np.testing.assert_allclose(mlp_apply(pp, xp), mlp_apply(p, x), rtol=1e-6, atol=1e-7)
    tr, va = np.arange(40) < 30, np.arange(40) >= 30
    cfg = TrainConfig(learning_rate=1e-2, max_steps=1000, eval_every=20)
    a, b = fit(p, make_data(x, y, tr, va), cfg), fit(pp, make_data(xp, y, tr, va), cfg)
    assert int(a.steps) == int(b.steps) > 0 and float(a.best_val_rms) == pytest.approx(float(b.best_val_rms), rel=1e-4)
    np.testing.assert_allclose(mlp_apply(b.params, xp), mlp_apply(a.params, x), rtol=1e-4, atol=1e-5)
    assert float(a.best_val_rms) < 0.5 * float(np.sqrt(np.mean((y[va] - y[tr].mean(0)) ** 2)))
