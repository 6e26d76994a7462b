"""The real-time vibration element for a simulator host, in NumPy (imports no JAX).

A host calls `step` once per frame with the simulator's state; the element returns the
current peak N/rev pilot-floor vibration (PVV, g; N the blade count, 4/rev on the UH-60A) and
a seat-shake sample, the N/rev acceleration at that amplitude and the rotor's azimuth.

It computes exactly what the offline replay (`pvvjax.replay.replay`, windows every
`hop_revs` revolutions) computes, frame by frame: window j spans revolutions
[a_j, a_j + L) counted from the first frame, its inputs are the state integrated over the
same window moved `offset_s` seconds earlier (sticks `stick_offset_s` more), and its PVV
is the network's prediction from those window averages. Window j's value is ready at the
first frame past the window's end (its time t(b_j) is then known); `pvv_g` holds the latest
ready window, and the seat-shake amplitude ramps from the previous value to it over one
hop, so that the shaker never steps.

Nets of several outputs (`outputs`: the pilot-floor axes they predict, e.g. az_g, ax_g
and ay_g of `pvvjax axes`) give a PVV per axis and a seat shake per axis (`shake_x_g`,
`shake_y_g`, `shake_z_g`: x forward, y right, z vertical as the data contract's `ax_g`,
`ay_g`, `az_g`): each axis's N/rev at its predicted amplitude and its phase, plus its 1/rev
of rotor track and balance at a constant amplitude and set phase (`shake`). An axis the
element does not predict shakes 0. `pvv_g` and `shake_g` are the first output's.

With a `response` (the dynamic model of `pvvjax dynamic`), each window's prediction is the
static map's value passed through a delay and a unit-gain second-order response along the
window times, stepped exactly as `pvvjax.dynamics.second_order` integrates it (Tustin, from
rest at the first window): in trimmed flight it equals the static map, through a maneuver it
lags and rings as identified.

Inputs named `d_<feature>_dt` (the `_rates` models and the GRU of `pvvjax dynamic`) are
a feature's rate, per second: the backward difference of its window average to the window
before, over their centre times, 0 at the first window (as `dynamics.window_sequences`
computes them in training). A recurrent net (`NumpyNet.stateful`) carries its state from
window to window from zero at the first.

Frames are stored as they come (time need not be uniform: jitter, frame-rate changes and
missed frames only change the samples the windows integrate), old frames are dropped once
no future window needs them, and a rotor-speed change is followed through the azimuth.
Inputs outside the training envelope are clipped to it and flagged; a frame with a
non-finite value or a time that does not advance is rejected (flagged, state unchanged).
"""

from __future__ import annotations

import json
import math
import time
import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np

__all__ = ["AIRCRAFT_DEFAULTS", "AXIS_OUTPUTS", "CHANNELS", "FEATURES", "ElementOutput", "VibrationElement",
           "input_source", "shake_settings", "stream"]

# Frame channels, canonical units (data contract): what db1-db3 and their features need.
CHANNELS = ("airspeed_kt", "gross_weight_lb", "rotor_rpm", "density_ratio", "pitch_rate_dps", "roll_angle_deg",
            "climb_rate_fpm", "collective_pct", "lateral_pct", "longitudinal_pct")
# What a net input may be: a channel, or a feature the element derives from the channels.
FEATURES = CHANNELS + ("advance_ratio", "mlf")
# The rotor constants an element uses, where its settings give none (the UH-60A's).
AIRCRAFT_DEFAULTS = {"rotor_radius_ft": 26.83, "g_ft_s2": 32.174, "blades": 4, "nominal_rpm": 257.8}
_STICKS = ("collective_pct", "lateral_pct", "longitudinal_pct")
# The pilot-floor axis a net output predicts -> the seat axis it shakes (x forward, y right, z vertical).
AXIS_OUTPUTS = {"ax_g": "x", "ay_g": "y", "az_g": "z"}
_KT_TO_FT_S = 6076.12 / 3600.0


class ElementOutput(NamedTuple):
    """One frame's outputs.

    Attributes:
        pvv_g: PVV of the latest ready window, g (0 before the first window is ready).
        shake_g: seat-shake sample: amplitude × cos(Nψ + phase) (+ optional harmonics), g.
        amplitude_g: the ramped amplitude of the shake.
        ready: a window has been predicted since the last reset.
        window_time_s: centre time of the window `pvv_g` belongs to (NaN before).
        out_of_envelope: some input of the latest window was clipped to the envelope.
        rejected: this frame was not used (non-finite value or time not advancing).
        pvv_x_g, pvv_y_g, pvv_z_g: each seat axis's N/rev amplitude of the latest ready
            window, g (0 for an axis the element does not predict).
        shake_x_g, shake_y_g, shake_z_g: each seat axis's shake sample, g (x forward, y
            right, z vertical; 0 for an axis the element does not predict).
    """

    pvv_g: float
    shake_g: float
    amplitude_g: float
    ready: bool
    window_time_s: float
    out_of_envelope: bool
    rejected: bool
    pvv_x_g: float = 0.0
    pvv_y_g: float = 0.0
    pvv_z_g: float = 0.0
    shake_x_g: float = 0.0
    shake_y_g: float = 0.0
    shake_z_g: float = 0.0


def input_source(name: str) -> tuple[str, bool]:
    """What a net input is: (the feature, False) for a `FEATURES` name, (the feature, True)
    for its rate `d_<feature>_dt`; any other name is a ValueError naming the ones allowed."""
    if name in FEATURES:
        return name, False
    if name.startswith("d_") and name.endswith("_dt") and name[2:-3] in FEATURES:
        return name[2:-3], True
    raise ValueError(f"input {name!r}: the element computes {', '.join(FEATURES)} and their rates d_<name>_dt")


def shake_settings(outputs, shake=None, phase_rad=0.0, harmonics=None) -> list[dict]:
    """Each output's shake settings (`VibrationElement`'s `shake`): as given, or by default
    the first output's `phase_rad` and `harmonics` and nothing for the others."""
    if shake is not None:
        return [dict(s) for s in shake]
    return [dict(phase_rad=phase_rad, harmonics=harmonics)] + [{} for _ in range(len(outputs) - 1)]


def edge_weight(u):
    """Part of a sample's hat function inside a window edge (u in hat half-widths); the
    same quadratic ramp as the offline replay's "linear" windows."""
    v = np.clip(u, -1.0, 1.0)
    return np.where(v < 0, 0.5 * (1.0 + v) ** 2, 1.0 - 0.5 * (1.0 - v) ** 2)


def _interp(x, xp, fp):
    """Linear interpolation on increasing xp, extrapolating with the end segments (as the
    offline replay does)."""
    i = min(max(int(np.searchsorted(xp, x)), 1), len(xp) - 1)
    x0, x1, f0, f1 = xp[i - 1], xp[i], fp[i - 1], fp[i]
    return f0 + (x - x0) * ((f1 - f0) / (x1 - x0))


class VibrationElement:
    """Streaming PVV and seat shake from one frame of simulator state at a time.

    Args:
        nets: callables x (n, d) -> (n,) PVV, g, or (n, A) for A `outputs` (e.g.
            `npnet.NumpyNet`), or nets with a state (`NumpyNet.stateful`, a GRU: stepped
            window by window); the median over nets is used, output by output.
        inputs: the nets' input names in their order: `FEATURES` (channels or derived
            features) and rates `d_<feature>_dt` (`input_source`).
        window_revs, hop_revs: window length and spacing, revolutions.
        offset_s, stick_offset_s: input-to-vibration offset and the sticks' extra offset, s.
        phase_rad: phase of the N/rev seat shake relative to the blade azimuth.
        envelope: (lo, hi) arrays over `inputs`, or None (no clipping).
        harmonics: extra shake content {k: (ratio to the N/rev amplitude, phase)}.
        aircraft: dict of rotor_radius_ft, g_ft_s2 and blades N (UH-60A defaults; other keys
            are ignored).
        clip: clip inputs to the envelope (always flagged).
        response: None (quasi-static), or dict of omega_n_rad_s, zeta and delay_s: the
            dynamic model's response after the nets' median.
        outputs: the pilot-floor axis each net output predicts (`AXIS_OUTPUTS` keys).
        shake: per output, dict of phase_rad (its N/rev phase), harmonics ({k: (ratio,
            phase)}), once_g and once_phase_rad (its 1/rev of track and balance: constant
            amplitude, g, and phase); default: the first output's `phase_rad` and
            `harmonics`, the others 0, no 1/rev.
    """

    def __init__(self, nets, inputs, *, window_revs=8.0, hop_revs=1.0, offset_s=0.0, stick_offset_s=0.0,
                 phase_rad=0.0, envelope=None, harmonics=None, aircraft=None, clip=True, response=None,
                 outputs=("az_g",), shake=None):
        self.nets = list(nets)
        self.inputs = tuple(inputs)
        self._sources = [input_source(k) for k in self.inputs]
        self.L, self.hop = float(window_revs), float(hop_revs)
        self.tau, self.tau_stick = float(offset_s), float(stick_offset_s)
        self.outputs = tuple(outputs)
        bad = [o for o in self.outputs if o not in AXIS_OUTPUTS] or len(set(self.outputs)) != len(self.outputs)
        if bad or not self.outputs:
            raise ValueError(f"outputs {list(self.outputs)}: each one of {', '.join(AXIS_OUTPUTS)}, at most once")
        shake = shake_settings(self.outputs, shake, phase_rad, harmonics)
        if len(shake) != len(self.outputs):
            raise ValueError(f"shake: one entry per output ({len(self.outputs)}), got {len(shake)}")
        self.shake = [dict(phase_rad=float(s.get("phase_rad", 0.0)),
                           harmonics={int(k): (float(v[0]), float(v[1]))
                                      for k, v in dict(s.get("harmonics") or {}).items()},
                           once_g=float(s.get("once_g", 0.0)), once_phase_rad=float(s.get("once_phase_rad", 0.0)))
                      for s in shake]
        ac = {**AIRCRAFT_DEFAULTS, **(aircraft or {})}
        self.radius, self.g, self.blades = float(ac["rotor_radius_ft"]), float(ac["g_ft_s2"]), int(ac["blades"])
        self.envelope = None if envelope is None else (np.asarray(envelope[0], float), np.asarray(envelope[1], float))
        self.clip = clip
        self.response = None if response is None else {k: float(response[k])
                                                         for k in ("omega_n_rad_s", "zeta", "delay_s")}
        self._stick_cols = [CHANNELS.index(s) for s in _STICKS]
        self.reset()

    @classmethod
    def load(cls, folder, **overrides) -> "VibrationElement":
        """An element exported by `pvvjax export --element` (element.json and the nets'
        .npz parameter files, read without pickle); keyword arguments override the file."""
        try:
            from .npnet import NumpyNet
        except ImportError:  # copied next to npnet.py by `pvvjax export --element`
            from npnet import NumpyNet

        folder = Path(folder)
        try:
            spec = json.loads((folder / "element.json").read_text())
        except ValueError as e:
            raise ValueError(f"{folder / 'element.json'}: not valid JSON ({e}); export the element again "
                             "(pvvjax export --element)") from None
        nets = [NumpyNet.load(folder / name) for name in spec.pop("nets")]
        env = spec.pop("envelope", None)
        spec = {**spec, **overrides}
        return cls(nets, spec.pop("inputs"), envelope=None if env is None else (env["lo"], env["hi"]), **spec)

    # ------------------------------------------------------------------ state

    def reset(self):
        """Forget every frame (a new record or a simulator reset)."""
        cap = 4096
        self._t = np.empty(cap)
        self._r = np.empty(cap)
        self._x = np.empty((cap, len(CHANNELS)))
        self._n = 0
        self._az = None
        self._j = 0  # next window to predict
        self._start = None  # revolution where window 0 starts
        self._pvv = np.zeros(len(self.outputs))
        self._prev = np.zeros(len(self.outputs))
        self._ramp_rev = 0.0  # revolution where the latest value arrived
        self._wtime = math.nan
        self._flag = False
        self._ready = False
        self._dropped = False  # the first stored frame is no longer the record's first
        self._rpm_last = 0.0
        self._hist_t, self._hist_u = [], []  # the static values of recent windows (the delay's past)
        self._states = [net.initial_state() if getattr(net, "stateful", False) else None for net in self.nets]
        self._last = None  # (centre time, features) of the latest window: the rates' backward difference
        self._dyn = None  # (time, delayed input, y, y') of the latest window

    def _respond(self, u: np.ndarray, t: float) -> np.ndarray:
        """The response's output at window time t, from the static values u (one per output:
        one Tustin step of `dynamics.second_order` on the delayed input, as
        `dynamics.delayed` interpolates)."""
        if self.response is None:
            return u
        d = self.response["delay_s"]
        if not self._hist_t:
            self._first = (t, u)
        self._hist_t.append(t)
        self._hist_u.append(u)
        while len(self._hist_t) > 2 and self._hist_t[1] <= t - d:  # older windows lie before every future delay
            self._hist_t.pop(0)
            self._hist_u.pop(0)
        td = t - d
        ud = self._first[1] if td <= self._first[0] else np.array(
            [np.interp(td, self._hist_t, [h[i] for h in self._hist_u]) for i in range(len(u))])
        if self._dyn is None:
            self._dyn = (t, ud, ud, np.zeros_like(ud))
            return ud
        t0, ud0, y, v = self._dyn
        w2, c = self.response["omega_n_rad_s"] ** 2, 2.0 * self.response["zeta"] * self.response["omega_n_rad_s"]
        a = 0.5 * (t - t0)
        r0, r1 = y + a * v, v - a * w2 * y - a * c * v + a * w2 * (ud0 + ud)
        det = 1.0 + a * c + a * a * w2
        y, v = ((1.0 + a * c) * r0 + a * r1) / det, (-a * w2 * r0 + r1) / det
        self._dyn = (t, ud, y, v)
        return y

    def _push(self, t, r, x):
        if self._n == len(self._t):  # grow (rarely: old frames are dropped as windows complete)
            self._t = np.concatenate([self._t, np.empty_like(self._t)])
            self._r = np.concatenate([self._r, np.empty_like(self._r)])
            self._x = np.concatenate([self._x, np.empty_like(self._x)])
        self._t[self._n], self._r[self._n], self._x[self._n] = t, r, x
        self._n += 1

    def _drop(self, keep_from: int):
        """Drop frames before index keep_from (never the first two: they define window 0)."""
        if keep_from <= 2:
            return
        k = keep_from - 1  # keep one more on the left: its hat reaches into the window
        n = self._n - k
        self._t[:n], self._r[:n], self._x[:n] = self._t[k:self._n], self._r[k:self._n], self._x[k:self._n]
        self._n = n
        self._dropped = True

    # ------------------------------------------------------------------ one frame

    def step(self, time_s: float, azimuth_deg: float | None, channels, rotor_rpm: float | None = None) -> ElementOutput:
        """Advance by one frame.

        Args:
            time_s: frame time, s (must increase).
            azimuth_deg: reference-blade azimuth, deg (None: integrate `rotor_rpm` instead).
            channels: the `CHANNELS` values of this frame (sequence or dict), canonical units.
            rotor_rpm: rotor speed, used only when no azimuth is given.
        """
        x = np.array([channels[c] for c in CHANNELS] if isinstance(channels, dict) else channels, float)
        bad = (x.shape != (len(CHANNELS),) or not np.all(np.isfinite(x)) or not math.isfinite(time_s)
               or (self._n and time_s <= self._t[self._n - 1]))
        if azimuth_deg is None:
            rpm = x[CHANNELS.index("rotor_rpm")] if rotor_rpm is None else rotor_rpm
            bad = bad or not math.isfinite(rpm)
        else:
            bad = bad or not math.isfinite(azimuth_deg)
        if bad:
            return self._output(rejected=True)
        if self._n == 0:
            r = (azimuth_deg / 360.0) if azimuth_deg is not None else 0.0
        elif azimuth_deg is not None:
            d = azimuth_deg - self._az
            r = self._r[self._n - 1] + (d - 360.0 * round(d / 360.0)) / 360.0  # unwrapped (as numpy.unwrap)
        else:
            rpm0 = self._rpm_last
            r = self._r[self._n - 1] + 0.5 * (rpm0 + rpm) / 60.0 * (time_s - self._t[self._n - 1])
        self._az = azimuth_deg
        self._rpm_last = x[CHANNELS.index("rotor_rpm")] if rotor_rpm is None else rotor_rpm
        self._push(float(time_s), r, x)
        if self._n == 2 and self._start is None:
            self._start = self._r[0] - 0.5 * (self._r[1] - self._r[0])
        if self._start is not None:
            while self._try_window():
                pass
        return self._output(rejected=False)

    def _amplitude(self) -> np.ndarray:
        """The shake amplitudes now, ramped from the previous window's values."""
        frac = min(max((self._r[self._n - 1] - self._ramp_rev) / self.hop, 0.0), 1.0)
        return self._prev + (self._pvv - self._prev) * frac

    def _output(self, rejected: bool) -> ElementOutput:
        if self._n == 0:
            return ElementOutput(0.0, 0.0, 0.0, False, math.nan, False, rejected)
        amp = self._amplitude()
        psi = 2.0 * math.pi * self._r[self._n - 1]
        pvv, shake = {}, {}
        for i, (axis, s) in enumerate(zip(self.outputs, self.shake)):
            a = float(amp[i])
            v = a * math.cos(self.blades * psi + s["phase_rad"]) + s["once_g"] * math.cos(psi + s["once_phase_rad"])
            for k, (ratio, ph) in s["harmonics"].items():
                v += ratio * a * math.cos(k * psi + ph)
            pvv[AXIS_OUTPUTS[axis]], shake[AXIS_OUTPUTS[axis]] = float(self._pvv[i]), v
        first = AXIS_OUTPUTS[self.outputs[0]]
        return ElementOutput(pvv[first], shake[first], float(amp[0]), self._ready, self._wtime, self._flag, rejected,
                             *(pvv.get(a, 0.0) for a in "xyz"), *(shake.get(a, 0.0) for a in "xyz"))

    # ------------------------------------------------------------------ windows

    def _try_window(self) -> bool:
        n = self._n
        t, r = self._t[:n], self._r[:n]
        a = self._start + self.hop * self._j
        b = a + self.L
        if r[-1] <= b:
            return False
        t_a, t_b = _interp(a, r, t), _interp(b, r, t)
        taus = [self.tau] + ([self.tau + self.tau_stick] if self.tau_stick != 0.0 else [])
        edges = [(_interp(t_a - tau, t, r), _interp(t_b - tau, t, r)) for tau in taus]
        # Every hat touching the input windows must be complete: two samples past the last edge.
        dr = np.diff(r)
        need = max(e[1] for e in edges) + 2.0 * dr.max()
        if r[-1] <= need or n < 3:
            return False
        # Half-way to each neighbour, as the offline analysis (`batch.sample_widths`).
        width = 0.5 * (np.r_[dr[:1], dr] + np.r_[dr, dr[-1:]])
        if self._dropped:
            width[0] = np.nan  # its left neighbour is gone; it lies left of every future window
        means = []
        for lo, hi in edges:
            h = width
            w = h * edge_weight((r - lo) / h) * edge_weight((hi - r) / h)
            w = np.where(np.isfinite(w), w, 0.0)
            means.append(w @ self._x[:n] / w.sum())
        x = means[0]
        if len(means) > 1:
            x = x.copy()
            x[self._stick_cols] = means[1][self._stick_cols]
        # the window's weighted centre time, as the offline analysis's
        w = width * edge_weight((r - a) / width) * edge_weight((b - r) / width)
        w = np.where(np.isfinite(w), w, 0.0)
        tc = float(w @ t / w.sum())
        z, flag = self._net_inputs(x, tc)
        outs = []
        for k, net in enumerate(self.nets):
            if self._states[k] is None:
                outs.append(np.reshape(net(z[None]), -1))
            else:
                self._states[k], y = net.step(self._states[k], z)
                outs.append(np.reshape(y, -1))
        pred = np.median(outs, axis=0)  # (A,)
        if self.response is not None:
            pred = self._respond(pred, tc)
        self._prev = self._amplitude() if self._ready else pred
        self._pvv, self._flag, self._ready = pred, flag, True
        self._ramp_rev = r[-1]
        self._wtime = 0.5 * (t_a + t_b)
        self._j += 1
        # Frames left of every future input window are no longer needed.
        a_next = self._start + self.hop * self._j
        t_next = _interp(a_next, r, t) - max(taus + [0.0])
        self._drop(int(np.searchsorted(t, t_next)) - 2)
        return True

    def _net_inputs(self, x, tc: float):
        """The nets' inputs from a window's channel means `x` at centre time `tc`: features
        and rates, clipped to the envelope, and whether any lay outside it."""
        ch = dict(zip(CHANNELS, x))
        v = ch["airspeed_kt"] * _KT_TO_FT_S
        feats = {
            **ch,
            "advance_ratio": v / (ch["rotor_rpm"] * 2.0 * math.pi / 60.0 * self.radius),
            "mlf": ((1.0 + math.radians(ch["pitch_rate_dps"]) * v / self.g)
                    / math.cos(math.radians(ch["roll_angle_deg"]))),
        }
        last, self._last = self._last, (tc, feats)
        rate = ((lambda f: (feats[f] - last[1][f]) / (tc - last[0])) if last is not None and tc > last[0]
                else (lambda f: 0.0))
        z = np.array([rate(f) if is_rate else feats[f] for f, is_rate in self._sources], float)
        flag = False
        if self.envelope is not None:
            lo, hi = self.envelope
            tol = 1e-9 * (1.0 + np.maximum(np.abs(lo), np.abs(hi)))  # not rounding noise on a constant channel
            flag = bool(np.any(z < lo - tol) or np.any(z > hi + tol))
            if self.clip:
                z = np.clip(z, lo, hi)
        return z, flag


def stream(el, t, az, x, names, what: str = "the frames") -> tuple[np.ndarray, np.ndarray]:
    """Feed an element frame by frame, as a simulator would.

    Args:
        el: an element (`VibrationElement`, `CElement`, ...: `step(t, az, x)`).
        t: (F,) frame times, s. az: (F,) rotor azimuth, deg. x: (F, C) the element's channels.
        names: the `ElementOutput` fields to keep. what: the frames' source, in messages.

    Returns:
        (the outputs `names` per frame (F, len(names)), each frame's latency in µs (F,)). An
        element that never becomes ready (no analysis window complete) is said in a warning
        naming `what`: every value it gave is the 0 it starts from.
    """
    out = np.zeros((t.size, len(names)))
    lat = np.empty(t.size)
    clock = time.perf_counter_ns
    ready = False
    for i in range(t.size):
        s0 = clock()
        o = el.step(t[i], az[i], x[i])
        lat[i] = (clock() - s0) / 1e3
        out[i] = [getattr(o, n) for n in names]
        ready = ready or o.ready
    if not ready:
        warnings.warn(f"the element never became ready on {what} ({t[-1] - t[0]:.1f} s): no analysis window was "
                      "complete, so every PVV and seat-shake value written is the 0 it starts from; give a longer "
                      "record", stacklevel=2)
    return out, lat
