"""The candidate library of the discovery workflow: every numeric channel and derived
feature of a campaign, through the operators of data-contract §3, averaged over the same
windows as the replay.

Two stages keep it cheap and exact:

1. `window_table`: per window, the window means of the sample-level series that need the
   samples: each channel and derived feature (`x:`), its magnitude (`abs:`), its time
   derivative over one rotor revolution (`rate:`; `_rate`), the derivative's magnitude
   (`abs_rate:`) and its spread inside
   the window (`spread:`, the `window` operator). Means integrate the linear interpolant of
   the samples between the window's edges (`interval_means`), as the replay does.
2. `values`: a `Candidate` (operator, channels, parameters) evaluated from those columns.
   Operators with a parameter act on window means, where the parameter is cheap to fit:
   `threshold` (knee), `product`, `resonance` (centre, width). The `lag` operator needs the
   model's own predictions and lives in `discovery`.

`library` lays the parametric operators on grids (knees at quantiles, resonance centres
across the rotor-speed range), so that the permutation test of `selection` sees every
parameter value a fit could have picked; `discovery` refines the chosen one by least squares.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..data.campaign import Campaign
from ..data.features import derive_features
from .effects import band

__all__ = [
    "Candidate",
    "EXCLUDED_CHANNELS",
    "channels_lacking",
    "columns_of",
    "describe",
    "from_key",
    "interval_means",
    "library",
    "sample_series",
    "values",
    "window_table",
    "window_tables",
]

# Not flight state: the clock, the vibration itself (every pilot-floor axis) and the blade azimuth.
EXCLUDED_CHANNELS = ("time_s", "az_g", "ax_g", "ay_g", "azimuth_deg")

_WORDS = {
    "airspeed_kt": "airspeed", "rotor_rpm": "rotor speed", "pitch_rate_dps": "pitch rate", "roll_rate_dps": "roll rate",
    "yaw_rate_dps": "yaw rate", "roll_angle_deg": "roll angle", "pitch_angle_deg": "pitch attitude",
    "climb_rate_fpm": "climb rate", "collective_pct": "collective", "lateral_pct": "lateral stick",
    "longitudinal_pct": "longitudinal stick", "pedal_pct": "pedal", "sideslip_deg": "sideslip",
    "nz_g": "load factor", "altitude_ft": "altitude", "shaft_power_hp": "shaft power",
    "gross_weight_lb": "gross weight", "density_ratio": "air density", "advance_ratio": "advance ratio",
    "mlf": "maneuver load factor", "thrust_coefficient": "thrust coefficient", "blade_loading": "blade loading",
}
# The rates of the attitude angles and of the altitude are named apart from the roll-rate,
# pitch-rate and climb-rate channels: they are other candidates (Euler rates, a differentiated
# altimeter), and a report that lists both under one name cannot be read.
_RATE_WORDS = {"pitch_rate_dps": "pitch acceleration", "roll_rate_dps": "roll acceleration",
               "yaw_rate_dps": "yaw acceleration", "roll_angle_deg": "roll angle rate",
               "pitch_angle_deg": "pitch attitude rate", "airspeed_kt": "airspeed rate", "altitude_ft": "altitude rate"}


@dataclass(frozen=True)
class Candidate:
    """One candidate effect.

    Attributes:
        operator: one of `effects.OPERATORS`.
        channels: canonical channels or derived features it is built from.
        parameters: its parameters (knee, centre, width, time constant, transform).
    """

    operator: str
    channels: tuple[str, ...]
    parameters: dict = field(default_factory=dict, hash=False, compare=False)

    @property
    def key(self) -> str:
        """A unique, readable key (operator:channels:parameters)."""
        par = ",".join(f"{k}={_fmt(v)}" for k, v in sorted(self.parameters.items()))
        return f"{self.operator}:{'*'.join(self.channels)}" + (f":{par}" if par else "")

    @property
    def name(self) -> str:
        return describe(self)

    @property
    def parameters_json(self) -> str:
        """Its parameters at full precision, as a JSON object (the key keeps four digits)."""
        def plain(v):
            return float(v) if isinstance(v, (float, np.floating)) else int(v) if isinstance(v, np.integer) else v
        return json.dumps({k: plain(v) for k, v in sorted(self.parameters.items())})

    @property
    def complexity(self) -> int:
        """1 for a channel (or its magnitude), 2 for a derivative or a spread inside the window,
        3 for an operator with a fitted parameter or two channels (knee, resonance, lag,
        product): the order in which a simpler explanation is preferred."""
        return {"input": 1, "rate": 2, "abs_rate": 2, "window": 2}.get(self.operator, 3)


def _fmt(v):
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def from_key(key: str, parameters: str | None = None) -> Candidate:
    """The candidate of a `Candidate.key` (as the rounds table and discovery.json keep it):
    operator:channel[*channel]:name=value,... Values are read back as written, floats to
    four significant digits, unless `parameters` (`Candidate.parameters_json`, as the rounds
    table also keeps them) gives them at full precision.

    Raises:
        ValueError: naming the key, if it is not operator:channels[:parameters].
    """
    parts = key.split(":")
    if len(parts) not in (2, 3) or not parts[0]:
        raise ValueError(f"candidate key {key!r}: expected operator:channels[:name=value,...]")
    channels = tuple(ch for ch in parts[1].split("*") if ch)
    if parameters:
        return Candidate(parts[0], channels, json.loads(parameters))
    pars = {}
    for item in parts[2].split(",") if len(parts) == 3 and parts[2] else ():
        name, eq, text = item.partition("=")
        if not eq or not name:
            raise ValueError(f"candidate key {key!r}: parameter {item!r} is not name=value")
        pars[name] = _read(text)
    return Candidate(parts[0], channels, pars)


def _read(text: str):
    if text in ("True", "False"):
        return text == "True"
    try:
        return float(text)
    except ValueError:
        return text


def describe(c: Candidate) -> str:
    """A plain-words name of a candidate."""
    w = [_WORDS.get(ch, ch.replace("_", " ")) for ch in c.channels]
    p = c.parameters
    if c.operator == "input":
        return f"{w[0]} magnitude" if p.get("transform") == "abs" else w[0]
    if c.operator in ("rate", "abs_rate"):
        words = _RATE_WORDS.get(c.channels[0], f"rate of {w[0]}")
        return f"{words} magnitude" if c.operator == "abs_rate" else words
    if c.operator == "threshold":
        side = "above" if p.get("above", True) else "below"
        return f"{w[0]} knee ({side} {_fmt(float(p['knee']))})"
    if c.operator == "product":
        return f"{w[0]} × {w[1]}"
    if c.operator == "resonance":
        return f"{w[0]} resonance (near {_fmt(float(p['center']))})"
    if c.operator == "window":
        return f"{w[0]} spread inside the analysis window"
    if c.operator == "lag":
        return "input-to-vibration lag"
    raise ValueError(f"unknown operator {c.operator!r}")


def sample_series(record: pd.DataFrame, aircraft, exclude=()) -> dict[str, np.ndarray]:
    """Every numeric channel of a record (float64) and the derived features."""
    skip = set(EXCLUDED_CHANNELS) | set(exclude)
    ch = {c: record[c].to_numpy(np.float64) for c in record.columns
          if c not in skip and pd.api.types.is_numeric_dtype(record[c])}
    needed = ("airspeed_kt", "rotor_rpm", "roll_angle_deg", "pitch_rate_dps", "gross_weight_lb", "density_ratio")
    if all(k in ch for k in needed):
        # Padded to a bucket length: every record length would otherwise compile its own ops.
        n = len(record)
        pad = -(-n // 4096) * 4096 - n
        padded = {k: np.pad(ch[k], (0, pad), mode="edge") for k in needed}
        ch.update({k: np.asarray(v, np.float64)[:n] for k, v in derive_features(padded, aircraft).items()})
    return ch


def _interp_columns(tq, t, x):
    """`np.interp(tq, t, x[:, c])` for every column of x (T, C) at once: the search is shared
    (same formula as NumPy's, so the same numbers); tq within [t[0], t[-1]]."""
    j = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, len(t) - 1)
    j1 = np.minimum(j + 1, len(t) - 1)
    on_sample = (j1 == j) | (t[j] == tq)
    dt = np.where(on_sample, 1.0, t[j1] - t[j])[:, None]
    x0 = x[j]
    return np.where(on_sample[:, None], x0, (x[j1] - x0) / dt * (tq - t[j])[:, None] + x0)


def _rate(x, t, span: float):
    """dx/dt over `span` seconds: (x(t + span/2) − x(t − span/2)) / span on the linear
    interpolant, the span shortened at the record's ends. Sample-to-sample differences of a
    measured channel are mostly sensor noise (0.1 deg/s of noise at 320 Hz is ±45 deg/s² of
    "pitch acceleration"); over one rotor revolution, the time scale the vibration is
    analysed on, the derivative follows the maneuver. x: (T,) or (T, C)."""
    if len(t) < 2:
        return np.zeros_like(x)
    vec = np.ndim(x) == 1
    x = np.asarray(x)[:, None] if vec else np.asarray(x)
    lo, hi = np.clip(t - span / 2, t[0], t[-1]), np.clip(t + span / 2, t[0], t[-1])
    r = (_interp_columns(hi, t, x) - _interp_columns(lo, t, x)) / np.maximum(hi - lo, 1e-12)[:, None]
    return r[:, 0] if vec else r


def _cumulative(s, t):
    """Cumulative trapezoid integral of the columns of s (T, M) over t (T,), from t[0]."""
    out = np.empty(s.shape, np.float64)
    out[0] = 0.0
    inc = out[1:]
    np.add(s[1:], s[:-1], out=inc)  # in place: s can be a record's hundred columns
    inc *= 0.5
    inc *= np.diff(t)[:, None]
    np.cumsum(inc, axis=0, out=inc)
    return out


def interval_means(s, t, t0, t1, cum=None):
    """Means of the linear interpolant of samples s(t) over the intervals [t0, t1].

    Args:
        s: (T,) or (T, M) samples. t: (T,) increasing times, s. t0, t1: (W,) interval edges
            (clipped to the record). cum: `_cumulative(s, t)` if already computed.

    Returns:
        (W,) or (W, M) means.
    """
    s, t = np.asarray(s, np.float64), np.asarray(t, np.float64)
    vec = s.ndim == 1
    s = s[:, None] if vec else s
    cum = _cumulative(s, t) if cum is None else cum
    a, b = np.clip(t0, t[0], t[-1]), np.clip(t1, t[0], t[-1])

    def integral_to(tq):  # ∫ from t[0] to tq of the linear interpolant
        i = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, len(t) - 2)
        d = (tq - t[i])[:, None]
        slope = (s[i + 1] - s[i]) / (t[i + 1] - t[i])[:, None]
        return cum[i] + s[i] * d + 0.5 * slope * d * d

    out = (integral_to(b) - integral_to(a)) / np.maximum(b - a, 1e-12)[:, None]
    return out[:, 0] if vec else out


def _signed(x) -> bool:
    """Both signs in a real share of the samples (so that the magnitude is another candidate)."""
    return bool(np.mean(x > 0) > 0.05 and np.mean(x < 0) > 0.05)


def window_table(campaign: Campaign, intervals: pd.DataFrame, exclude=(), channels=None) -> pd.DataFrame:
    """Window means of every channel-level column (see module docstring).

    Args:
        campaign: the campaign.
        intervals: one row per window with `counter`, `t0`, `t1` (s, record time).
        exclude: channels left out.
        channels: only these channels and derived features (default: all).

    Returns:
        DataFrame aligned with `intervals`, columns `x:<ch>`, `abs:<ch>`, `rate:<ch>`,
        `abs_rate:<ch>`, `spread:<ch>`; `attrs["signed"]` lists the channels that take both
        signs (whose magnitude is a candidate of its own).
    """
    return window_tables(campaign, [intervals], exclude, channels)[0]


def channels_lacking(campaign: Campaign, counters) -> dict[str, list[str]]:
    """The numeric channels some of `counters`' records carry and others lack (an optional
    channel a logger did not record in every flight), each with the counters that lack it:
    they are not candidates, since a candidate's value is needed in every window.

    Returns:
        channel -> counters without it; empty where every record carries the same channels.
    """
    have = {c: {k for k in campaign.records[c].columns if pd.api.types.is_numeric_dtype(campaign.records[c][k])}
            for c in counters}
    every = set().union(*have.values()) if have else set()
    return {k: [c for c in counters if k not in have[c]] for k in sorted(every)
            if any(k not in h for h in have.values())}


def window_tables(campaign: Campaign, intervals: list[pd.DataFrame], exclude=(), channels=None) -> list[pd.DataFrame]:
    """`window_table` of several interval sets of the same windows (the same index and
    counters, other times: the windows at other offsets) in one pass over each record's
    samples: the series, rates and running integrals are computed once per record."""
    first = intervals[0]
    for iv in intervals[1:]:
        if not (iv.index.equals(first.index) and (iv.counter.to_numpy() == first.counter.to_numpy()).all()):
            raise ValueError("window_tables: interval sets must share their index and counters")
    parts, names, signed, order = [[] for _ in intervals], None, {}, []
    groups = first.groupby("counter", sort=False).indices
    lacking = channels_lacking(campaign, list(groups))
    for counter, rows in groups.items():
        rec = campaign.records[counter]
        ser = sample_series(rec, campaign.aircraft, exclude)
        ser = {k: v for k, v in ser.items() if k not in lacking and (channels is None or k in channels)}
        if names is None:
            names = list(ser)
        ser = {k: ser[k] for k in names}  # each record's columns in the first's order
        t = rec["time_s"].to_numpy(np.float64)
        span = 60.0 / float(np.mean(rec["rotor_rpm"])) if "rotor_rpm" in rec else 0.25  # one revolution, s
        # A few windows in a long record (the training windows: one per record) take only the
        # samples they and their rates reach (a revolution of margin; rates inside are the
        # record's). Windows over most of the record integrate it whole, from its start.
        edges = np.concatenate([np.r_[iv.t0.to_numpy()[rows], iv.t1.to_numpy()[rows]] for iv in intervals])
        i0, i1 = 0, len(t)
        if not np.isnan(edges).any():  # a NaN edge gives NaN means for its row, as over the whole record
            i0 = max(int(np.searchsorted(t, edges.min() - span)) - 2, 0)
            i1 = min(int(np.searchsorted(t, edges.max() + span)) + 2, len(t))
            if i1 - i0 > len(t) // 2:
                i0, i1 = 0, len(t)
        x = np.stack([v[i0:i1] for v in ser.values()], axis=1)  # (T, C)
        # Centred before squaring: the spread of a large constant stays 0.
        centre = np.array([np.mean(v) for v in ser.values()])
        t = t[i0:i1]
        r = _rate(x, t, span)
        cols = np.stack([x, np.abs(x), r, np.abs(r), (x - centre) ** 2], axis=2).reshape(len(t), -1)
        cum = _cumulative(cols, t)
        for k, v in ser.items():
            signed[k] = signed.get(k, False) or _signed(v)
        order.append(rows)
        for iv, out_parts in zip(intervals, parts):
            m = interval_means(cols, t, iv.t0.to_numpy()[rows], iv.t1.to_numpy()[rows], cum)
            m = m.reshape(len(rows), len(names), 5)
            m[:, :, 4] = np.sqrt(np.maximum(m[:, :, 4] - (m[:, :, 0] - centre) ** 2, 0.0))  # mean square -> spread
            out_parts.append(m.reshape(len(rows), -1))
    # One frame per interval set (a frame per record and a column per array cost more than the means).
    columns = [f"{kind}:{k}" for k in names or () for kind in ("x", "abs", "rate", "abs_rate", "spread")]
    index = first.index[np.concatenate(order)] if order else first.index[:0]
    tables = []
    for iv, out_parts in zip(intervals, parts):
        data = np.concatenate(out_parts) if out_parts else np.zeros((0, len(columns)))
        table = pd.DataFrame(data, index=index, columns=columns).loc[iv.index]
        table.attrs["signed"] = sorted(k for k, v in signed.items() if v)
        tables.append(table)
    return tables


def _hinge(u, softness):
    return softness * np.logaddexp(0.0, u / softness)


def columns_of(c: Candidate) -> list[str]:
    """The `window_table` columns a candidate is computed from: its channel's mean, magnitude,
    rate, rate's magnitude or spread, or (a knee, product or band) its channels' means; none
    for a lag, which the table does not hold."""
    ch = c.channels
    if c.operator == "input":
        return [("abs:" if c.parameters.get("transform") == "abs" else "x:") + ch[0]]
    if c.operator in ("rate", "abs_rate"):
        return [f"{c.operator}:{ch[0]}"]
    if c.operator == "window":
        return [f"spread:{ch[0]}"]
    return [f"x:{k}" for k in ch]


def values(c: Candidate, table: pd.DataFrame) -> np.ndarray:
    """A candidate's value per window, from a `window_table`."""
    p = c.parameters
    x = lambda k: table[f"x:{k}"].to_numpy()  # noqa: E731
    if c.operator in ("input", "rate", "abs_rate", "window"):
        return table[columns_of(c)[0]].to_numpy()
    if c.operator == "threshold":
        u = x(c.channels[0]) - p["knee"]
        return _hinge(u if p.get("above", True) else -u, p["softness"])
    if c.operator == "product":
        return x(c.channels[0]) * x(c.channels[1])
    if c.operator == "resonance":
        return band((x(c.channels[0]) - p["center"]) / p["width"], p.get("shape", "gaussian"), np)
    raise ValueError(f"operator {c.operator!r} is not evaluated from window means")


def library(table: pd.DataFrame, *, model_inputs=(), knee_quantiles=(0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95),
            resonance_channels=("rotor_rpm",), resonance_centers: int = 9, resonance_shape: str = "gaussian",
            product_channels=("advance_ratio", "blade_loading", "climb_rate_fpm", "mlf", "rotor_rpm",
                              "collective_pct")) -> list[Candidate]:
    """Every candidate of a window table.

    `input` candidates are the channels the model does not already take (and the magnitude
    of every signed channel); the other operators apply to every channel. Knees sit at the
    `knee_quantiles` of the channel's window means (above and below); resonance centres
    span the 5–95 % range of the channel with a width of one grid step.

    Args:
        table: `window_table` of the windows the candidates are fitted on.
        model_inputs: the model's inputs.
        resonance_shape: the bands' shape (`effects.band`); a Lorentzian band carries it as
            its parameter `shape`.

    Returns:
        list of `Candidate`.
    """
    chans = [c[2:] for c in table.columns if c.startswith("x:")]
    signed = set(table.attrs.get("signed", ()))
    varying = [k for k in chans if np.ptp(table[f"x:{k}"].to_numpy()) > 0]
    out: list[Candidate] = []
    for k in varying:
        if k not in model_inputs:
            out.append(Candidate("input", (k,)))
        if k in signed:
            out.append(Candidate("input", (k,), {"transform": "abs"}))
        out += [Candidate("rate", (k,)), Candidate("abs_rate", (k,)), Candidate("window", (k,))]
        xv = table[f"x:{k}"].to_numpy()
        soft = 0.02 * float(np.subtract(*np.percentile(xv, [95, 5]))) or 1e-6
        for q in knee_quantiles:
            knee = float(np.quantile(xv, q))
            if q >= 0.5:
                out.append(Candidate("threshold", (k,), {"knee": knee, "above": True, "softness": soft}))
            if q <= 0.5:
                out.append(Candidate("threshold", (k,), {"knee": knee, "above": False, "softness": soft}))
    for k in resonance_channels:
        if k in varying:
            lo, hi = np.percentile(table[f"x:{k}"], [5, 95])
            centers = np.linspace(lo, hi, resonance_centers)
            width = float(centers[1] - centers[0]) if resonance_centers > 1 else float(hi - lo) or 1.0
            shape = {} if resonance_shape == "gaussian" else {"shape": resonance_shape}
            out += [Candidate("resonance", (k,), {"center": float(c), "width": width, **shape}) for c in centers]
    prods = [k for k in product_channels if k in varying]
    for i, a in enumerate(prods):
        for b in prods[i + 1:]:
            out.append(Candidate("product", (a, b)))
    return out
