"""Units of the campaign channels and conversion of foreign units into them.

Every canonical channel of the data contract has one unit (`CANONICAL_UNITS`). A user's
column in another unit is converted once, at load time, through SI. A conversion between
different dimensions (a speed given as an angle) is refused.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass

# unit -> (dimension, factor to SI)
_UNITS: dict[str, tuple[str, float]] = {
    "s": ("time", 1.0), "ms": ("time", 1e-3), "min": ("time", 60.0),
    "g": ("acceleration", 9.80665), "m/s^2": ("acceleration", 1.0), "ft/s^2": ("acceleration", 0.3048),
    "deg": ("angle", math.pi / 180), "rad": ("angle", 1.0), "rev": ("angle", 2 * math.pi),
    "deg/s": ("angular_rate", math.pi / 180), "rad/s": ("angular_rate", 1.0),
    "rpm": ("angular_rate", 2 * math.pi / 60), "rev/s": ("angular_rate", 2 * math.pi),
    "kt": ("speed", 1852.0 / 3600), "m/s": ("speed", 1.0), "ft/s": ("speed", 0.3048),
    "km/h": ("speed", 1 / 3.6), "ft/min": ("speed", 0.3048 / 60), "fpm": ("speed", 0.3048 / 60),
    "m/min": ("speed", 1 / 60),
    "%": ("ratio", 0.01), "pct": ("ratio", 0.01), "fraction": ("ratio", 1.0), "1": ("ratio", 1.0),
    "lb": ("weight", 0.45359237), "kg": ("weight", 1.0), "N": ("weight", 1 / 9.80665),
    "hp": ("power", 745.69987), "kW": ("power", 1000.0), "W": ("power", 1.0),
    "ft": ("length", 0.3048), "m": ("length", 1.0),
}

CANONICAL_UNITS: dict[str, str] = {
    "time_s": "s",
    "az_g": "g",
    "ax_g": "g",
    "ay_g": "g",
    "azimuth_deg": "deg",
    "rotor_rpm": "rpm",
    "airspeed_kt": "kt",
    "pitch_rate_dps": "deg/s",
    "roll_angle_deg": "deg",
    "climb_rate_fpm": "ft/min",
    "collective_pct": "%",
    "lateral_pct": "%",
    "longitudinal_pct": "%",
    "gross_weight_lb": "lb",
    "density_ratio": "1",
    "shaft_power_hp": "hp",
    "pedal_pct": "%",
    "roll_rate_dps": "deg/s",
    "yaw_rate_dps": "deg/s",
    "pitch_angle_deg": "deg",
    "nz_g": "g",
    "altitude_ft": "ft",
}

KNOWN_UNITS = tuple(_UNITS)


def conversion_factor(unit: str, canonical: str) -> float:
    """Factor that converts a value in `unit` into the unit of canonical channel `canonical`.

    Raises:
        ValueError: naming the unit and channel, for an unknown unit or a dimension mismatch.
    """
    if unit not in _UNITS:
        raise ValueError(f"unknown unit {unit!r}; known: {', '.join(KNOWN_UNITS)}")
    target = CANONICAL_UNITS.get(canonical)
    if target is None:
        near = difflib.get_close_matches(canonical, list(CANONICAL_UNITS), n=1)
        raise ValueError(f"{canonical!r} is not a data-contract channel, so it has no unit to convert to"
                         + (f" (did you mean {near[0]!r}?)" if near else "")
                         + "; map to a channel of the data contract, or give a scale instead of a unit")
    dim, factor = _UNITS[unit]
    tdim, tfactor = _UNITS[target]
    if dim != tdim:
        raise ValueError(f"unit {unit!r} ({dim}) cannot be converted to {canonical!r} ({target}, {tdim})")
    return factor / tfactor


@dataclass(frozen=True)
class ColumnMap:
    """How one foreign column becomes a canonical channel.

    canonical value = raw value × (unit conversion, if `unit` is given) × `scale` + `offset`.
    """

    to: str
    unit: str | None = None
    scale: float = 1.0
    offset: float = 0.0

    def __post_init__(self):
        if self.unit is not None:
            conversion_factor(self.unit, self.to)  # raises on an unknown unit or wrong dimension
        if self.scale == 0:
            raise ValueError(f"scale 0 would make {self.to} a constant {self.offset:g}; give the channel's factor")

    def factor(self) -> float:
        return (conversion_factor(self.unit, self.to) if self.unit else 1.0) * self.scale
