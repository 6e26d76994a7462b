"""Arguments of the numerical entry points, checked before any work, each refused by name."""

from __future__ import annotations

import math
import numbers


def check_arguments(window_revs, hop_revs, harmonic, taper_revs, start_revs) -> None:
    """`analyze`'s numbers, each refused by name where no analysis could use it (a NumPy
    scalar is a number like Python's)."""
    for name, v, ok, need in (("window_revs", window_revs, lambda v: v > 0, "above 0 revolutions"),
                              ("hop_revs", hop_revs, lambda v: v > 0, "above 0 revolutions"),
                              ("taper_revs", taper_revs, lambda v: 0 <= v, "at least 0 revolutions"),
                              ("start_revs", start_revs, lambda v: 0 <= v, "at least 0 revolutions")):
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v) or not ok(v):
            raise ValueError(f"{name} = {v!r}: must be a number {need}")
    if 2 * taper_revs > window_revs:
        raise ValueError(f"taper_revs = {taper_revs!r}: its two edges must fit in the window of {window_revs!r} "
                         "revolutions")
    if isinstance(harmonic, bool) or not isinstance(harmonic, numbers.Integral) or harmonic < 1:
        raise ValueError(f"harmonic = {harmonic!r}: must be a whole number of cycles per revolution, at least 1")
