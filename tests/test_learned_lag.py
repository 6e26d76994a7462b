"""The lag learned inside one training (`discovery._learned`): the lag it trains through is
the model's (`_lag_windows`) and an exact window-by-window loop, its gradient in τ matches
finite differences, and it recovers the time constant of a known lag and finds none where
there is none."""

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd
import pytest
from conftest import lag_loop

from pvvjax.discovery import _learned, _model

fit_learned_lag = _learned.fit_learned_lag
_lag_windows, _Windows = _model._lag_windows, _model._Windows
lagged_windows, window_layout = _model.lagged_windows, _model.window_layout



def _windows(first_k=(0, 3, 1), n=(40, 30, 25), dt=0.25, seed=0):
    """Counters whose windows start at column `first_k` (a leading gap) with one missing
    window inside the last, at jittered times."""
    rng = np.random.default_rng(seed)
    rows = []
    for i, (k0, m) in enumerate(zip(first_k, n)):
        ks = [k for k in range(k0, k0 + m) if not (i == 2 and k == k0 + 10)]
        rows += [dict(i=i, k=k, time_s=dt * k + 0.02 * rng.random()) for k in ks]
    t = pd.DataFrame(rows)
    return _Windows(t, (len(n), int(t.k.max()) + 1), (), None)


def test_the_lag_trained_through_is_the_models_lag_and_an_exact_window_loop():
    win = _windows()
    u = np.random.default_rng(1).standard_normal((2, len(win.table)))
    layout = window_layout(win)
    for tau in (0.3, 2.0):
        want = lag_loop(u, win.table, tau)
        np.testing.assert_allclose(_lag_windows(u, win, tau), want, atol=2e-6)
        got = np.asarray(lagged_windows(jnp.asarray(u, jnp.float32), layout, tau))
        np.testing.assert_allclose(got, want, atol=2e-6)
        np.testing.assert_allclose(np.asarray(lagged_windows(jnp.asarray(u[0], jnp.float32), layout, tau)), want[0],
                                   atol=2e-6)
    assert np.array_equal(_lag_windows(u, win, 0.0), u)


def test_the_gradient_in_tau_matches_finite_differences():
    win = _windows()
    layout = window_layout(win)
    u = jnp.asarray(np.random.default_rng(2).standard_normal(len(win.table)), jnp.float32)
    y = jnp.asarray(np.random.default_rng(3).standard_normal(len(win.table)), jnp.float32)
    loss = jax.jit(lambda tau: jnp.sum((lagged_windows(u, layout, tau) - y) ** 2))
    for tau in (0.5, 1.5):
        h = 1e-3 * tau
        fd = (float(loss(tau + h)) - float(loss(tau - h))) / (2 * h)
        assert float(jax.grad(loss)(tau)) == pytest.approx(fd, rel=2e-2)


def _world(tau_true, seed=0, n_counters=40, n_windows=48, dt=0.25):
    """Counters of two slowly varying inputs; PVV a static map of them, lagged by tau_true
    (none if 0), plus noise."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n_counters):
        t = dt * np.arange(n_windows)
        a = np.cumsum(rng.standard_normal(n_windows)) * 0.3 + rng.standard_normal()
        steps = np.where(t > rng.uniform(2, 8), rng.uniform(-1.5, 1.5), 0.0)  # a step, as a maneuver's entry
        rows += [dict(i=i, k=k, time_s=t[k], x1=a[k], x2=steps[k]) for k in range(n_windows)]
    tab = pd.DataFrame(rows)
    win = _Windows(tab, (n_counters, n_windows), (), None)
    static = 0.1 + 0.03 * np.tanh(tab.x1.to_numpy()) + 0.04 * tab.x2.to_numpy()
    y = _lag_windows(static[None], win, tau_true)[0] if tau_true > 0 else static
    y = y + 0.002 * rng.standard_normal(len(y))
    return win, tab[["x1", "x2"]].to_numpy(), y


@pytest.mark.parametrize("tau_true", [0.0, 2.0])
def test_it_recovers_a_known_lag_and_finds_none_without_one(tau_true):
    win, x, y = _world(tau_true)
    folds = win.table.i.to_numpy() % 3
    train_w = np.stack([folds != f for f in range(3)]).astype(float)
    fit = fit_learned_lag(x, y, train_w, window_layout(win), 3, seeds=2, hidden=(6,), steps=600, learning_rate=0.02)
    tau = fit["tau_s"]
    assert tau.shape == (3, 2) and fit["pred"].shape == (3, 2, len(y))
    if tau_true:
        assert np.median(tau) == pytest.approx(tau_true, rel=0.15)
    else:
        assert np.median(tau) < 0.3
    held = fit["pred"][folds, :, np.arange(len(y))]  # every window by the nets that held it out
    assert np.sqrt(np.mean((np.median(held, 1) - y) ** 2)) < 0.01  # a lagged map, learned
