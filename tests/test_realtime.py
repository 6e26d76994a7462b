"""The JAX element step: equals the NumPy element frame by frame, runs a record in one
scan, vmaps over records, and ignores rejected (NaN-padded) frames."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import rbf_nets

from pvvjax.analysis.databases import DB_INPUTS
from pvvjax.data.campaign import load_campaign
from pvvjax.realtime import jax_element as RT
from pvvjax.realtime.element import CHANNELS, VibrationElement
from pvvjax.realtime.npnet import NumpyNet

F = 13312  # every record padded to this many frames (rejected NaN frames), one compiled scan


@pytest.fixture(scope="module")
def setup(small_campaign_dir, small_dbs):
    params, envelope = rbf_nets(small_dbs, "db2")
    return load_campaign(small_campaign_dir), params, envelope


def _padded(camp, counter):
    rec = camp.records[counter]
    n = len(rec)
    assert n <= F
    pad = lambda v: np.concatenate([v, np.full((F - n, *v.shape[1:]), np.nan)])  # noqa: E731
    return (pad(rec.time_s.to_numpy()), pad(rec.azimuth_deg.to_numpy()), pad(rec[list(CHANNELS)].to_numpy(float)), n)


@pytest.mark.parametrize("kind", ["pullup", "autorotation", "roll"])
def test_jax_stream_equals_the_numpy_element(setup, kind):
    camp, params, envelope = setup
    counter = camp.counters.index[camp.counters.maneuver == kind][0]
    T, AZ, X, n = _padded(camp, counter)
    kw = dict(window_revs=8.0, hop_revs=1.0, offset_s=0.7, stick_offset_s=-0.4, phase_rad=0.3,
              harmonics={1: (0.2, 0.5), 8: (0.1, -1.0)})
    el = VibrationElement([NumpyNet(p) for p in params], DB_INPUTS["db2"], envelope=envelope, **kw)
    ref = np.array([tuple(el.step(T[i], AZ[i], X[i]))[:6] for i in range(n)], float)
    with jax.enable_x64(True):
        stacked = jax.tree.map(lambda *a: jnp.stack([jnp.asarray(v, jnp.float64) for v in a]), *params)
        spec = RT.make_spec(stacked, DB_INPUTS["db2"], envelope=envelope, **kw)
        state, out = RT.stream(spec, RT.init(RT.capacity_for(8.0, 1.0, [0.7, 0.3], 320.0)), T, AZ, X)
        got = np.stack([np.asarray(o, float) for o in tuple(out)[:6]], 1)
    assert ref[:, 3].sum() > 10  # windows were predicted
    np.testing.assert_allclose(got[:n], ref, rtol=0, atol=1e-9, equal_nan=True)
    assert np.asarray(out.rejected)[n:].all() and not np.asarray(out.rejected)[:n].any()
    assert int(state.n) == n  # the padding frames were not stored


def test_single_steps_and_vmap_over_records(setup):
    camp, params, _ = setup
    counters = list(camp.counters.index[camp.counters.maneuver == "pullup"][:2])
    frames = [_padded(camp, c) for c in counters]
    stacked = jax.tree.map(lambda *a: jnp.stack(a), *params)
    spec = RT.make_spec(stacked, DB_INPUTS["db2"], offset_s=0.5)
    s0 = RT.init(2048)
    both = jax.vmap(RT.stream, in_axes=(None, None, 0, 0, 0))(spec, s0, *[jnp.asarray(np.stack(v)) for v in
                                                                        list(zip(*frames))[:3]])[1]
    one = RT.stream(spec, s0, *frames[1][:3])[1]
    np.testing.assert_allclose(np.asarray(both.pvv_g[1]), np.asarray(one.pvv_g), atol=1e-6)
    # Frame by frame through the jitted step: the same as the scan.
    step = jax.jit(RT.step)
    s = s0
    T, AZ, X, _ = frames[0]
    for i in range(700):
        s, o = step(spec, s, T[i], AZ[i], X[i])
    np.testing.assert_allclose(float(o.pvv_g), float(both.pvv_g[0, 699]), atol=1e-6)
    assert bool(o.ready)
