"""The lag study: de-lagging against the exact lag recursion, and the study's nets on a
world without a hidden lag."""

import numpy as np
import pandas as pd
import pytest

from pvvjax.discovery import _lag_windows, _Windows, delag
from pvvjax.lag_study import lag_study


def _slow_windows(n_counters=4, W=160, dt=0.25):
    rows = [dict(i=i, k=k, time_s=dt * k, weight=1.0) for i in range(n_counters) for k in range(W)]
    return _Windows(pd.DataFrame(rows), (n_counters, W), (), None)


def test_delag_undoes_the_exact_lag_recursion():
    # A slow vibration (periods 9-15 s, like a maneuver) through the exact first-order lag of
    # the replay; de-lagging recovers it to the central difference's error, in any row order.
    win = _slow_windows()
    t, i = win.table.time_s.to_numpy(), win.table.i.to_numpy()
    u = 0.12 + 0.05 * np.sin(2 * np.pi * t / (9 + 2 * i) + i)
    y = _lag_windows(u[None], win, 2.0)[0]
    got = delag(y, t, i, 2.0)
    inner = t > 8.0  # past the start at rest (and its one-sided difference)
    inner &= t < t.max() - 1.0
    assert np.max(np.abs(got - u)[inner]) < 0.005 < 0.03 < np.max(np.abs(y - u)[inner])
    perm = np.random.default_rng(0).permutation(len(u))
    np.testing.assert_allclose(delag(y[perm], t[perm], i[perm], 2.0), got[perm], rtol=1e-12)
    np.testing.assert_array_equal(delag(y, t, i, 0.0), y)


def test_a_world_without_a_hidden_lag_gains_nothing_from_nets_trained_through_one(monkeypatch):
    # The nets train on the de-lagged strided windows (recorded), their offset is refitted,
    # and on a world with nothing hidden a 2 s lag does not lower the held-out RMS by 5 %.
    from test_discovery import _BASE, _FAST

    from pvvjax import discovery as D
    from pvvjax._strict import from_dict
    from pvvjax.campaign import campaign_from_frames
    from pvvjax.config import DiscoveryConfig, ExperimentConfig
    from pvvjax.synth import SynthConfig, generate

    camp = campaign_from_frames(*generate(from_dict(SynthConfig, {**_BASE, "name": "null", "seed": 51}))[:2])
    calls, fit = [], D.fit_ensemble

    def recorded(x, y, folds, **kw):
        calls.append(y)
        return fit(x, y, folds, **kw)

    monkeypatch.setattr(D, "fit_ensemble", recorded)
    replays, replay = {}, D._replay
    monkeypatch.setattr(D, "_replay", lambda ctx, off: replays.setdefault(off, replay(ctx, off)))
    cfg = ExperimentConfig(discovery=from_dict(DiscoveryConfig, {**_FAST, "train_stride": 16}))
    with pytest.raises(ValueError, match="reference_offsets inside discovery.offset_bounds"):
        lag_study(camp, cfg, reference_offsets=(5.0,))
    t = lag_study(camp, cfg, taus=(2.0,), reference_offsets=(), log=lambda m: None)
    assert list(t.tau_s) == [0.0, 2.0] and len(calls) == 3  # the peak nets, then τ = 0 and 2 s
    lo, hi = cfg.discovery.offset_bounds
    assert t.train_offset_s[1] == max(lo, round(t.train_offset_s[0] - 2.0, 6))
    assert t.offset_s.between(lo, hi).all() and t["drop"][0] == 0.0
    win = replays[t.train_offset_s[1]].table
    rows = (win.weight.to_numpy() >= 0.999) & (win.k.to_numpy() % 16 == 0)
    want = delag(win.measured_g.to_numpy(), win.time_s.to_numpy(), win.i.to_numpy(), 2.0)[rows]
    np.testing.assert_allclose(calls[2], want, rtol=1e-5)
    assert t["drop"][1] < 0.05, t
