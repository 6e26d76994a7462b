"""The user's own simulation as discovery's baseline: a column of predicted vibration in
every record (g, from whatever code produced it), with the channels that simulation took as
its inputs. Discovery then asks what explains the measured level beyond any function of
those inputs: what the simulation lacks, not what a net failed to learn."""

from __future__ import annotations

import jax
import numpy as np

from ..nets.networks import mlp_init
from ._model import _Ctx, _lag_windows, _replay, _Windows
from ._tested import linear_shift


def placeholder_params(ctx: _Ctx) -> dict:
    """Nets of the database's shape that were never trained, stacked (folds, seeds): the
    replay cuts the measured windows with them; their prediction is not used."""
    e = ctx.cfg.discovery.ensemble
    one = mlp_init(jax.random.key(0), ctx.x_db.shape[1], tuple(e.hidden))
    return jax.tree.map(lambda a: np.broadcast_to(np.asarray(a), (e.folds, e.seeds) + np.shape(a)).copy(), one)


def simulation_windows(ctx: _Ctx) -> tuple[_Windows, np.ndarray]:
    """The measured windows (at offset 0: the simulation predicts the vibration at the time
    of its inputs) and the simulation's prediction on each, (1, n): its window mean."""
    d = ctx.cfg.discovery
    win = _replay(ctx, 0.0)
    source = ctx.campaign.source or "<memory>"
    missing = [k for k in (d.simulation, *d.simulation_inputs) if f"x:{k}" not in win.cands]
    if missing:
        raise ValueError(f"discovery.simulation / simulation_inputs: {missing} are not numeric channels (or derived "
                         f"features) of campaign {source}")
    sim = win.cands[f"x:{d.simulation}"].to_numpy(np.float64)
    if not np.all(np.isfinite(sim)):
        bad = win.table.counter.to_numpy()[~np.isfinite(sim)][0]
        raise ValueError(f"discovery.simulation: column {d.simulation!r} of counter {bad} of campaign {source} is not "
                         "finite in every window")
    return win, sim[None]


def simulated_after(ctx: _Ctx, win: _Windows, sim, fitted) -> np.ndarray:
    """(1, n) the simulation with the named effects: its prediction lagged by a named lag,
    plus the other named candidates as a linear term fitted out of fold by condition (each
    fold's coefficients on the other folds' fully weighted windows)."""
    y = np.asarray(sim, float)[0]
    tau = next((f.candidate.parameters["tau_s"] for f in fitted if f.candidate.operator == "lag"), 0.0)
    y = _lag_windows(y[None], win, tau)[0] if tau > 0 else y
    return (y + linear_shift(ctx, win, y, [f.candidate for f in fitted if f.candidate.operator != "lag"]))[None]
