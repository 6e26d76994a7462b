"""Arguments of the public entry points, checked before any work, each refused by name with
one error type (`ArgumentError`): a notebook user gets what the CLI gives a config's key."""

from __future__ import annotations

import math
import numbers
import os


class ArgumentError(TypeError, ValueError):
    """A public function's argument that no computation could use: of the wrong type, shape
    or range, or a path that is not there. The message names the function, the argument,
    what it got and what it needs. A `TypeError` and a `ValueError` both, so that code that
    caught either before still catches it."""


def _got(v) -> str:
    text = repr(v)
    return text if len(text) <= 60 else f"a {type(v).__name__}"


def refuse(caller: str, name: str, v, need: str) -> ArgumentError:
    """The error for argument `name` of `caller` holding `v` where it needs `need`."""
    return ArgumentError(f"{caller}: {name} = {_got(v)}: must be {need}")


def number(caller: str, name: str, v, *, above=None, at_least=None, at_most=None, whole: bool = False):
    """`v` as a finite real number (a NumPy scalar is one) within the bounds, or an
    `ArgumentError` naming it; a whole number where `whole`."""
    kind = "a whole number" if whole else "a number"
    bounds = [f"above {above:g}" if above is not None else "", f"at least {at_least:g}" if at_least is not None else "",
              f"at most {at_most:g}" if at_most is not None else ""]
    need = " ".join([kind] + [b for b in bounds if b])
    if isinstance(v, bool) or not isinstance(v, numbers.Integral if whole else numbers.Real):
        raise refuse(caller, name, v, need)
    if not math.isfinite(float(v)) or (above is not None and not v > above) or (
            at_least is not None and not v >= at_least) or (at_most is not None and not v <= at_most):
        raise refuse(caller, name, v, need)
    return v


def names(caller: str, name: str, v) -> list[str]:
    """`v` as a list of names (a sequence of strings, not one string), or an
    `ArgumentError` naming it."""
    if isinstance(v, (str, bytes)) or not hasattr(v, "__iter__"):
        raise refuse(caller, name, v, "a list of names (a single one in a list: [name])")
    out = list(v)
    if not all(isinstance(x, str) for x in out):
        raise refuse(caller, name, v, "a list of names (strings)")
    return out


def instance(caller: str, name: str, v, types, need: str):
    """`v` if it is one of `types`, else an `ArgumentError` naming it."""
    if not isinstance(v, types):
        raise refuse(caller, name, v, need)
    return v


def path(caller: str, name: str, v) -> os.PathLike | str:
    """`v` if it is a path (a string or `os.PathLike`), else an `ArgumentError` naming it."""
    return instance(caller, name, v, (str, os.PathLike), "a path (a string or pathlib.Path)")


def check_arguments(window_revs, hop_revs, harmonic, taper_revs, start_revs) -> None:
    """`analyze`'s numbers, each refused by name where no analysis could use it (a NumPy
    scalar is a number like Python's)."""
    number("analyze", "window_revs", window_revs, above=0)
    number("analyze", "hop_revs", hop_revs, above=0)
    number("analyze", "taper_revs", taper_revs, at_least=0)
    number("analyze", "start_revs", start_revs, at_least=0)
    if 2 * taper_revs > window_revs:
        raise refuse("analyze", "taper_revs", taper_revs, f"small enough that its two edges fit in the window of "
                                                            f"{window_revs!r} revolutions")
    number("analyze", "harmonic", harmonic, at_least=1, whole=True)
