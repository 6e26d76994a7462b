"""Strict conversion of TOML tables into frozen dataclasses.

Every key must be a field; every value must have the field's type. Errors name the file
and the dotted key, so a typo in a config never passes silently.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import numbers
import types
import typing
from typing import Any, Literal, Union

import numpy as np


class ConfigError(ValueError):
    """A config file (or table) that does not match its schema."""


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", None) or str(tp).replace("typing.", "")


def _convert(tp: Any, value: Any, where: str) -> Any:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is Any:
        return value
    if origin in (Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(arg, value, where)
            except ConfigError as e:
                errors.append(str(e))
        raise ConfigError(errors[0] if len(errors) == 1 else f"{where}: {value!r} matches none of {tp}")
    if origin is Literal:
        if value not in args:
            raise ConfigError(f"{where}: {value!r} is not one of {', '.join(map(repr, args))}")
        return value
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a table, got {value!r}")
        return from_dict(tp, value, where=where)
    if origin in (tuple, list):
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where}: expected a list, got {value!r}")
        if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        if origin is tuple and args:
            if len(args) != len(value):
                raise ConfigError(f"{where}: expected {len(args)} values, got {len(value)}")
            return tuple(_convert(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value)))
        item = args[0] if args else Any
        return tuple(_convert(item, v, f"{where}[{i}]") for i, v in enumerate(value))
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a table, got {value!r}")
        kt, vt = args if args else (str, Any)
        return {_convert(kt, k, where): _convert(vt, v, f"{where}.{k}") for k, v in value.items()}
    # NumPy's scalars are numbers like Python's (a notebook's np.int64(3) is an integer).
    flag = isinstance(value, (bool, np.bool_))
    if tp is bool:
        if not flag:
            raise ConfigError(f"{where}: expected true/false, got {value!r}")
        return bool(value)
    if tp is int:
        if flag or not isinstance(value, numbers.Integral):
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        return int(value)
    if tp is float:
        if flag or not isinstance(value, numbers.Real):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        if not math.isfinite(value):
            raise ConfigError(f"{where}: {value!r} is not a finite number; give a number")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {value!r}")
        return value
    raise TypeError(f"unsupported config type {_type_name(tp)} at {where}")


def _distinct(values: tuple, where: str) -> None:
    """A list setting is a set of choices (databases, seeds' axes, counters): a value given
    twice is a mistake (it would train or replay the same thing twice), refused by name.
    Fields whose values may repeat (layer widths) carry `metadata={"repeats": True}`."""
    seen, twice = set(), []
    for v in values:
        if v in seen and v not in twice:
            twice.append(v)
        seen.add(v)
    if twice:
        raise ConfigError(f"{where}: {', '.join(map(repr, twice))} given twice in {list(values)}; list each once")


def from_dict(cls: type, data: dict, *, where: str = "") -> Any:
    """Build the frozen dataclass `cls` from a (TOML) table, strictly.

    Args:
        cls: the dataclass type.
        data: the table.
        where: a prefix for error messages (file name and key path).

    Returns:
        An instance of `cls`. Raises `ConfigError` naming the key on an unknown key, a
        wrong type, a NaN or infinite number, a list value given twice, or a value that
        the dataclass's own checks refuse.
    """
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    kwargs = {}
    for key, value in data.items():
        at = f"{where}.{key}" if where else key
        if key not in fields:
            close = difflib.get_close_matches(key, list(fields), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ConfigError(f"{at}: unknown key{hint}; allowed: {', '.join(sorted(fields))}")
        kwargs[key] = _convert(hints[key], value, at)
        if typing.get_origin(hints[key]) is tuple and typing.get_args(hints[key])[-1:] == (Ellipsis,) \
                and not fields[key].metadata.get("repeats"):
            _distinct(kwargs[key], at)
    try:
        return cls(**kwargs)
    except (ValueError, TypeError) as e:
        if isinstance(e, ConfigError):
            raise
        raise ConfigError(f"{where or cls.__name__}: {e}") from None


def to_dict(obj: Any) -> Any:
    """A dataclass (nested) as plain TOML-able values; `None` fields are dropped."""
    if dataclasses.is_dataclass(obj):
        out = {}
        for f in dataclasses.fields(obj):
            v = to_dict(getattr(obj, f.name))
            if v is not None:
                out[f.name] = v
        return out
    if isinstance(obj, dict):
        return {k: to_dict(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_dict(v) for v in obj]
    return obj
