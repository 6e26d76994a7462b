"""Peak PVV per flight condition and the paper's training databases 1-3 (data-contract §2).

The paper's "physically consistent" extraction: each flight condition is characterised by
its peak PVV over all windows of all its counters (a condition may span several counters,
like the two-segment autorotation), and every input is taken at that same peak window.
By default an input is its average over the peak window (`inputs = "mean"`), the same
averaging the quasi-static replay applies, so a database row is exactly what the replayed
network sees at that window; `inputs = "center"` takes instantaneous values at the
window's centre instead. Derived features (advance ratio, MLF) are computed from those
window values.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

from .._arguments import instance
from ..config import AnalysisConfig
from ..data.batch import RecordBatch, bucket_size, in_batch_order, to_batch
from ..data.campaign import Campaign
from ..data.features import derive_features
from ..io import listed
from .axes import AXES, AxisWindows, analyze_axes, resolved_harmonics
from .harmonics import Windows, analyze

__all__ = [
    "DATABASES",
    "DB_INPUTS",
    "META_COLUMNS",
    "OUTPUT",
    "PADDING_LIMIT",
    "STATE_CHANNELS",
    "Peaks",
    "analyze_by_length",
    "axes_database",
    "axis_peak_tables",
    "build_databases",
    "campaign_axes",
    "condition_peaks",
    "length_groups",
    "peak_table",
    "peaks_from_windows",
    "require_axis",
    "window_table",
]

DB_INPUTS: dict[str, tuple[str, ...]] = {
    "db1": ("advance_ratio", "gross_weight_lb", "rotor_rpm", "density_ratio", "mlf", "climb_rate_fpm"),
    "db2": ("advance_ratio", "gross_weight_lb", "rotor_rpm", "density_ratio",
            "collective_pct", "lateral_pct", "longitudinal_pct", "climb_rate_fpm"),
    "db3": ("advance_ratio", "rotor_rpm", "density_ratio",
            "collective_pct", "lateral_pct", "longitudinal_pct", "climb_rate_fpm"),
}
DATABASES = tuple(DB_INPUTS)
OUTPUT = "peak_pvv_g"
META_COLUMNS = ("condition", "counter", "maneuver", "peak_time_s", "window_revs")
# The measured channels the databases and their derived features are computed from.
STATE_CHANNELS = (
    "airspeed_kt", "gross_weight_lb", "rotor_rpm", "density_ratio", "pitch_rate_dps", "roll_angle_deg",
    "climb_rate_fpm", "collective_pct", "lateral_pct", "longitudinal_pct",
)


class Peaks(NamedTuple):
    """Peak window of each condition: value (g), batch row and window index."""

    value: jax.Array
    counter: jax.Array
    window: jax.Array


def condition_peaks(amplitude, valid, condition_ids, num_conditions: int) -> Peaks:
    """Peak amplitude of each condition over all valid windows of all its counters.

    Args:
        amplitude: (B, W) window amplitudes. valid: (B, W) window mask.
        condition_ids: (B,) int condition index of each batch row, in [0, num_conditions).
        num_conditions: K (static).

    Returns:
        `Peaks` of shape (K,). Ties go to the earliest batch row, then earliest window.
    """
    masked = jnp.where(valid, amplitude, -jnp.inf)
    row_max = masked.max(axis=1)
    row_arg = masked.argmax(axis=1)
    peak = jax.ops.segment_max(row_max, condition_ids, num_segments=num_conditions)
    rows = jnp.arange(amplitude.shape[0])
    is_peak = row_max == peak[condition_ids]
    counter = jax.ops.segment_min(jnp.where(is_peak, rows, amplitude.shape[0]), condition_ids,
                                  num_segments=num_conditions)
    return Peaks(peak, counter, row_arg[counter])


condition_peaks = jax.jit(condition_peaks, static_argnames="num_conditions")


def window_table(campaign: Campaign, windows: Windows, counters) -> pd.DataFrame:
    """All valid windows as a long table: counter, condition, maneuver, window, time_s, pvv_g, phase_rad."""
    amp, valid = np.asarray(windows.amplitude), np.asarray(windows.valid)
    time, phase = np.asarray(windows.time), np.asarray(windows.phase)
    b, w = np.nonzero(valid)
    names = np.asarray(counters, dtype=object)[b]
    info = campaign.counters.loc[names]
    return pd.DataFrame({
        "counter": names, "condition": info["condition"].to_numpy(), "maneuver": info["maneuver"].to_numpy(),
        "window": w, "time_s": time[b, w], "pvv_g": amp[b, w], "phase_rad": phase[b, w],
    })


def _counters(campaign: Campaign):
    conds = campaign.conditions()
    return list(conds), [c for cs in conds.values() for c in cs]


def campaign_axes(campaign: Campaign) -> tuple[str, ...]:
    """The pilot-floor axes every record of a campaign carries (`az_g` always; `ax_g`,
    `ay_g` where given). An axis that some records carry and others lack is left out of
    every per-axis table and study, said once as a `CampaignWarning` naming it and the
    records that lack it."""
    import warnings

    from ..data.campaign import CampaignWarning

    out = []
    for axis in AXES:
        lacking = _lacking(campaign, axis)
        if not lacking:
            out.append(axis)
        elif len(lacking) < len(campaign.records):
            warnings.warn(f"campaign {campaign.source}: {axis} is in {len(campaign.records) - len(lacking)} of "
                          f"{len(campaign.records)} records and missing from {listed(lacking)}: left out of the "
                          "per-axis tables and the three-axis study (give it in every record, or in none)",
                          CampaignWarning, stacklevel=2)
    return tuple(out)


def _lacking(campaign: Campaign, axis: str) -> list[str]:
    """The records of `campaign` without an `axis` column."""
    return [c for c, r in campaign.records.items() if axis not in r.columns]


def require_axis(campaign: Campaign, axis: str, key: str = "analysis.axis") -> None:
    """Refuse, naming `key` and the records, an analysis of an axis some record lacks."""
    lacking = _lacking(campaign, axis)
    if lacking:
        raise ValueError(f"{key} = {axis!r}: campaign {campaign.source} has no {axis} channel in "
                         f"{len(lacking)} of {len(campaign.records)} records ({listed(lacking)}); its axes in every "
                         f"record: {', '.join(campaign_axes(campaign))}")


def _check_inputs(caller: str, campaign, analysis) -> None:
    instance(caller, "campaign", campaign, Campaign, "a Campaign (load_campaign or campaign_from_frames)")
    instance(caller, "analysis", analysis, AnalysisConfig, "an AnalysisConfig")


def peak_table(campaign: Campaign, analysis: AnalysisConfig = AnalysisConfig()) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Analyse every counter's `analysis.axis` and take each condition's peak window.

    Returns:
        (peaks, windows): one row per condition with every state channel and derived
        feature at the peak window; and the long table of all valid windows.
    """
    _check_inputs("peak_table", campaign, analysis)
    require_axis(campaign, analysis.axis)
    _, counters = _counters(campaign)
    win = analyze_by_length(campaign, counters, analysis.window_revs, analysis.hop,
                            harmonic=analysis.harmonic or campaign.aircraft.blades, taper_revs=analysis.taper_revs,
                            axis=analysis.axis)
    return peaks_from_windows(campaign, win, counters, analysis), window_table(campaign, win, counters)


# Records are batched together while padding them to the longest at most multiplies their
# memory by this; beyond, they are batched by length.
PADDING_LIMIT = 4.0


def length_groups(lengths) -> np.ndarray:
    """(n,) a batch key per record of these sample counts: all one batch while padding them
    to the longest at most multiplies their memory by `PADDING_LIMIT`, else groups whose
    lengths lie within a factor 2 (padded, each costs at most twice its records' samples)."""
    lengths = np.asarray(lengths)
    if lengths.max() * len(lengths) <= PADDING_LIMIT * lengths.sum():  # alike: one batch, one program
        return np.zeros(len(lengths), int)
    return np.ceil(np.log2(np.maximum(lengths, 1))).astype(int)


def _length_batches(campaign: Campaign, counters, axis="az_g") -> list[tuple[np.ndarray, RecordBatch]]:
    """The counters' records (their `STATE_CHANNELS` and acceleration `axis`, one name or a
    tuple) as batches by length (`length_groups`): one batch where their lengths are alike,
    else one per group, so one long record among short ones costs its own memory.

    Returns:
        (rows, batch) per group: the positions in `counters` of its records, and their batch.
    """
    buckets = length_groups([len(campaign.records[c]) for c in counters])
    return [(rows, to_batch(campaign, STATE_CHANNELS, [counters[i] for i in rows], axis=axis))
            for rows in (np.flatnonzero(buckets == b) for b in np.unique(buckets))]


def _in_counter_order(parts):
    """Windows (`Windows` or `AxisWindows`) of batches by length, `[(rows, windows), ...]` from
    `_length_batches`, as one in the order of the counters: each part widened to the most
    windows of any (the windows past a record's end invalid)."""
    if len(parts) == 1:
        return parts[0][1]
    n_windows = max(int(w.valid.shape[1]) for _, w in parts)

    def widen(w):
        out = {}
        for name, a in zip(w._fields, w):
            a = np.asarray(a)
            ax = a.ndim - 1 if isinstance(w, AxisWindows) and name in ("amplitude", "phase") else 1
            pad = [(0, 0)] * a.ndim
            pad[ax] = (0, n_windows - a.shape[ax])
            out[name] = np.pad(a, pad)
        return type(w)(**out)

    return in_batch_order([widen(w) for _, w in parts], {i: rows for i, (rows, _) in enumerate(parts)})


def analyze_by_length(campaign: Campaign, counters, window_revs: float, hop_revs: float | None = None, *,
                      harmonic: int, taper_revs: float = 0.0, axis: str = "az_g") -> Windows:
    """`analyze` of the counters' records (their `STATE_CHANNELS`), batched by length where
    their lengths differ widely (`_length_batches`). Windows come back in the order of
    `counters`, the short records' past their last as invalid.

    Args: as `analyze`; `counters` the records, `axis` the acceleration analysed.

    Returns:
        `Windows` with shapes (B, W) and (B, W, C), W the most windows of any record.
    """
    return _in_counter_order([(rows, analyze(batch, window_revs, hop_revs, harmonic=harmonic, taper_revs=taper_revs))
                             for rows, batch in _length_batches(campaign, counters, axis)])


def peaks_from_windows(campaign: Campaign, win: Windows, counters, analysis: AnalysisConfig) -> pd.DataFrame:
    """Each condition's peak window of an analysis of `counters` (every counter of the
    campaign, condition by condition), with every state channel and derived feature there."""
    row, col, value = _peak_windows(campaign, win.amplitude, win.valid, counters)
    return _state_table(campaign, win, counters, analysis, row, col).assign(**{OUTPUT: value})


def _peak_windows(campaign: Campaign, amplitude, valid, counters):
    """(batch row, window, value) of each condition's peak."""
    if not bool(np.asarray(valid).any(axis=1).all()):
        short = [c for c, ok in zip(counters, np.asarray(valid).any(axis=1)) if not ok]
        raise ValueError(f"counters with no complete analysis window: {short}")
    cond_names, _ = _counters(campaign)
    cond_ids = np.array([cond_names.index(campaign.counters.loc[c, "condition"]) for c in counters])
    # Conditions counted in buckets (an empty condition's peak is -inf, and it is sliced off).
    pk = condition_peaks(amplitude, valid, np.asarray(cond_ids), num_conditions=bucket_size(len(cond_names)))
    pk = jax.tree.map(lambda a: np.asarray(a)[: len(cond_names)], pk)
    return pk.counter, pk.window, pk.value


def _state_table(campaign: Campaign, win, counters, analysis: AnalysisConfig, row, col) -> pd.DataFrame:
    """One row per condition: where its window (batch row, window) lies, and the state
    channels and derived features there."""
    cond_names, _ = _counters(campaign)
    source = win.means if analysis.inputs == "mean" else win.center
    vals = np.asarray(source)[row, col]  # (K, C)
    ch = {name: vals[:, i] for i, name in enumerate(STATE_CHANNELS)}
    feats = {k: np.asarray(v) for k, v in derive_features(ch, campaign.aircraft).items()}
    peak_counters = [counters[i] for i in row]
    return pd.DataFrame({
        "condition": cond_names,
        "counter": peak_counters,
        "maneuver": campaign.counters.loc[peak_counters, "maneuver"].to_numpy(),
        "peak_time_s": np.asarray(win.time)[row, col],
        "window_revs": float(analysis.window_revs),
        **feats,
        **ch,
    })


def axes_database(campaign: Campaign, analysis: AnalysisConfig = AnalysisConfig()) -> pd.DataFrame:
    """The rows a net of several outputs (one per pilot-floor axis) trains on: for each
    condition and each axis the campaign carries, the axis's peak window (of harmonic
    `analysis.harmonic`, default N/rev), with the flight state there and every axis's
    amplitude in that same window. So each axis's peak is a target (column of that axis in
    the rows whose `peak_axis` is it), and every row teaches all outputs what the state
    gives in one window, as the element predicts them.

    Returns:
        Rows ordered by axis (`AXES` order) then condition: META_COLUMNS, `peak_axis`, the
        state channels and features, and one amplitude column per axis (g).
    """
    axes = campaign_axes(campaign)
    _, counters = _counters(campaign)
    k = analysis.harmonic or campaign.aircraft.blades
    win = _in_counter_order([(rows, analyze_axes(batch, (k,), analysis.window_revs, analysis.hop,
                                                taper_revs=analysis.taper_revs))
                            for rows, batch in _length_batches(campaign, counters, axes)])
    amp = np.asarray(win.amplitude)[:, :, 0, :]  # (B, A, W)
    parts = []
    for a, axis in enumerate(axes):
        row, col, _ = _peak_windows(campaign, amp[:, a], win.valid, counters)
        part = _state_table(campaign, win, counters, analysis, row, col)
        part.insert(len(META_COLUMNS), "peak_axis", axis)
        parts.append(part.assign(**{name: amp[row, i, col] for i, name in enumerate(axes)}))
    return pd.concat(parts, ignore_index=True)


def axis_peak_tables(campaign: Campaign, analysis: AnalysisConfig = AnalysisConfig(),
                     harmonics=None) -> dict[tuple[str, int], pd.DataFrame]:
    """A peak table per pilot-floor axis and harmonic, from one windowed pass
    (`analyze_axes`): for every axis the campaign carries, the 1/rev, N/rev and 2N/rev
    (`harmonics`, default) that its sampling and windows resolve. Each table is what
    `peak_table` gives for that `analysis.axis` and `harmonic`: its own peak window per
    condition, the flight state there, and the peak in `OUTPUT` (g).

    Returns:
        (axis, harmonic) -> table, axes in `AXES` order, harmonics ascending.
    """
    n = campaign.aircraft.blades
    _, counters = _counters(campaign)
    axes = campaign_axes(campaign)
    batches = _length_batches(campaign, counters, axes)
    wanted = sorted(set(harmonics or (1, n, 2 * n)))
    every = set.intersection(*(set(resolved_harmonics(b, wanted, analysis.window_revs)) for _, b in batches))
    ks = [k for k in wanted if k in every]
    win = _in_counter_order([(rows, analyze_axes(batch, ks, analysis.window_revs, analysis.hop,
                                                taper_revs=analysis.taper_revs)) for rows, batch in batches])
    return {(axis, k): peaks_from_windows(campaign, win.select(a, h), counters, analysis)
            for a, axis in enumerate(axes) for h, k in enumerate(ks)}


def build_databases(campaign: Campaign, analysis: AnalysisConfig = AnalysisConfig()) -> dict[str, pd.DataFrame]:
    """db1, db2, db3 (data-contract §2) and the full peak table under key "peaks"."""
    _check_inputs("build_databases", campaign, analysis)
    peaks, _ = peak_table(campaign, analysis)
    out = {name: peaks[list(META_COLUMNS) + list(inputs) + [OUTPUT]].copy() for name, inputs in DB_INPUTS.items()}
    out["peaks"] = peaks
    return out
