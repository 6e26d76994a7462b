"""Locating residuals: a misfit planted in one maneuver kind, regime and time inside the
maneuvers is found there; replay tables carry what localization needs."""

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd
import pytest
from conftest import rbf_nets

from pvvjax.analysis.databases import STATE_CHANNELS
from pvvjax.data.batch import to_batch
from pvvjax.data.campaign import load_campaign
from pvvjax.discovery.residuals import by_group, localize, residual_windows
from pvvjax.replay.quasistatic import input_index, make_settings, prepare
from pvvjax.replay.tables import replay_windows


def _windows(seed=0):
    rng = np.random.default_rng(seed)
    rows = []
    for kind in ("pullup", "roll", "flare", "level"):
        for c in range(6):
            n = 30
            t = np.arange(n) * 1.0
            mu = rng.uniform(0.1, 0.4, n)
            measured = 0.1 + rng.normal(0, 0.005, n)
            predicted = measured + rng.normal(0, 0.005, n)
            if kind == "flare":  # planted: late in the flare and at high advance ratio
                late = (t >= 20) & (mu > 0.3)
                predicted[late] -= 0.08
            rows.append(pd.DataFrame(dict(database="db1", counter=f"{kind}{c}", condition=f"{kind}{c}", maneuver=kind,
                                          window=np.arange(n), time_s=t, measured_g=measured, predicted_g=predicted,
                                          weight=1.0, advance_ratio=mu, mlf=rng.uniform(0.8, 1.6, n))))
    return pd.concat(rows, ignore_index=True)


def test_a_planted_misfit_is_located():
    loc = localize(_windows())
    assert loc["maneuver"].index[0] == "flare" and loc["maneuver"].concentration.iloc[0] > 2.5
    top_regime = loc["regime:advance_ratio"].sort_values("share_sq").index[-1]
    assert top_regime.left >= 0.28  # the highest advance-ratio bin
    assert loc["time"].index[0].startswith("flare @") and loc["time"].index[0].endswith("1.0]")
    assert loc["counter"].index[0].startswith("flare")
    assert loc["maneuver"].share_sq.sum() == pytest.approx(1.0)
    # Signs: the model under-predicts there (predicted lowered), so the residual is positive.
    assert loc["maneuver"].loc["flare", "mean_residual_g"] > 0.005
    assert loc["time"].mean_residual_g.iloc[0] > 0.02


def test_residual_windows_and_errors():
    w = _windows()
    w.loc[:3, "weight"] = 0.5
    res = residual_windows(w)
    assert len(res) == len(w) - 4 and res.position.between(0, 1).all()
    assert by_group(res, "maneuver").windows.sum() == len(res)
    with pytest.raises(ValueError, match="one database"):
        localize(pd.concat([w, w.assign(database="db2")]))


def test_replay_windows_carry_the_features(small_campaign_dir, small_dbs):
    camp = load_campaign(small_campaign_dir)
    counters = list(camp.counters.index[camp.counters.maneuver.isin(["pullup", "roll"])])
    params, _ = rbf_nets(small_dbs, "db1", n=2)
    stacked = jax.tree.map(lambda *a: jnp.stack(a), *params)
    model = jax.tree.map(lambda a: jnp.broadcast_to(a, (len(counters), *a.shape)),
                         dict(params=stacked, idx=jnp.asarray(input_index("db1"))))
    info = camp.counters.loc[counters, ["maneuver", "condition"]]
    batch = to_batch(camp, STATE_CHANNELS, counters)
    w = replay_windows(info, prepare(batch), {"db1": model}, (0.5, 8.0, 0.0), make_settings(batch, hop_revs=1.0))
    assert {"advance_ratio", "mlf", "collective_pct"} <= set(w.columns)
    assert w.advance_ratio.between(0.0, 0.5).all()
    loc = localize(w)
    assert set(loc["maneuver"].index) == {"pullup", "roll"}
