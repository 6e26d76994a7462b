"""Quasi-static replay of a record through a trained network, and its cost.

The paper's replay: cut the record into windows of L rotor revolutions, average the flight
state over each window, feed the averages to the static network and compare the predicted
PVV with the measured PVV of the same windows. pvvjax adds an input-to-vibration offset τ
(seconds): the prediction for the window [a, b) uses the state averaged over the window
that starts and ends τ seconds earlier, and optionally a separate extra offset for the
three stick positions.

Everything is one pure function of (model, record, τ, L), differentiable in τ and L:
windows integrate the linear interpolant of the samples (the "linear" edge of
`harmonics`), so a window average is continuously differentiable in its edge positions,
at whole-sample offsets too (a rectangular, sample-and-hold window has a derivative that
jumps there, and an interpolated shift of the samples has one that jumps at every sample).
The record's window sums are computed once (`prepare`); a replay only weighs the samples
near the window edges, so it costs microseconds.

Windows near the record ends are weighted smoothly (`Replay.weight`): a window counts fully
when it and its input window lie inside the record for every offset within the settings'
bounds, and fades out over `fade_s` beyond that, so the cost is continuous in L too.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from .._arguments import instance, number
from .._lookup import Lookup, make_lookup, search
from ..analysis.databases import DB_INPUTS, STATE_CHANNELS
from ..analysis.harmonics import (
    N_HARMONIC_COLS,
    Columns,
    WindowPlan,
    harmonic_from_means,
    means_from_sums,
    plan_groups,
    plan_windows,
    record_bounds,
    record_columns,
    record_plans,
    stack_columns,
    window_sums,
    with_prefix,
)
from ..data.batch import RecordBatch, bucket_size, pad_rows, unpad_rows
from ..data.constants import UH60A, Aircraft
from ..data.features import derive_features
from ..nets.networks import apply_for

__all__ = [
    "FEATURES",
    "STICKS",
    "CostWeights",
    "Replay",
    "ReplayRecord",
    "Settings",
    "cost_terms",
    "input_index",
    "make_settings",
    "prepare",
    "replay",
    "replay_cost",
    "residuals",
    "soft_peak",
]

# Every network input of db1-db3, in one order (a database picks its inputs by index, so
# that models of all three databases stack and vmap).
FEATURES = ("advance_ratio", "gross_weight_lb", "rotor_rpm", "density_ratio", "mlf", "climb_rate_fpm",
            "collective_pct", "lateral_pct", "longitudinal_pct")
STICKS = ("collective_pct", "lateral_pct", "longitudinal_pct")
_STICK_COLS = tuple(N_HARMONIC_COLS + STATE_CHANNELS.index(s) for s in STICKS)
_STATE_COLS = tuple(range(N_HARMONIC_COLS, N_HARMONIC_COLS + len(STATE_CHANNELS)))


def input_index(database: str, n_inputs: int = 8) -> np.ndarray:
    """Indices into `FEATURES` of a database's inputs, padded with 0 to `n_inputs` (the
    padded inputs are masked out by the network's `in_mask`)."""
    idx = [FEATURES.index(f) for f in DB_INPUTS[database]]
    return np.array(idx + [0] * (n_inputs - len(idx)), np.int32)


class ReplayRecord(NamedTuple):
    """A record prepared for replay (`prepare`); leading batch axes allowed.

    Attributes:
        columns: window-sum columns of the acceleration and `STATE_CHANNELS`.
        time: (T,) s (padding continues it). time_lookup: its search table.
        rev_start, rev_end: revolutions covered by the samples.
        time_start, time_end: the same in seconds.
    """

    columns: Columns
    time: jax.Array
    time_lookup: Lookup
    rev_start: jax.Array
    rev_end: jax.Array
    time_start: jax.Array
    time_end: jax.Array


@struct.dataclass
class Settings:
    """Replay settings (`make_settings` fills in the plan). A PyTree: the plan (array
    sizes), the stick lag (whether the sticks get their own input windows) and the aircraft
    are static fields that key the compiled program; the offset bounds, hop, fade and the
    reference window length are data, so that replays with other values reuse the program
    instead of compiling the replay again.

    Attributes:
        plan: window plan covering the longest window and the shortest hop.
        hop_revs: window spacing, revolutions; 0 for consecutive windows (hop = L).
        offset_bounds: (lo, hi) s: input windows are kept inside the record for every
            offset in this range (windows that would leave it are weighted out).
        fade_s: width of the smooth weight fade at the record ends, s.
        stick_lag: replay the sticks with their own extra offset.
        reference_revs: length of the measured (reference) windows, revolutions; 0: the
            window length L of the replay, so that inputs and vibration share windows (the
            paper). > 0 decouples them: L is then the length of the input averaging only,
            centred on each reference window.
        aircraft: rotor constants for the derived features.
        groups: where the records need plans of other sizes, ((plan, rows), ...): each
            record's own plan (`analysis.record_plans`), the records that share one grouped.
            `replay_all` replays each group with its plan, so that no record's sampling (a
            logger glitch in one) changes another record's numbers; empty when one plan
            serves every record. Never part of a compiled program's key.
    """

    plan: WindowPlan = struct.field(pytree_node=False)
    hop_revs: float = 0.0
    offset_bounds: tuple[float, float] = (-1.0, 3.0)
    fade_s: float = 0.25
    stick_lag: bool = struct.field(pytree_node=False, default=False)
    reference_revs: float = 0.0
    aircraft: Aircraft = struct.field(pytree_node=False, default=UH60A)
    groups: tuple = struct.field(pytree_node=False, default=())


def make_settings(batch: RecordBatch, *, max_window_revs: float = 12.0, min_window_revs: float = 4.0,
                  hop_revs: float = 0.0, reference_revs: float = 0.0, **kw) -> Settings:
    """Settings whose plan covers windows of `min_window_revs`..`max_window_revs` on `batch`
    (and the reference windows, if any), with the records grouped by the plans their own
    samples need (`Settings.groups`) where those differ."""
    instance("make_settings", "batch", batch, RecordBatch, "a RecordBatch (to_batch)")
    number("make_settings", "max_window_revs", max_window_revs, above=0)
    number("make_settings", "min_window_revs", min_window_revs, above=0, at_most=max_window_revs)
    number("make_settings", "hop_revs", hop_revs, at_least=0)
    number("make_settings", "reference_revs", reference_revs, at_least=0)
    hop = hop_revs if hop_revs > 0 else (reference_revs if reference_revs > 0 else min_window_revs)
    longest = max(max_window_revs, reference_revs)
    plans = plan_groups(record_plans(batch, longest, hop, edge="linear"))
    plan = next(iter(plans)) if len(plans) == 1 else plan_windows(batch, longest, hop, edge="linear")
    groups = tuple((p, tuple(int(i) for i in rows)) for p, rows in plans.items()) if len(plans) > 1 else ()
    return Settings(plan=plan, hop_revs=float(hop_revs), reference_revs=float(reference_revs), groups=groups, **kw)


def _prepare_one(az, cos_psi, sin_psi, rev, width, time, x, mask, harmonic, block):
    cols = stack_columns(record_columns(az, cos_psi, sin_psi, rev, width, time, x, harmonic=harmonic, block=block))
    r0, r1 = record_bounds(rev, width, mask)
    last = jnp.maximum(jnp.sum(mask) - 1, 0)
    dt0, dt1 = time[1] - time[0], time[last] - time[jnp.maximum(last - 1, 0)]
    return ReplayRecord(cols, time, None, r0, r1, time[0] - 0.5 * dt0, time[last] + 0.5 * dt1)


@partial(jax.jit, static_argnames=("harmonic", "block"))
def _prepare(arrays, harmonic, block):
    return jax.vmap(partial(_prepare_one, harmonic=harmonic, block=block))(*arrays)


def prepare(batch: RecordBatch, *, harmonic: int = 4, block: int = 16) -> ReplayRecord:
    """Window-sum columns of every record of a batch (channels must be `STATE_CHANNELS`).

    Returns:
        `ReplayRecord` with a leading counter axis (index it, or vmap over it).

    The arrays alone enter the compiled program (not the counter names), padded to a
    `bucket_size` count of records, so that batches of similar size share it.
    """
    if tuple(batch.channels) != STATE_CHANNELS:
        raise ValueError(f"replay needs a batch of the channels {STATE_CHANNELS}, got {batch.channels}")
    arrays = (batch.accel, batch.cos_psi, batch.sin_psi, batch.rev, batch.width, batch.time, batch.x, batch.mask)
    n = arrays[0].shape[0]
    recs = unpad_rows(_prepare(pad_rows(arrays, bucket_size(n)), harmonic, block), n)
    return recs._replace(columns=with_prefix(recs.columns),
                         time_lookup=jax.tree.map(jax.device_put, make_lookup(recs.time)))


class Replay(NamedTuple):
    """One replayed record, per window (shape (W,), features (W, len(FEATURES))).

    Attributes:
        time: window-centre time, s.
        measured: measured PVV (4/rev amplitude of the window), g.
        predicted: network prediction from the offset input window, g.
        weight: 0..1 weight of the window in costs (see module docstring).
        features: the network inputs of each window, in `FEATURES` order.
    """

    time: jax.Array
    measured: jax.Array
    predicted: jax.Array
    weight: jax.Array
    features: jax.Array


def _smoothstep(u):
    u = jnp.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def _ensemble(params, x, apply):
    """Median over the leading (seed) axis of stacked nets, or the single net."""
    apply = apply or apply_for(params)
    if jnp.ndim(params["y_shift"]) == 0:
        return apply(params, x)
    pred = jnp.sort(jax.vmap(apply, in_axes=(0, None))(params, x), axis=0)  # jnp.median is far slower
    n = pred.shape[0]
    return 0.5 * (pred[(n - 1) // 2] + pred[n // 2])


def replay(model: dict, rec: ReplayRecord, offset_s, window_revs, stick_offset_s=0.0, *, settings: Settings,
           apply=None) -> Replay:
    """Quasi-static replay of one record.

    Args:
        model: dict with `params` (one net, or nets stacked on a leading seed axis: the
            prediction is their median) and `idx` (`input_index` of its database).
        rec: one `ReplayRecord` (no batch axis; vmap for many).
        offset_s: input-to-vibration offset τ, s (> 0: inputs precede the vibration).
        window_revs: window length L, revolutions (within the settings' plan).
        stick_offset_s: extra offset of the stick inputs, s (used if `settings.stick_lag`).
        settings: `Settings`.
        apply: network function (params, x (..., n_in)) -> (...,); default: the MLP or RBF
            evaluator that matches the parameters (`networks.apply_for`).

    Returns:
        `Replay`, windows aligned with the measured PVV windows.
    """
    c = rec.columns
    dt = c.blocks.dtype
    W = settings.plan.n_windows
    L = jnp.asarray(window_revs, dt)
    ref = settings.reference_revs
    if isinstance(ref, (int, float)):
        L_ref = L if ref <= 0 else jnp.asarray(ref, dt)
    else:  # data (traced): one compiled program for every reference length
        L_ref = jnp.where(ref > 0, jnp.asarray(ref, dt), L)
    hop_revs = jnp.asarray(settings.hop_revs, dt)
    hop = jnp.where(hop_revs > 0, hop_revs, L_ref)
    a = rec.rev_start + hop * jnp.arange(W, dtype=dt)
    b = a + L_ref
    # Input windows: length L, centred on the measured window, then τ seconds earlier
    # (edge revolution -> time -> shifted time -> revolution).
    mid = a + 0.5 * L_ref
    t_edges = _interp(jnp.concatenate([a, b, mid - 0.5 * L, mid + 0.5 * L]), c.rev, rec.time, c.lookup)
    t_a, t_b, t_in = t_edges[:W], t_edges[W:2 * W], t_edges[2 * W:]
    taus = [offset_s] + ([offset_s + stick_offset_s] if settings.stick_lag else [])
    r_in = _interp(jnp.concatenate([t_in - tau for tau in taus]), rec.time, c.rev, rec.time_lookup)
    # One window sum for the measured windows and the input windows together.
    n_sets = 1 + len(taus)
    starts = jnp.concatenate([a] + [r_in[2 * W * k: 2 * W * k + W] for k in range(len(taus))])
    ends = jnp.concatenate([b] + [r_in[2 * W * k + W: 2 * W * (k + 1)] for k in range(len(taus))])
    mean, _ = means_from_sums(window_sums(c, starts, ends, kind="linear", taper_revs=0.0, plan=settings.plan))
    mean = mean.reshape(n_sets, W, -1)
    measured, _, t_mid = harmonic_from_means(mean[0])
    x = mean[1, :, N_HARMONIC_COLS:] + c.x_ref
    if settings.stick_lag:
        sticks = jnp.array(_STICK_COLS)
        x = x.at[:, sticks - N_HARMONIC_COLS].set(mean[2][:, sticks] + c.x_ref[sticks - N_HARMONIC_COLS])
    ch = {name: x[:, i] for i, name in enumerate(STATE_CHANNELS)}
    ch.update(derive_features(ch, settings.aircraft))
    feats = jnp.stack([ch[f] for f in FEATURES], axis=-1)
    predicted = _ensemble(model["params"], feats[:, model["idx"]], apply)

    lo, hi = settings.offset_bounds
    f = settings.fade_s
    ti_a, ti_b = t_in[:W], t_in[W:]
    weight = (_smoothstep((t_a - rec.time_start) / f + 1.0) * _smoothstep((rec.time_end - t_b) / f + 1.0)
              * _smoothstep((ti_a - hi - rec.time_start) / f + 1.0) * _smoothstep((rec.time_end - ti_b + lo) / f + 1.0))
    return Replay(t_mid, measured, predicted, weight, feats)


def _interp(x, xp, fp, lookup=None):
    """Linear interpolation on increasing xp (extrapolates with the end segments)."""
    i = jnp.searchsorted(xp, x) if lookup is None else search(lookup, xp, x)
    i = jnp.clip(i, 1, xp.shape[0] - 1)
    x0, x1 = xp[i - 1], xp[i]
    f0, f1 = fp[i - 1], fp[i]
    return f0 + (x - x0) * ((f1 - f0) / (x1 - x0))


class CostWeights(NamedTuple):
    """Weights and scales of the replay cost (a NamedTuple of floats, traced under jit:
    other weights reuse the compiled cost).

    cost = peak·(Δpeak / peak_scale_g)² + phase·(c·tanh(Δt / c) / phase_scale_s)² + rms·(RMS / peak_scale_g)²

    with c = `phase_cap_s`: a peak-time error well below c counts in full; one far beyond it
    (the prediction peaks at another bump of the record, which no offset mends) counts as c,
    so that such counters do not steer the fit.

    Attributes:
        peak, phase, rms: weights of the three terms.
        peak_scale_g: error in g that costs 1 (the paper's 0.02 g replay tolerance).
        phase_scale_s: peak-time error in s that costs 1.
        temperature_g: soft-max temperature of the peak (smaller: closer to the hard max).
        phase_cap_s: soft cap of the peak-time error, s (0: none).
    """

    peak: float = 1.0
    phase: float = 1.0
    rms: float = 1.0
    peak_scale_g: float = 0.02
    phase_scale_s: float = 1.0
    temperature_g: float = 0.005
    phase_cap_s: float = 3.0


def soft_peak(values, time, weight, temperature):
    """Smooth peak value and peak time: averages under softmax(values / temperature) over
    the windows with weight > 0 (log-weights added, so fading windows fade out)."""
    on = weight > 0
    logits = jnp.where(on, values / temperature + jnp.log(jnp.where(on, weight, 1.0)), -jnp.inf)
    # Stable softmax by hand: jax.nn.softmax(where=...) has NaN gradients at masked entries.
    e = jnp.where(on, jnp.exp(logits - jax.lax.stop_gradient(jnp.max(logits))), 0.0)
    p = e / jnp.sum(e)
    return jnp.sum(p * values), jnp.sum(p * time)


def cost_terms(rep: Replay, weights: CostWeights = CostWeights()) -> dict:
    """Peak error (g), phase error (s; time of peak, predicted − measured) and RMS (g) of
    one replay, from soft peaks (differentiable)."""
    pk_m, t_m = soft_peak(rep.measured, rep.time, rep.weight, weights.temperature_g)
    pk_p, t_p = soft_peak(rep.predicted, rep.time, rep.weight, weights.temperature_g)
    wsum = jnp.maximum(jnp.sum(rep.weight), 1e-9)
    rms = jnp.sqrt(jnp.sum(rep.weight * (rep.predicted - rep.measured) ** 2) / wsum)
    return dict(peak_error_g=pk_p - pk_m, phase_error_s=t_p - t_m, rms_g=rms)


def residuals(rep: Replay, weights: CostWeights = CostWeights()):
    """The cost as a sum of squares: (2 + W,) residuals whose squares add up to `replay_cost`."""
    t = cost_terms(rep, weights)
    wsum = jnp.maximum(jnp.sum(rep.weight), 1e-9)
    on = rep.weight > 0
    sqrt_w = jnp.where(on, jnp.sqrt(jnp.where(on, rep.weight, 1.0)), 0.0)  # d√w/dw is infinite at 0
    per_window = jnp.sqrt(weights.rms / wsum) * sqrt_w * (rep.predicted - rep.measured) / weights.peak_scale_g
    dt, cap = t["phase_error_s"], jnp.asarray(weights.phase_cap_s, per_window.dtype)
    dt = jnp.where(cap > 0, cap * jnp.tanh(dt / jnp.where(cap > 0, cap, 1.0)), dt)
    head = jnp.stack([jnp.sqrt(weights.peak) * t["peak_error_g"] / weights.peak_scale_g,
                      jnp.sqrt(weights.phase) * dt / weights.phase_scale_s])
    return jnp.concatenate([head, per_window])


def replay_cost(rep: Replay, weights: CostWeights = CostWeights()):
    """The cost of one replay (scalar, see `CostWeights`)."""
    return jnp.sum(residuals(rep, weights) ** 2)
