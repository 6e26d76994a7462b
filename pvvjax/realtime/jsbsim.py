"""JSBSim as a host of the element: its properties as the data contract's channels, and a
rotorcraft's constants read from its model files.

`JSBSIM_CHANNELS` is the one table of the mapping (property, scale, offset: channel = scale ×
property + offset, canonical units); `frame_channels(fdm)` applies it to a running
`jsbsim.FGFDMExec`. JSBSim's rotor model has no azimuth property, so a host steps the element
with the azimuth left out and the rotor speed integrated. `jsbsim_aircraft` reads the main
rotor's constants (diameter, blade count, nominal rpm, chord, solidity) where the model states
them. Importing this module does not import jsbsim.
"""

from __future__ import annotations

import contextlib
import ctypes
import math
import os
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .element import CHANNELS

__all__ = ["JSBSIM_CHANNELS", "frame_channels", "jsbsim_aircraft", "quiet_stdout"]

# channel: (JSBSim property, scale, offset). Sticks: JSBSim's pilot commands, collective 0..1 and
# cyclic -1..1 (positive: right, forward), as percent of travel.
JSBSIM_CHANNELS = {
    "airspeed_kt": ("velocities/vtrue-kts", 1.0, 0.0),
    "gross_weight_lb": ("inertia/weight-lbs", 1.0, 0.0),
    "rotor_rpm": ("propulsion/engine/rotor-rpm", 1.0, 0.0),
    "density_ratio": ("atmosphere/sigma", 1.0, 0.0),
    "pitch_rate_dps": ("velocities/q-rad_sec", 180.0 / math.pi, 0.0),
    "roll_angle_deg": ("attitude/phi-deg", 1.0, 0.0),
    "climb_rate_fpm": ("velocities/h-dot-fps", 60.0, 0.0),
    "collective_pct": ("fcs/collective-cmd-norm", 100.0, 0.0),
    "lateral_pct": ("fcs/aileron-cmd-norm", 50.0, 50.0),
    "longitudinal_pct": ("fcs/elevator-cmd-norm", 50.0, 50.0),
}
assert tuple(JSBSIM_CHANNELS) == CHANNELS

_TIME = "simulation/sim-time-sec"
_LENGTH_FT = {"FT": 1.0, "M": 1.0 / 0.3048, "IN": 1.0 / 12.0}


def frame_channels(fdm) -> tuple[float, np.ndarray]:
    """(time s, the `CHANNELS` values in canonical units) of a JSBSim executive's current frame."""
    x = np.array([fdm[p] * scale + offset for p, scale, offset in JSBSIM_CHANNELS.values()])
    return float(fdm[_TIME]), x


def _length_ft(node) -> float:
    unit = node.get("unit", "FT").upper()
    if unit not in _LENGTH_FT:
        raise ValueError(f"<{node.tag} unit={unit!r}>: a length in FT, M or IN")
    return float(node.text) * _LENGTH_FT[unit]


def jsbsim_aircraft(root, aircraft: str) -> dict:
    """The main rotor's constants as `pvvjax.data.Aircraft` fields, from JSBSim's model files:
    the first thruster of `aircraft/<name>/<name>.xml` that is a rotor (its diameter, numblades,
    nominalrpm and chord) and the model's `metrics/rotor/solidity` property where it is stated
    (else blades × chord / (π R)).

    Args:
        root: JSBSim's root folder (`jsbsim.get_default_root_dir()`).
        aircraft: the model's name, e.g. "ah1s".
    """
    folder = Path(root) / "aircraft" / aircraft
    model = ET.parse(folder / f"{aircraft}.xml").getroot()
    for thruster in model.iter("thruster"):
        path = folder / "Engines" / f"{thruster.get('file')}.xml"
        rotor = ET.parse(path).getroot() if path.is_file() else None
        if rotor is not None and rotor.tag == "rotor":
            break
    else:
        raise ValueError(f"{folder / (aircraft + '.xml')}: no rotor thruster; not a rotorcraft model")
    radius = 0.5 * _length_ft(rotor.find("diameter"))
    blades = int(float(rotor.find("numblades").text))
    chord = _length_ft(rotor.find("chord"))
    out = dict(rotor_radius_ft=radius, blades=blades, nominal_rpm=float(rotor.find("nominalrpm").text), chord_ft=chord,
               solidity=blades * chord / (math.pi * radius))
    for prop in model.iter("property"):
        if (prop.text or "").strip() == "metrics/rotor/solidity" and prop.get("value"):
            out["solidity"] = float(prop.get("value"))
    return out


@contextlib.contextmanager
def quiet_stdout():
    """Send the process's standard output to /dev/null while JSBSim runs: its banner and its
    scripts' <notify> events are printed there by C++, past Python's sys.stdout."""
    sys.stdout.flush()
    saved, null = os.dup(1), os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    try:
        yield
    finally:
        try:
            ctypes.CDLL(None).fflush(None)  # C++ output still buffered in the C library
        except (OSError, AttributeError):  # no C library to ask (not POSIX)
            pass
        os.dup2(saved, 1)
        os.close(saved)
        os.close(null)
