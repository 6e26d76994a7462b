"""From a config, a campaign and a sweep to replay and calibration tables: the imperative
shell around `replay` and `calibration` (file reading, model loading, pandas).

Tables report hard peaks (the largest fully-weighted window) so that they read like the
paper's figures; the calibration itself minimises the smooth cost of `replay`.
"""

from __future__ import annotations

import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from ..analysis.databases import STATE_CHANNELS
from ..config import AnalysisConfig, CalibrationConfig, ReplayConfig
from ..data.batch import bucket_size, in_batch_order, pad_rows, take_rows, to_batch, unpad_rows
from ..data.campaign import Campaign
from ..nets.sweep import heldout_models
from .calibration import PARAMS, Bounds, calibrate, cost_grid, counter_costs, group_members
from .quasistatic import FEATURES, CostWeights, ReplayRecord, Settings, make_settings, prepare, replay

__all__ = [
    "at_bounds",
    "calibration_settings",
    "calibration_table",
    "cost_weights",
    "counter_cost_table",
    "grid_table",
    "load_replay_set",
    "peak_summary",
    "replay_windows",
    "select_counters",
    "settings_at",
    "take_counters",
]


def select_counters(campaign: Campaign, cfg: ReplayConfig, named=None, what: str = "replay.counters") -> list[str]:
    """The counters a replay config names (or every counter of its maneuver kinds).

    Args:
        named: counters given elsewhere (a command's `--counters`), in place of the config's.
        what: where they were given, for the error that names one not in the campaign.
    """
    known = campaign.counters
    counters = list(named or cfg.counters)
    if counters:
        missing = [c for c in counters if c not in known.index]
        if missing:
            names = list(known.index)
            raise ValueError(f"{what}: {', '.join(missing)} not in the campaign {campaign.source} (its {len(names)} "
                           f"counters: {', '.join(names[:8])}{', ...' if len(names) > 8 else ''})")
        return counters
    sel = known[known.maneuver.isin(cfg.maneuvers)]
    if sel.empty:
        raise ValueError(f"replay.maneuvers {list(cfg.maneuvers)}: no counters of these kinds in the campaign "
                         f"(it has {sorted(set(known.maneuver))})")
    return list(sel.index)


def load_replay_set(campaign: Campaign, counters, sweep_dir, databases, architecture: str = "",
                    analysis: AnalysisConfig = AnalysisConfig()) -> tuple:
    """Prepare `counters` and load, for each database, the nets that held each counter's
    condition out; the records' `analysis.axis` and harmonic are what the nets predict.

    Returns:
        (info DataFrame, batch, recs, models by database).
    """
    info = campaign.counters.loc[list(counters), ["maneuver", "condition"]]
    batch = to_batch(campaign, STATE_CHANNELS, list(counters), axis=analysis.axis)
    recs = prepare(batch, harmonic=analysis.harmonic or campaign.aircraft.blades)
    models = {db: heldout_models(Path(sweep_dir), db, list(info.condition), architecture or None) for db in databases}
    return info, batch, recs, models


def take_counters(tree, idx):
    """The counters `idx` of a replay set's arrays (records, models: any PyTree with the
    counter as leading axis)."""
    return take_rows(tree, np.asarray(idx))


def cost_weights(cfg: CalibrationConfig) -> CostWeights:
    """The replay-cost weights and scales of a calibration config."""
    return CostWeights(cfg.peak_weight, cfg.phase_weight, cfg.rms_weight, cfg.peak_scale_g, cfg.phase_scale_s,
                       cfg.temperature_g, cfg.phase_cap_s)


def _bounds(cfg: CalibrationConfig) -> Bounds:
    return Bounds(tuple(cfg.offset_bounds), tuple(cfg.window_bounds), tuple(cfg.stick_offset_bounds))


@jax.jit
def _replay_all(m, r, th, settings):
    return jax.vmap(lambda m, r, th: replay(m, r, th[0], th[1], th[2], settings=settings))(m, r, th)


def replay_all(m, r, th, *, settings):
    """Every counter's replay (leading axis N) at its θ (N, 3). The counters of each of the
    settings' `groups` are replayed with their group's plan (all at once where one plan
    serves every record), and padded to a `bucket_size` count for the computation, so that
    campaigns of similar size share the compiled replay."""
    n = r.time.shape[0]
    th = jnp.broadcast_to(jnp.asarray(th, r.time.dtype), (n, 3))
    one = settings.replace(groups=())
    if not settings.groups:
        return unpad_rows(_replay_all(*pad_rows((m, r, th), bucket_size(n)), one), n)
    groups = dict(settings.groups)
    total = sum(len(rows) for rows in groups.values())
    if total != n:
        raise ValueError(f"replay_all: the settings' plans were made for a batch of {total} records "
                         f"(`make_settings`), not these {n}: make them from the batch replayed")
    parts = [unpad_rows(_replay_all(*pad_rows(take_rows((m, r, th), np.asarray(rows)), bucket_size(len(rows))),
                                    one.replace(plan=plan)), len(rows)) for plan, rows in groups.items()]
    return in_batch_order(parts, groups)


def _bucketed(models, recs, members=None, mask=None):
    """Models and records padded to a `bucket_size` count of counters, and groups to a
    `bucket_size` count of groups and of members (padded groups have no members: their
    results are sliced off), so that a calibration's programs serve campaigns of similar size."""
    models, recs = pad_rows((models, recs), bucket_size(recs.time.shape[0]))
    if members is None:
        return models, recs
    (G, M), G2 = members.shape, bucket_size(members.shape[0])
    M2 = bucket_size(M)
    members = np.pad(members, ((0, G2 - G), (0, M2 - M)), mode="edge")
    mask = np.pad(mask, ((0, G2 - G), (0, M2 - M)), constant_values=False)
    return models, recs, members, mask


def replay_windows(info: pd.DataFrame, recs: ReplayRecord, models: dict, theta, settings: Settings) -> pd.DataFrame:
    """Window-level table of replays of every counter and database.

    Args:
        theta: (3,) θ for all, or a dict database -> (N, 3) per counter.

    Returns:
        database, counter, condition, maneuver, window, time_s, measured_g, predicted_g,
        weight, offset_s, window_revs, stick_offset_s, and the window's network features
        (`replay.FEATURES`: advance_ratio, mlf, ...) for locating residuals by regime.
    """
    parts = []
    n = len(info)
    for db, model in models.items():
        th = theta[db] if isinstance(theta, dict) else theta
        th = np.broadcast_to(np.asarray(th, np.float32), (n, 3))
        rep = replay_all(model, recs, jnp.asarray(th), settings=settings)
        W = rep.time.shape[1]
        parts.append(pd.DataFrame({
            "database": db,
            "counter": np.repeat(info.index.to_numpy(), W),
            "condition": np.repeat(info.condition.to_numpy(), W),
            "maneuver": np.repeat(info.maneuver.to_numpy(), W),
            "window": np.tile(np.arange(W), n),
            "time_s": np.asarray(rep.time).ravel(),
            "measured_g": np.asarray(rep.measured).ravel(),
            "predicted_g": np.asarray(rep.predicted).ravel(),
            "weight": np.asarray(rep.weight).ravel(),
            "offset_s": np.repeat(th[:, 0], W),
            "window_revs": np.repeat(th[:, 1], W),
            "stick_offset_s": np.repeat(th[:, 2], W),
            **{f: np.asarray(rep.features[..., k]).ravel() for k, f in enumerate(FEATURES)},
        }))
    out = pd.concat(parts, ignore_index=True)
    out = out[out.weight > 0].reset_index(drop=True)
    _say_windowless(info.index[~info.index.isin(out.counter)], "gets no replay window",
                    "shorter than the window plus the offset")
    return out


def _say_windowless(counters, what: str, why: str) -> None:
    """A warning naming the counters left out of a table, never a silent drop."""
    import warnings

    from ..io import listed

    counters = [str(c) for c in counters]
    if counters:
        warnings.warn(f"{len(counters)} counter(s) {what} ({why}), left out of the tables: {listed(counters)}",
                      stacklevel=3)


def peak_summary(windows: pd.DataFrame) -> pd.DataFrame:
    """Per database and counter: measured and predicted peak (largest fully weighted
    window), peak error (g), phase error (s, predicted − measured peak time) and RMS (g)."""
    full = windows[windows.weight >= 0.999]
    _say_windowless(sorted(set(windows.counter) - set(full.counter)), "get no whole window",
                    "their windows reach past the record's ends")
    rows = []
    for (db, counter), g in full.groupby(["database", "counter"], sort=False):
        im, ip = g.measured_g.idxmax(), g.predicted_g.idxmax()
        rows.append(dict(database=db, counter=counter, condition=g.condition.iloc[0], maneuver=g.maneuver.iloc[0],
                         offset_s=g.offset_s.iloc[0], window_revs=g.window_revs.iloc[0],
                         stick_offset_s=g.stick_offset_s.iloc[0],
                         measured_peak_g=g.measured_g[im], predicted_peak_g=g.predicted_g[ip],
                         peak_error_g=g.predicted_g[ip] - g.measured_g[im],
                         measured_peak_time_s=g.time_s[im], predicted_peak_time_s=g.time_s[ip],
                         phase_error_s=g.time_s[ip] - g.time_s[im],
                         rms_g=float(np.sqrt(np.mean((g.predicted_g - g.measured_g) ** 2)))))
    return pd.DataFrame(rows)


def _groups(info: pd.DataFrame, how: str) -> tuple[np.ndarray, list[str]]:
    if how == "all":
        return np.zeros(len(info), int), ["all"]
    keys = info.maneuver if how == "maneuver" else pd.Series(info.index, index=info.index)
    names = list(dict.fromkeys(keys))
    return np.array([names.index(k) for k in keys]), names


def _coarse(cfg: CalibrationConfig, free) -> np.ndarray:
    axes = {"offset_s": np.arange(cfg.offset_bounds[0], cfg.offset_bounds[1] + 1e-9, cfg.coarse_offset_step_s),
            "window_revs": np.arange(cfg.window_bounds[0], cfg.window_bounds[1] + 1e-9, cfg.coarse_window_step_revs),
            "stick_offset_s": np.arange(cfg.stick_offset_bounds[0], cfg.stick_offset_bounds[1] + 1e-9,
                                        cfg.coarse_stick_step_s)}
    mesh = np.meshgrid(*[axes[f] for f in free], indexing="ij")
    return np.stack([m.ravel() for m in mesh], -1)


def settings_at(batch, theta, hop_revs: float = 0.0) -> Settings:
    """Settings for replays at one θ = (offset_s, window_revs, stick_offset_s): the plan
    covers that window length, and a window counts when its input windows (the sticks'
    too) lie in the record at that offset."""
    tau, L, tau_stick = (float(v) for v in theta)
    total = tau + tau_stick
    return make_settings(batch, max_window_revs=L, min_window_revs=L, hop_revs=hop_revs,
                         offset_bounds=(min(0.0, tau, total), max(0.0, tau, total)), stick_lag=tau_stick != 0)


def calibration_settings(batch, cfg: CalibrationConfig, stick_lag: bool) -> Settings:
    """Replay settings that cover every θ inside the config's bounds (the window plan of the
    longest window, the largest offsets), so one compiled cost serves the whole search: one
    plan for every record (no `groups`), as the cost sums them all."""
    lo, hi = cfg.offset_bounds
    if stick_lag:  # the sticks' total offset must stay inside the record too
        lo, hi = lo + min(cfg.stick_offset_bounds[0], 0.0), hi + max(cfg.stick_offset_bounds[1], 0.0)
    return make_settings(batch, max_window_revs=float(cfg.window_bounds[1]),
                         min_window_revs=float(cfg.window_bounds[0]), hop_revs=cfg.hop_revs,
                         reference_revs=cfg.reference_revs, offset_bounds=(float(lo), float(hi)),
                         stick_lag=stick_lag).replace(groups=())


def calibration_table(info: pd.DataFrame, batch, recs: ReplayRecord, models: dict, cfg: CalibrationConfig,
                      init=(0.0, 8.0, 0.0), *, groups: str | None = None, free=None, log=print) -> pd.DataFrame:
    """Calibrate θ per database and group; one row each with θ, cost, the coarse start,
    solver steps, wall time, and (if the config asks) the brute-force grid optimum.

    The databases are solved together (vmapped) when they share one model shape.
    """
    free = tuple(free or cfg.free)
    how = groups or cfg.groups
    gid, names = _groups(info, how)
    settings = calibration_settings(batch, cfg, "stick_offset_s" in free)
    weights = cost_weights(cfg)
    coarse = _coarse(cfg, free)
    dbs = list(models)
    stacked = jax.tree.map(lambda *a: jnp.stack(a), *[_bucketed(models[d], recs)[0] for d in dbs])
    _, recs, members, mask = _bucketed(models[dbs[0]], recs, *group_members(gid, len(names)))
    run = lambda m: calibrate(m, recs, members, mask, jnp.asarray(init, jnp.float32), coarse, free=free,  # noqa: E731
                              bounds=_bounds(cfg), settings=settings, weights=weights, max_steps=cfg.max_steps)
    t0 = time.perf_counter()
    cal = jax.block_until_ready(jax.vmap(run)(stacked))
    seconds = time.perf_counter() - t0
    log(f"calibrated {', '.join(free)} for {len(dbs)} database(s) x {len(names)} group(s) of {len(info)} counters "
        f"in {seconds:.1f} s")
    rows = []
    for d, db in enumerate(dbs):
        for g, name in enumerate(names):
            row = dict(database=db, group=name, groups=how, free=",".join(free), n_counters=int(mask[g].sum()),
                       cost=float(cal.cost[d, g]), start_cost=float(cal.start_cost[d, g]),
                       steps=int(cal.steps[d, g]), converged=bool(cal.ok[d, g]), wall_s=seconds)
            for i, p in enumerate(PARAMS):
                row[p] = float(cal.theta[d, g, i])
                row[f"start_{p}"] = float(cal.start[d, g, i])
            row["at_bound"] = at_bounds(row, free, _bounds(cfg))
            if row["at_bound"]:
                log(f"warning: {db}, group {name}: {row['at_bound']} stopped at its search bound, so it is not a "
                    "fitted value (the optimum may lie beyond): widen calibration's bounds for it")
            rows.append(row)
    return pd.DataFrame(rows)


def at_bounds(theta: dict, free, bounds: Bounds, share: float = 1e-3) -> str:
    """The free parameters of a calibrated θ that lie on a bound of the search (within
    `share` of its span), as "name=value" joined by commas; "" for none."""
    out = []
    for p in free:
        lo, hi = getattr(bounds, p)
        tol = share * (hi - lo)
        if min(abs(theta[p] - lo), abs(theta[p] - hi)) <= tol:
            out.append(f"{p}={theta[p]:g}")
    return ", ".join(out)


def grid_table(info: pd.DataFrame, recs: ReplayRecord, models: dict, cfg: CalibrationConfig, batch,
               base=(0.0, 8.0, 0.0), *, groups: str | None = None) -> pd.DataFrame:
    """Brute-force cost over offset × window length (those of them the config fits) per
    database and group (long table: database, group, offset_s, window_revs, cost)."""
    how = groups or cfg.groups
    gid, names = _groups(info, how)
    members, mask = group_members(gid, len(names))
    settings = calibration_settings(batch, cfg, False)
    n_groups = len(names)
    # Only the fitted parameters span the grid; the others stay at `base`, as in the fit.
    offsets = (np.arange(cfg.offset_bounds[0], cfg.offset_bounds[1] + 1e-9, cfg.grid_offset_step_s)
               if "offset_s" in cfg.free else np.array([base[0]]))
    lengths = (np.arange(cfg.window_bounds[0], cfg.window_bounds[1] + 1e-9, cfg.grid_window_step_revs)
               if "window_revs" in cfg.free else np.array([base[1]]))
    parts = []
    for db, model in models.items():
        g = np.asarray(cost_grid(*_bucketed(model, recs, members, mask), offsets, lengths,
                                 jnp.asarray(base, jnp.float32), settings=settings, weights=cost_weights(cfg)))
        g = g[:n_groups]
        G, J, K = g.shape
        parts.append(pd.DataFrame({
            "database": db, "group": np.repeat(names, J * K),
            "window_revs": np.tile(np.repeat(lengths, K), G), "offset_s": np.tile(offsets, G * J),
            "cost": g.ravel()}))
    return pd.concat(parts, ignore_index=True)


def counter_cost_table(info, recs, models, theta, settings, weights) -> pd.DataFrame:
    """Smooth cost terms per database and counter at θ (dict database -> (N, 3) or (3,))."""
    parts = []
    for db, model in models.items():
        th = theta[db] if isinstance(theta, dict) else theta
        n = len(info)
        th = pad_rows(np.broadcast_to(np.asarray(th, np.float32), (n, 3)), bucket_size(n))
        out = counter_costs(*_bucketed(model, recs), jnp.asarray(th), settings=settings, weights=weights)
        out = {k: np.asarray(v)[:n] for k, v in out.items()}
        parts.append(pd.DataFrame({"database": db, "counter": info.index, "maneuver": info.maneuver.to_numpy(),
                                   **{k: np.asarray(v) for k, v in out.items()}}))
    return pd.concat(parts, ignore_index=True)
