"""A discovery model's nets trained on the database's peaks, and where a change of its
prediction lies."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..analysis.databases import OUTPUT
from ._model import Model, _columns, _Ctx, _Windows, fit_ensemble
from .candidates import values


def _train_model(ctx: _Ctx, model: Model) -> dict:
    """Nets on the database inputs, the model's extra inputs and its gains' columns (each
    taken at the peak window of its condition), trained k-fold by condition over seeds on
    the peak PVV."""
    e = ctx.cfg.discovery.ensemble
    x = _columns(ctx.x_db, model, lambda c: values(c, ctx.train_table))
    return fit_ensemble(x, ctx.db[OUTPUT].to_numpy(np.float64), ctx.folds, k=e.folds, seeds=e.seeds, hidden=e.hidden,
                        train_cfg=ctx.cfg.train, seed=ctx.cfg.seed, n_gain=len(model.gains))


def _region(win: _Windows, full, before, after) -> dict:
    """The maneuver kinds that hold ≥ 80 % of the squared change between two predictions
    ((S, n) each), with the held-out RMS there before and after (medians over seeds)."""
    t = win.table[full]
    change = (np.median(after, axis=0) - np.median(before, axis=0))[full] ** 2
    share = pd.Series(change, index=t.maneuver.to_numpy()).groupby(level=0).sum().sort_values(ascending=False)
    share = share / max(share.sum(), 1e-30)
    kinds = list(share.index[: int(np.searchsorted(share.cumsum().to_numpy(), 0.8) + 1)])
    sel = t.maneuver.isin(kinds).to_numpy()
    meas = t.measured_g.to_numpy()[sel]
    rms = lambda p: float(np.median(np.sqrt(np.mean((p[:, full][:, sel] - meas) ** 2, axis=1))))  # noqa: E731
    return {"where": ", ".join(kinds), "before_rms_g": rms(before), "after_rms_g": rms(after)}
