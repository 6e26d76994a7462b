"""The real-time element as dependency-free C99 source (`pvv_element.h`, `pvv_element.c`).

`c_sources` turns an element (its `element.json` settings and its nets as `NumpyNet`) into C:
the nets' weights become constants (input and output scalings already folded in, padding
dropped), and the element's arithmetic is `csrc/pvv_element.c`, the NumPy element line by line.
Inputs may be features or their rates (`element.input_source`), nets MLP, RBF or GRU (whose
state the element carries from window to window). The frame buffers have a fixed size, chosen
here from the highest frame rate, the lowest rotor speed and the largest window and offsets a
host may set; nothing is allocated at run time. Imports NumPy only.
"""

from __future__ import annotations

import ctypes
import math
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np

from .element import AIRCRAFT_DEFAULTS, AXIS_OUTPUTS, CHANNELS, FEATURES, input_source, shake_settings

__all__ = ["CElement", "CSourceLimits", "buffer_capacity", "c_compiler", "c_sources", "compile_shared",
           "write_c_element"]

_CSRC = Path(__file__).parent / "csrc"


class CSourceLimits:
    """What the C element's buffers are sized for, and the settings a host may choose.

    Args:
        max_rate_hz: highest frame rate, Hz.
        min_rpm_ratio: lowest rotor speed as a fraction of the aircraft's nominal rpm (0.5:
            the campaign checks' own lower limit).
        window_revs: (lo, hi) window length a host may set, revolutions.
        max_offset_s, max_stick_offset_s: largest |offset| and |stick offset|, s.

    The defaults are the calibration's bounds (`pvvjax.replay.Bounds`), so any calibrated
    setting fits.
    """

    def __init__(self, max_rate_hz: float = 1000.0, min_rpm_ratio: float = 0.5, window_revs=(4.0, 16.0),
                 max_offset_s: float = 3.0, max_stick_offset_s: float = 2.0):
        if not (max_rate_hz > 0 and 0 < min_rpm_ratio <= 1 and 0 < window_revs[0] <= window_revs[1]
                and max_offset_s >= 0 and max_stick_offset_s >= 0):
            raise ValueError("C element limits: a rate > 0, a rotor-speed ratio in (0, 1], 0 < window lo <= hi, "
                             "offsets >= 0")
        self.max_rate_hz, self.min_rpm_ratio = float(max_rate_hz), float(min_rpm_ratio)
        self.window_revs = (float(window_revs[0]), float(window_revs[1]))
        self.max_offset_s, self.max_stick_offset_s = float(max_offset_s), float(max_stick_offset_s)


def buffer_capacity(limits: CSourceLimits, nominal_rpm: float) -> int:
    """Frames the element may have to hold: after each window it keeps frames from the next
    window's start less the largest offset, and it needs them up to that window's end less the
    most negative offset and two frames; a window of the largest length, both offsets at their
    extremes, at the highest rate and the lowest rotor speed, with 4 revolutions and 16 frames
    to spare."""
    per_rev = limits.max_rate_hz * 60.0 / (limits.min_rpm_ratio * nominal_rpm)
    offsets = 2.0 * (limits.max_offset_s + limits.max_stick_offset_s)
    return int(math.ceil((limits.window_revs[1] + 4.0) * per_rev + offsets * limits.max_rate_hz)) + 16


def history_capacity(spec: dict, limits: CSourceLimits, nominal_rpm: float) -> int:
    """Windows a dynamic element keeps for its delay: those within the delay at a quarter of
    the exported hop and twice the nominal rotor speed, and 4 to spare (1 without a response)."""
    if not spec.get("response"):
        return 1
    per_s = 2.0 * nominal_rpm / 60.0 / (0.25 * spec["hop_revs"])
    return int(math.ceil(float(spec["response"]["delay_s"]) * per_s)) + 4


def _response_defines(spec: dict) -> dict:
    """The dynamic response's constants (`PVV_RESPONSE` 0: a quasi-static element)."""
    r = spec.get("response")
    if not r:
        return dict(RESPONSE=0, OMEGA_N="0.0", ZETA="0.0", DELAY_S="0.0")
    return dict(RESPONSE=1, OMEGA_N=_num(r["omega_n_rad_s"]), ZETA=_num(r["zeta"]), DELAY_S=_num(r["delay_s"]))


def _num(v) -> str:
    v = float(v)
    if math.isnan(v):
        return "NAN"
    if math.isinf(v):
        return "HUGE_VAL" if v > 0 else "-HUGE_VAL"
    return repr(v)


def _array(name: str, values, ctype: str = "double") -> str:
    vals = [str(int(v)) if ctype == "int" else _num(v) for v in np.ravel(values)] or ["0"]  # C99: no empty array
    lines, line = [], "   "
    for v in vals:
        if len(line) + len(v) + 2 > 100:
            lines.append(line)
            line = "   "
        line += " " + v + ","
    lines.append(line)
    return f"static const {ctype} {name}[{len(vals)}] = {{\n" + "\n".join(lines) + "\n};\n"


def _net_source(k: int, net) -> str:
    """Constants and the evaluating function `net{k}(z, state, out)` of one `NumpyNet` (MLP,
    RBF or GRU), writing its `n_out` outputs; a GRU advances its `state` in place."""
    p = f"NET{k}_"
    out = []
    if net.kind == "gru":
        out += [_array(f"{p}WI", net.w_i), _array(f"{p}BI", net.b_i), _array(f"{p}WH", net.w_h),
                _array(f"{p}WHN", net.w_hn), _array(f"{p}BHN", net.b_hn), _array(f"{p}WOUT", net.w_out)]
        body = [f"    double next[{net.hidden}];",
                f"    out[0] = gru(z, {net.n_in}, {net.hidden}, {p}WI, {p}BI, {p}WH, {p}WHN, {p}BHN, {p}WOUT, "
                f"{_num(net.b_out)}, state, next);"]
    elif net.kind == "mlp":
        widths = [w.shape[1] for w in net.w[:-1]]
        for i, (w, b) in enumerate(zip(net.w[:-1], net.b[:-1])):
            out += [_array(f"{p}W{i}", w), _array(f"{p}B{i}", b)]
        w_out = np.reshape(net.w[-1], (net.w[-1].shape[0], -1)).T  # (n_out, n_prev): one row per output
        out += [_array(f"{p}WOUT", w_out), _array(f"{p}BOUT", np.ravel(net.b[-1]))]
        body = [f"    double {', '.join(f'h{i}[{n}]' for i, n in enumerate(widths))};"] if widths else []
        prev, n_prev = "z", net.n_in
        for i, n in enumerate(widths):
            body.append(f"    dense_tanh({prev}, {n_prev}, {p}W{i}, {p}B{i}, {n}, h{i});")
            prev, n_prev = f"h{i}", n
        body.append(f"    int o;\n    for (o = 0; o < {w_out.shape[0]}; o++) "
                    f"out[o] = dot({prev}, {p}WOUT + o * {n_prev}, {n_prev}) + {p}BOUT[o];")
    else:
        n_c = net.centers.shape[0]
        out += [_array(f"{p}SHIFT", net.shift), _array(f"{p}SCALE", net.scale), _array(f"{p}CENTERS", net.centers),
                _array(f"{p}INV2W2", np.broadcast_to(net.inv2w2, (n_c,))), _array(f"{p}WO", net.wo)]
        body = [f"    out[0] = rbf(z, {net.n_in}, {n_c}, {p}SHIFT, {p}SCALE, {p}CENTERS, {p}INV2W2, {p}WO, "
                f"{_num(net.bo)});"]
    if net.kind != "gru":
        body.insert(0, "    (void)state;")
    return ("".join(out) + f"static void net{k}(const double *z, double *state, double *out)\n{{\n"
            + "\n".join(body) + "\n}\n")


def c_sources(spec: dict, nets: list, limits: CSourceLimits = CSourceLimits(), source: str = "") -> dict[str, str]:
    """The C element's two files, {"pvv_element.h": text, "pvv_element.c": text}.

    Args:
        spec: the element's settings, as `export.element_spec` makes them (element.json).
        nets: the nets as `NumpyNet`, in `spec["inputs"]` order; the element predicts their median.
        limits: what the buffers are sized for and the settings a host may choose.
        source: a line naming where the nets came from, written into both files.
    """
    inputs = list(spec["inputs"])
    if not nets:
        raise ValueError("a C element needs at least one net")
    for i, net in enumerate(nets):
        if net.n_in != len(inputs):
            raise ValueError(f"net {i} takes {net.n_in} inputs; the element's database has {len(inputs)}")
    sources = [input_source(k) for k in inputs]
    ac = {**AIRCRAFT_DEFAULTS, **spec.get("aircraft", {})}
    lo, hi = limits.window_revs
    if not (lo <= spec["window_revs"] <= hi and abs(spec["offset_s"]) <= limits.max_offset_s
            and abs(spec["stick_offset_s"]) <= limits.max_stick_offset_s):
        raise ValueError(f"the element's window {spec['window_revs']:g} revs, offset {spec['offset_s']:g} s or stick "
                         f"offset {spec['stick_offset_s']:g} s lies outside the C limits")
    env = spec.get("envelope")
    d = len(inputs)
    elo = np.full(d, -np.inf) if env is None else np.asarray(env["lo"], float)
    ehi = np.full(d, np.inf) if env is None else np.asarray(env["hi"], float)
    outputs, shake = element_outputs(spec)
    n_out = {getattr(net, "n_out", 1) for net in nets}
    if n_out != {len(outputs)}:
        raise ValueError(f"the nets give {sorted(n_out)} output(s); the element predicts {len(outputs)} ({outputs})")
    harm = [(i, int(k), v) for i, s in enumerate(shake) for k, v in dict(s.get("harmonics") or {}).items()]
    defines = dict(BLADES=int(ac["blades"]),
                   ROTOR_RADIUS_FT=_num(ac["rotor_radius_ft"]), G_FT_S2=_num(ac["g_ft_s2"]),
                   DEFAULT_OFFSET_S=_num(spec["offset_s"]), DEFAULT_STICK_OFFSET_S=_num(spec["stick_offset_s"]),
                   DEFAULT_WINDOW_REVS=_num(spec["window_revs"]), DEFAULT_HOP_REVS=_num(spec["hop_revs"]),
                   N_INPUTS=d, N_HARMONICS=len(harm), RATES=int(any(r for _, r in sources)),
                   **_response_defines(spec))
    seat_axis = {"x": 0, "y": 1, "z": 2}
    constants = "".join(f"#define PVV_{k} {v}\n" for k, v in defines.items()) + "\n"
    constants += f"/* inputs: {', '.join(inputs)} */\n"
    # a feature's index in FEATURES order, its rate's that plus len(FEATURES)
    constants += _array("PVV_INPUT_FEATURE", [FEATURES.index(f) + len(FEATURES) * r for f, r in sources], "int")
    constants += _array("PVV_LO", elo) + _array("PVV_HI", ehi)
    constants += f"/* outputs: {', '.join(outputs)} */\n"
    constants += _array("PVV_OUT_AXIS", [seat_axis[AXIS_OUTPUTS[o]] for o in outputs], "int")
    constants += _array("PVV_PHASE", [s.get("phase_rad", 0.0) for s in shake])
    constants += _array("PVV_ONCE_G", [s.get("once_g", 0.0) for s in shake])
    constants += _array("PVV_ONCE_PHASE", [s.get("once_phase_rad", 0.0) for s in shake])
    constants += _array("PVV_HARMONIC_OUT", [h[0] for h in harm], "int")
    constants += _array("PVV_HARMONIC_K", [h[1] for h in harm])
    constants += _array("PVV_HARMONIC_RATIO", [h[2][0] for h in harm])
    constants += _array("PVV_HARMONIC_PHASE", [h[2][1] for h in harm])
    kinds = {net.kind for net in nets}
    helpers = "".join((_CSRC / f"net_{k}.inc").read_text() + "\n" for k in ("mlp", "rbf", "gru") if k in kinds)
    nets_src = helpers + "\n".join(_net_source(k, net) for k, net in enumerate(nets))
    table = ", ".join(f"net{k}" for k in range(len(nets)))
    nets_src += ("\ntypedef void (*pvv_net_fn)(const double *z, double *state, double *out);\n"
                 f"static const pvv_net_fn PVV_NETS[PVV_N_NETS] = {{{table}}};\n")
    header = dict(BLADES=str(int(ac["blades"])), SOURCE=source or "pvvjax", MAX_RATE_HZ=_num(limits.max_rate_hz),
                  MIN_RPM=_num(limits.min_rpm_ratio * ac["nominal_rpm"]), MIN_WINDOW_REVS=_num(lo),
                  MAX_WINDOW_REVS=_num(hi), MAX_OFFSET_S=_num(limits.max_offset_s),
                  MAX_STICK_OFFSET_S=_num(limits.max_stick_offset_s),
                  CAPACITY=str(buffer_capacity(limits, ac["nominal_rpm"])),
                  HIST=str(history_capacity(spec, limits, ac["nominal_rpm"])), N_OUT=str(len(outputs)),
                  N_NETS=str(len(nets)), STATE=str(max([net.hidden for net in nets if net.kind == "gru"] or [1])),
                  OUTPUTS=", ".join(outputs))
    h = _fill((_CSRC / "pvv_element.h").read_text(), header)
    c = _fill((_CSRC / "pvv_element.c").read_text(), dict(SOURCE=header["SOURCE"], CONSTANTS=constants, NETS=nets_src))
    return {"pvv_element.h": h, "pvv_element.c": c}


def element_outputs(spec: dict) -> tuple[list[str], list[dict]]:
    """An element's outputs (the axes its nets predict) and each one's shake settings, as
    `VibrationElement` reads them from `element.json` (`outputs`, `shake`; an element of one
    output may give only `phase_rad` and `harmonics`)."""
    outputs = list(spec.get("outputs") or ["az_g"])
    return outputs, shake_settings(outputs, spec.get("shake"), spec.get("phase_rad", 0.0), spec.get("harmonics"))


def _fill(template: str, values: dict) -> str:
    for k, v in values.items():
        template = template.replace(f"@{k}@", v)
    left = re.findall(r"@[A-Z_]+@", template)
    if left:
        raise AssertionError(f"unfilled placeholders in the C template: {left}")
    return template


def write_c_element(out, spec: dict, nets: list, limits: CSourceLimits = CSourceLimits(), source: str = "") -> Path:
    """Write `pvv_element.h` and `pvv_element.c` into folder `out` (created); returns it."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for name, text in c_sources(spec, nets, limits, source).items():
        (out / name).write_text(text)
    return out


def c_compiler() -> str | None:
    """The C compiler to build with: `$CC`, else `cc`, `gcc` or `clang` on the PATH (None: none)."""
    for name in ([os.environ["CC"]] if os.environ.get("CC") else []) + ["cc", "gcc", "clang"]:
        found = shutil.which(name)
        if found:
            return found
    return None


def compile_shared(sources: list, out, flags: tuple = ("-O2",)) -> Path:
    """Compile C99 sources into a shared library `out` with `c_compiler()`; a compiler error is
    raised with its message."""
    cc = c_compiler()
    if cc is None:
        raise RuntimeError("no C compiler found (set CC, or install cc, gcc or clang)")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    cmd = [cc, "-std=c99", *flags, "-shared", "-fPIC", "-o", str(out), *map(str, sources), "-lm"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{done.stderr}")
    return out


class _Settings(ctypes.Structure):
    _fields_ = [("offset_s", ctypes.c_double), ("stick_offset_s", ctypes.c_double), ("window_revs", ctypes.c_double),
                ("hop_revs", ctypes.c_double), ("clip", ctypes.c_int)]


class _Output(ctypes.Structure):
    _fields_ = [(k, ctypes.c_double) for k in ("pvv_g", "shake_g", "amplitude_g", "window_time_s", "pvv_x_g",
                                                "pvv_y_g", "pvv_z_g", "shake_x_g", "shake_y_g", "shake_z_g")] + [
        (k, ctypes.c_int) for k in ("ready", "out_of_envelope", "rejected", "overflow")]


class CElement:
    """A compiled C element driven from Python through ctypes (tests, benchmarks, a Python
    host): the same `step`, `reset` as `VibrationElement`, returning a dict of the outputs.

    Args:
        library: the shared library built from `pvv_element.c` (`compile_shared`).
        **settings: offset_s, stick_offset_s, window_revs, hop_revs, clip (default: as exported).
    """

    def __init__(self, library, **settings):
        self.lib = ctypes.CDLL(str(library))
        self.lib.pvv_element_size.restype = ctypes.c_ulong
        self.lib.pvv_default_settings.restype = _Settings
        self.lib.pvv_init.argtypes = [ctypes.c_void_p, ctypes.POINTER(_Settings)]
        self.lib.pvv_step.restype = _Output
        self.lib.pvv_step.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double,
                                      ctypes.POINTER(ctypes.c_double)]
        self.lib.pvv_reset.argtypes = [ctypes.c_void_p]
        self._mem = ctypes.create_string_buffer(self.lib.pvv_element_size())
        s = self.lib.pvv_default_settings()
        for k, v in settings.items():
            setattr(s, k, v)
        if self.lib.pvv_init(self._mem, ctypes.byref(s)) != 0:
            raise ValueError(f"C element settings outside its limits: {settings}")
        self._ch = (ctypes.c_double * len(CHANNELS))()

    def reset(self):
        self.lib.pvv_reset(self._mem)

    def step(self, time_s: float, azimuth_deg: float | None, channels) -> dict:
        """One frame (azimuth None: integrate the channels' rotor speed); the outputs by name."""
        for i, v in enumerate(channels):
            self._ch[i] = v
        o = self.lib.pvv_step(self._mem, time_s, math.nan if azimuth_deg is None else azimuth_deg, self._ch)
        return {k: getattr(o, k) for k, _ in _Output._fields_}
