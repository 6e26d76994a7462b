"""Aircraft constants (UH-60A defaults) and unit conversions.

`Aircraft` is a NamedTuple of floats, so it is a PyTree: it can be passed into jitted
functions as an argument and vmapped over like any other array container.
"""

from __future__ import annotations

import math
from typing import NamedTuple

KT_TO_FT_S = 6076.12 / 3600.0  # international knot, ft/s
FPM_TO_FT_S = 1.0 / 60.0
RPM_TO_RAD_S = 2.0 * math.pi / 60.0
DEG_TO_RAD = math.pi / 180.0


class Aircraft(NamedTuple):
    """Main-rotor constants of the aircraft a campaign was flown on.

    Defaults are the UH-60A (physics.md). `campaign.toml` may override any of them.
    """

    rotor_radius_ft: float = 26.83
    blades: int = 4
    nominal_rpm: float = 257.8
    chord_ft: float = 1.73
    solidity: float = 0.0826
    rho0_slug_ft3: float = 0.002377
    g_ft_s2: float = 32.174

    @property
    def disk_area_ft2(self) -> float:
        return math.pi * self.rotor_radius_ft**2

    @property
    def nominal_omega_rad_s(self) -> float:
        return self.nominal_rpm * RPM_TO_RAD_S

    def nominal_np_hz(self) -> float:
        """Blade-passage (N/rev) frequency at nominal rotor speed, Hz."""
        return self.blades * self.nominal_rpm / 60.0


UH60A = Aircraft()
