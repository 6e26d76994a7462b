import jax
import numpy as np
import pytest

from pvvjax.config import TrainConfig
from pvvjax.nets.networks import mlp_apply, mlp_init, scaling
from pvvjax.nets.train import condition_folds, fit, hyper, make_data, masked_metrics, split_masks


def test_folds_split_by_condition_never_by_row():
    cond = np.repeat([f"c{i}" for i in range(20)], 3)
    folds = condition_folds(cond, 5, seed=0)
    for c in np.unique(cond):
        assert len(set(folds[cond == c])) == 1
    assert sorted(np.bincount(folds)) == [12] * 5
    np.testing.assert_array_equal(folds, condition_folds(cond, 5, seed=0))
    tr, va, te = split_masks(folds, 2, 5)
    np.testing.assert_array_equal(tr + va + te, 1.0)
    assert set(cond[te > 0]).isdisjoint(cond[tr > 0]) and set(cond[va > 0]).isdisjoint(cond[tr > 0])
    with pytest.raises(ValueError, match="k-fold"):
        condition_folds(cond, 2, 0)


def _problem(n=160, seed=0):
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, (n, 3)).astype(np.float32)
    y = 0.15 + 0.05 * np.sin(2 * x[:, 0]) + 0.03 * x[:, 1] * x[:, 2] + 0.002 * rng.standard_normal(n)
    y = y.astype(np.float32)
    folds = condition_folds(np.arange(n), 5, 0)
    tr, va, te = split_masks(folds, 0, 5)
    return x, y, tr, va, te


def test_training_reaches_the_noise_floor_on_held_out_rows():
    x, y, tr, va, te = _problem()
    p0 = mlp_init(jax.random.key(0), 3, (10, 5), scale=scaling(x[tr > 0], y[tr > 0]))
    cfg = TrainConfig(learning_rate=1e-2, max_steps=20000, patience=20, eval_every=50)
    f = jax.jit(lambda p, d: fit(p, d, cfg))(p0, make_data(x, y, tr, va))
    assert int(f.failed_step) == -1 and int(f.best_step) > 0
    test = masked_metrics(mlp_apply(f.params, x), y, te)
    assert test["rms_g"] < 0.01  # signal std 0.04 g, noise 0.002 g
    assert float(f.best_val_rms) == pytest.approx(masked_metrics(mlp_apply(f.params, x), y, va)["rms_g"], rel=1e-4)
    # masks and scalings never train
    np.testing.assert_array_equal(f.params["x_scale"], p0["x_scale"])
    np.testing.assert_array_equal(f.params["masks"][0], p0["masks"][0])


def test_nan_loss_is_reported_with_its_step():
    x, y, tr, va, _ = _problem()
    y = y.copy()
    y[np.flatnonzero(tr)[3]] = np.nan
    p0 = mlp_init(jax.random.key(0), 3, (5,), scale=scaling(x[tr > 0], np.nan_to_num(y[tr > 0])))
    f = fit(p0, make_data(x, y, tr, va), TrainConfig(eval_every=10))
    assert int(f.failed_step) == 10


def test_divergence_is_detected():
    x, y, tr, va, _ = _problem()
    p0 = mlp_init(jax.random.key(0), 3, (5,), scale=scaling(x[tr > 0], y[tr > 0]))
    cfg = TrainConfig(eval_every=10, divergence_factor=10.0)  # a config refuses a step size above 1: pass it traced
    f = fit(p0, make_data(x, y, tr, va), cfg, hp=hyper(cfg, learning_rate=1e4))
    assert int(f.failed_step) > 0


def test_vmapped_training_equals_one_by_one():
    x, y, tr, va, _ = _problem()
    d = make_data(x, y, tr, va)
    ps = [mlp_init(jax.random.key(i), 3, (6,), scale=scaling(x[tr > 0], y[tr > 0])) for i in range(3)]
    cfg = TrainConfig(max_steps=500)
    stacked = jax.tree.map(lambda *a: np.stack(a), *ps)
    fv = jax.vmap(lambda p: fit(p, d, cfg))(stacked)
    for i, p in enumerate(ps):
        f = fit(p, d, cfg)
        assert int(fv.best_step[i]) == int(f.best_step)
        np.testing.assert_allclose(fv.best_val_rms[i], f.best_val_rms, rtol=1e-4)
