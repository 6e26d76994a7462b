"""Calibration by gradient against a known lag and against brute-force grids; groups and
databases vmapped equal separate solves."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_replay import lagged_campaign, linear_apply, linear_model

from pvvjax.analysis.databases import STATE_CHANNELS
from pvvjax.data.batch import to_batch
from pvvjax.replay import calibration
from pvvjax.replay import quasistatic as R
from pvvjax.replay.calibration import Bounds, calibrate, cost_grid, counter_costs, group_members


def _per_counter(model, n):
    return jax.tree.map(lambda a: jnp.broadcast_to(a, (n, *jnp.shape(a))), model)


@pytest.fixture(scope="module")
def lagged():
    taus = np.array([0.3, 0.3, 1.1, 1.1])
    camp = lagged_campaign(taus, n=4, seed=2)
    batch = to_batch(camp, STATE_CHANNELS)
    return taus, R.prepare(batch), R.make_settings(batch, hop_revs=1.0), _per_counter(linear_model(), 4)


@pytest.mark.heavy
def test_calibration_recovers_known_lags_per_group(lagged):
    taus, recs, settings, models = lagged
    coarse = np.arange(-1.0, 3.01, 0.5)[:, None]
    # Two groups with different true lags, solved together (vmapped over groups)...
    members, mask = group_members([0, 0, 1, 1])
    cal = calibrate(models, recs, members, mask, jnp.array([0.0, 8.0, 0.0]), coarse, settings=settings,
                    apply=linear_apply)
    np.testing.assert_allclose(np.asarray(cal.theta[:, 0]), [0.3, 1.1], atol=0.03)
    assert np.all(np.asarray(cal.cost) < 0.05 * np.asarray(cal.start_cost))
    # ... equal each group solved alone.
    for g, idx in enumerate(([0, 1], [2, 3])):
        sub = jax.tree.map(lambda a: a[np.array(idx)], (models, recs))
        m1, k1 = group_members([0, 0])
        alone = calibrate(*sub, m1, k1, jnp.array([0.0, 8.0, 0.0]), coarse, settings=settings, apply=linear_apply)
        np.testing.assert_allclose(float(alone.theta[0, 0]), float(cal.theta[g, 0]), atol=1e-4)


def test_per_counter_costs_are_lowest_at_the_true_lag(lagged):
    taus, recs, settings, models = lagged
    at_truth = counter_costs(models, recs, jnp.stack([jnp.asarray(taus), jnp.full(4, 8.0), jnp.zeros(4)], 1),
                             settings=settings, apply=linear_apply)
    off = counter_costs(models, recs, jnp.array([0.7, 8.0, 0.0]), settings=settings, apply=linear_apply)
    assert np.all(np.asarray(at_truth["cost"]) < np.asarray(off["cost"]))
    assert np.abs(np.asarray(at_truth["phase_error_s"])).max() < 0.1


def test_the_reference_window_length_is_data_one_program_serves_every_length(lagged):
    # The measured windows' length (the window-length study's second set-up) enters the cost
    # programs as data: the costs equal those of replays that bake it in, and other lengths
    # reuse the compiled program instead of compiling the replay again.
    _, recs, settings, models = lagged
    theta = jnp.array([0.5, 6.0, 0.0])

    def baked(ref):
        s = settings.replace(reference_revs=ref)
        one = lambda m, r: jnp.sum(R.residuals(R.replay(m, r, 0.5, 6.0, 0.0, settings=s, apply=linear_apply)) ** 2)  # noqa: E731
        return np.asarray(jax.jit(jax.vmap(one))(models, recs))

    n0 = counter_costs._cache_size()
    for ref in (0.0, 8.0, 10.0):
        got = counter_costs(models, recs, theta, settings=settings.replace(reference_revs=ref), apply=linear_apply)
        np.testing.assert_allclose(np.asarray(got["cost"]), baked(ref), rtol=1e-6)
    assert counter_costs._cache_size() - n0 <= 1
    assert not np.allclose(baked(0.0), baked(8.0), rtol=1e-3)


@pytest.fixture(scope="module")
def small_cal(small_campaign_dir, small_dbs):
    from pvvjax.data.campaign import load_campaign
    from pvvjax.nets.networks import rbf_fit
    from pvvjax.nets.sweep import stack_data

    camp = load_campaign(small_campaign_dir)
    ctr = camp.counters[camp.counters.maneuver.isin(["pullup", "pushover", "roll", "flare", "autorotation"])]
    batch = to_batch(camp, STATE_CHANNELS, list(ctr.index))
    data = stack_data(small_dbs, ["db1", "db2"], 5, 0)
    models = []
    for db in ("db1", "db2"):
        x, y, in_mask, _ = data[db]
        p = rbf_fit(jax.random.key(1), x, y, 24, in_mask=in_mask)
        models.append(_per_counter(dict(params=p, idx=jnp.asarray(R.input_index(db))), len(ctr)))
    return R.prepare(batch), R.make_settings(batch, hop_revs=1.0, min_window_revs=6.0), models


@pytest.mark.heavy
def test_gradient_optimum_agrees_with_a_brute_force_grid(small_cal):
    from pvvjax.nets.networks import rbf_apply

    recs, settings, models = small_cal
    members, mask = group_members(np.zeros(recs.time.shape[0], int))
    offsets, lengths = np.arange(-0.5, 2.51, 0.1), np.arange(6.0, 12.01, 0.5)
    coarse = np.stack(np.meshgrid(np.arange(-0.5, 2.51, 0.5), [6.0, 9.0, 12.0], indexing="ij"), -1).reshape(-1, 2)
    for model in models:
        cal = calibrate(model, recs, members, mask, jnp.array([0.0, 8.0, 0.0]), coarse,
                        free=("offset_s", "window_revs"), bounds=Bounds(offset_s=(-0.5, 2.5), window_revs=(6.0, 12.0)),
                        settings=settings, apply=rbf_apply)
        grid = np.asarray(cost_grid(model, recs, members, mask, offsets, lengths, settings=settings,
                                    apply=rbf_apply))[0]
        tau, L = np.asarray(cal.theta[0, :2])
        # Within one grid step of the grid minimum, or of a grid point that ties with it
        # (the cost valley can be flat to 1e-4 over a few grid steps), and no worse.
        jj, kk = np.nonzero(grid <= grid.min() * (1 + 2e-4))
        near = (np.abs(tau - offsets[kk]) <= 0.1 + 1e-6) & (np.abs(L - lengths[jj]) <= 0.5 + 1e-6)
        assert near.any(), (tau, L, offsets[kk], lengths[jj])
        assert float(cal.cost[0]) <= grid.min() * (1 + 2e-4)


@pytest.mark.heavy
def test_calibration_vmaps_over_databases(lagged):
    _, recs, settings, model = lagged
    other = {**model, "params": {**model["params"], "w": model["params"]["w"] * 1.3}}
    members, mask = group_members([0, 0, 1, 1])
    coarse = np.arange(-1.0, 3.01, 0.5)[:, None]
    run = lambda m: calibrate(m, recs, members, mask, jnp.array([0.0, 8.0, 0.0]), coarse,  # noqa: E731
                              settings=settings, apply=linear_apply)
    both = jax.vmap(run)(jax.tree.map(lambda *a: jnp.stack(a), model, other))
    for d, m in enumerate((model, other)):
        # Vmapped, a converged solve idles until the others finish: equal to solver tolerance.
        np.testing.assert_allclose(np.asarray(both.theta[d]), np.asarray(run(m).theta), atol=2e-3)


def test_bad_groups_and_parameters_are_errors(lagged):
    _, recs, settings, models = lagged
    with pytest.raises(ValueError, match="empty group"):
        group_members([0, 2])
    members, mask = group_members([0, 0, 0, 0])
    with pytest.raises(ValueError, match="free parameters"):
        calibrate(models, recs, members, mask, jnp.zeros(3), np.zeros((1, 1)), free=("delay",), settings=settings,
                  apply=linear_apply)


def test_levenberg_marquardt_reaches_optimistixs_minimum_and_keeps_a_flat_parameter():
    import optimistix as optx

    _levenberg_marquardt = calibration._levenberg_marquardt

    t = jnp.linspace(0.0, 3.0, 40)
    data = 2.0 * jnp.exp(-1.3 * t) + 0.01 * jnp.sin(7.0 * t)  # not exactly the model: a residual remains

    def fn(y, _):  # exponential decay; y[2] does not enter (a clipped, flat parameter)
        return y[0] * jnp.exp(-y[1] * t) - data

    y0 = jnp.array([1.0, 0.5, 0.7])
    y, r, steps, ok = jax.jit(lambda y0: _levenberg_marquardt(fn, y0, max_steps=64, rtol=1e-6, atol=1e-8))(y0)
    ref = optx.least_squares(fn, optx.LevenbergMarquardt(rtol=1e-6, atol=1e-8), y0, max_steps=256).value
    assert bool(ok) and int(steps) < 64
    np.testing.assert_allclose(np.asarray(y[:2]), np.asarray(ref[:2]), rtol=1e-4)
    np.testing.assert_allclose(np.asarray(r), np.asarray(fn(y, None)), rtol=1e-6, atol=1e-7)  # the residuals at y
    assert float(y[2]) == float(y0[2])
    # Rosenbrock's valley as least squares: minimum at (1, 1).
    rosen = lambda y, _: jnp.stack([10.0 * (y[1] - y[0] ** 2), 1.0 - y[0]])  # noqa: E731
    y, r, steps, ok = _levenberg_marquardt(rosen, jnp.array([-1.2, 1.0]), max_steps=100, rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(np.asarray(y), [1.0, 1.0], atol=1e-4)
    np.testing.assert_allclose(np.asarray(r), np.asarray(rosen(y, None)), atol=1e-6)
    assert bool(ok)
    # A flat cost (no parameter enters): converged at once, where it started.
    y, _, steps, ok = _levenberg_marquardt(lambda y, _: jnp.full(5, 0.3), jnp.array([0.5, 1.0]), max_steps=20,
                                           rtol=1e-5, atol=1e-6)
    assert bool(ok) and int(steps) == 1 and np.asarray(y).tolist() == [0.5, 1.0]
    # Out of steps: not converged.
    assert not bool(_levenberg_marquardt(rosen, jnp.array([-1.2, 1.0]), max_steps=2, rtol=1e-7, atol=1e-10)[3])


def test_a_parameter_on_its_search_bound_is_named_not_reported_as_fitted():
    from pvvjax.replay import at_bounds

    theta = {"offset_s": 3.0, "window_revs": 8.0, "stick_offset_s": -2.0}
    assert at_bounds(theta, ("offset_s", "window_revs"), Bounds()) == "offset_s=3"
    assert at_bounds(theta, ("window_revs",), Bounds()) == ""
    assert at_bounds(theta, ("offset_s", "stick_offset_s"), Bounds()) == "offset_s=3, stick_offset_s=-2"
    assert at_bounds({**theta, "offset_s": 2.9}, ("offset_s",), Bounds()) == ""
