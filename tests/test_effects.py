"""Candidate-effect operators against independent references: a sample-by-sample loop and
the analytic step response for the lag, numpy.gradient for the rate, finite differences
for the gradients in τ and the knee."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from pvvjax.discovery import effects as E


def _signal(n=2000, seed=0, jitter=0.2):
    rng = np.random.default_rng(seed)
    dt = (1 + jitter * rng.uniform(-1, 1, n)) / 320.0  # nearly uniform, like flight-test frames
    t = np.concatenate([[0.0], np.cumsum(dt[1:])])
    x = np.sin(2 * np.pi * 0.3 * t) + 0.5 * np.sin(2 * np.pi * 1.7 * t + 1.0) + 0.05 * rng.standard_normal(n)
    return t, x


def test_lag_matches_a_sample_loop_and_the_step_response():
    lag = jax.jit(E.lag)  # one program (op by op, the scan's levels are a hundred small ones)
    with jax.enable_x64(True):
        t, x = _signal()
        tau = 0.6
        y = np.asarray(lag(jnp.asarray(x), jnp.asarray(t), tau))
        ref = np.empty_like(x)
        ref[0] = x[0]
        for n in range(1, len(x)):
            a = np.exp(-(t[n] - t[n - 1]) / tau)
            ref[n] = a * ref[n - 1] + (1 - a) * x[n]
        np.testing.assert_allclose(y, ref, rtol=0, atol=1e-12)
        # Unit step at rest: 1 − exp(−t/τ) at the sample times (input held between samples).
        step = np.r_[0.0, np.ones(len(t) - 1)]
        ys = np.asarray(lag(jnp.asarray(step), jnp.asarray(t), tau))
        np.testing.assert_allclose(ys, 1 - np.exp(-(t - t[0]) / tau), atol=1e-12)


def test_lag_gradient_in_tau_matches_finite_differences():
    with jax.enable_x64(True):
        t, x = (jnp.asarray(v) for v in _signal(seed=1))
        f = jax.jit(lambda tau: jnp.sum(E.lag(x, t, tau) ** 2))
        g = float(jax.grad(f)(0.8))
        h = 1e-6
        assert g == pytest.approx((float(f(0.8 + h)) - float(f(0.8 - h))) / (2 * h), rel=1e-6)


def test_rate_matches_numpy_gradient_and_abs_rate_is_smooth():
    with jax.enable_x64(True):
        t, x = _signal(jitter=0.0)
        r = np.asarray(E.rate(jnp.asarray(x), jnp.asarray(t)))
        ref = np.gradient(x, t)
        np.testing.assert_allclose(r[1:-1], ref[1:-1], rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(np.asarray(E.abs_rate(jnp.asarray(x), jnp.asarray(t))), np.abs(r), atol=1e-6)
        g = jax.grad(lambda s: jnp.sum(E.abs_rate(s * jnp.asarray(x), jnp.asarray(t))))(1.0)
        assert np.isfinite(float(g))


def test_threshold_is_a_softened_hinge_with_a_knee_gradient():
    with jax.enable_x64(True):
        x = jnp.linspace(-1.0, 1.0, 401)
        for above in (True, False):
            y = np.asarray(E.threshold(x, 0.2, above=above, softness=1e-4))
            ref = np.maximum(0.0, np.asarray(x) - 0.2) if above else np.maximum(0.0, 0.2 - np.asarray(x))
            np.testing.assert_allclose(y, ref, atol=1e-4)
        f = lambda k: jnp.sum(E.threshold(x, k, softness=0.05))  # noqa: E731
        h = 1e-6
        assert float(jax.grad(f)(0.1)) == pytest.approx((float(f(0.1 + h)) - float(f(0.1 - h))) / (2 * h), rel=1e-6)


def test_resonance_product_and_window_spread():
    rpm = jnp.linspace(240.0, 270.0, 301)
    band = np.asarray(E.resonance(rpm, 258.0, 2.0))
    assert float(rpm[np.argmax(band)]) == pytest.approx(258.0) and band.max() == pytest.approx(1.0)
    assert band[0] < 1e-6
    np.testing.assert_allclose(np.asarray(E.product(rpm, 2.0)), 2 * np.asarray(rpm))
    x = np.random.default_rng(0).standard_normal(1000)
    spread = float(E.window_spread(jnp.mean(x), jnp.mean(x * x)))
    assert spread == pytest.approx(np.std(x), rel=1e-5)
    assert set(E.OPERATORS) == {"input", "rate", "abs_rate", "lag", "threshold", "product", "resonance", "window"}


def test_a_lorentzian_band_keeps_the_tails_a_gaussian_loses():
    # A mode of half-width w: at 2 w the Lorentzian is 1/5, the Gaussian e^-2; at 5 w, 1/26
    # and ~4e-6 (rotor-speed settings several widths from a mode still feel it).
    rpm = jnp.array([258.0, 262.0, 268.0])
    np.testing.assert_allclose(np.asarray(E.resonance(rpm, 258.0, 2.0, "lorentzian")), [1.0, 0.2, 1 / 26], rtol=1e-6)
    np.testing.assert_allclose(np.asarray(E.resonance(rpm, 258.0, 2.0)), np.exp(-0.5 * np.array([0.0, 4.0, 25.0])),
                               rtol=1e-6)
    u = np.linspace(-3.0, 3.0, 7)
    np.testing.assert_allclose(E.band(u, "lorentzian", np), np.asarray(E.band(jnp.asarray(u), "lorentzian")), rtol=1e-6)
    with pytest.raises(ValueError, match="'cauchy'"):
        E.band(u, "cauchy", np)
