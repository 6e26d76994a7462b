"""What a campaign's files and values must satisfy: readable files that are what they claim
(no other separator, encoding, duplicated or blank header), required channels, numbers,
physical ranges, and records long and uniform enough to analyse. Each failure is a
`Problem` naming file, column and first bad row."""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["RANGES", "REQUIRED_CHANNELS", "UNIFORM_TOLERANCE", "Problem"]

# Channels every record needs (gross weight and density ratio may come from counters.csv).
REQUIRED_CHANNELS = (
    "time_s", "az_g", "rotor_rpm", "airspeed_kt", "pitch_rate_dps", "roll_angle_deg",
    "climb_rate_fpm", "collective_pct", "lateral_pct", "longitudinal_pct",
    "gross_weight_lb", "density_ratio",
)
# (lower, upper, inclusive) physical ranges; None = unbounded.
RANGES: dict[str, tuple[float | None, float | None, bool]] = {
    "collective_pct": (0.0, 100.0, True),
    "lateral_pct": (0.0, 100.0, True),
    "longitudinal_pct": (0.0, 100.0, True),
    "pedal_pct": (0.0, 100.0, True),
    "rotor_rpm": (0.0, None, False),
    "airspeed_kt": (0.0, None, True),
    "density_ratio": (0.3, 1.3, True),
    "roll_angle_deg": (-90.0, 90.0, True),
    "gross_weight_lb": (0.0, None, False),
}
UNIFORM_TOLERANCE = 0.01  # sample spacing may vary by less than 1 %


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a campaign: where it is and what it is. A warning (suspicious,
    not impossible) is reported but does not refuse the campaign."""

    file: str
    column: str | None
    row: int | None
    message: str
    warning: bool = False

    def __str__(self) -> str:
        where = ("warning: " if self.warning else "") + self.file
        if self.column:
            where += f", column {self.column!r}"
        if self.row is not None:
            where += f", row {self.row}"
        return f"{where}: {self.message}"


def _first_bad(mask: np.ndarray) -> int | None:
    idx = np.flatnonzero(mask)
    return int(idx[0]) + 1 if idx.size else None


def _numeric(series: pd.Series) -> np.ndarray:
    return pd.to_numeric(series, errors="coerce").to_numpy(dtype=float)


def _number_hint(text) -> str:
    """What a number written as text most likely needs: a decimal point, or its unit moved
    into the column mapping."""
    t = str(text).strip()
    if re.fullmatch(r"[-+]?\d+,\d+", t):
        return f"; a decimal comma? write {t.replace(',', '.')}"
    m = re.fullmatch(r"([-+]?[\d.]+(?:[eE][-+]?\d+)?)\s*([^\d\s].*)", t)
    if m:
        return (f"; a unit in the value? write the number ({m[1]}) and map the column's unit in the config "
                f"([campaign.columns.NAME] unit = \"{m[2]}\") if it is not the canonical one")
    return ""


def _check_values(df: pd.DataFrame, columns, file: str, problems: list) -> None:
    """Non-numeric / NaN / infinite values and physical ranges, first bad row each. Text in
    row 1 of three or more columns is one problem: a units row under the header."""
    first = len(problems)
    _column_values(df, columns, file, problems)
    units = [p for p in problems[first:] if p.row == 1 and p.message.startswith("non-numeric value")]
    if len(units) >= 3:
        cols = [p.column for p in units]
        problems[first:] = [p for p in problems[first:] if p not in units]
        problems.insert(first, Problem(file, None, 1, f"text in {len(cols)} columns ({', '.join(cols[:3])}, …; "
                                                      f"{units[0].message}): a units row under the header? Remove "
                                                      "it (units go in the column names)"))


def _column_values(df: pd.DataFrame, columns, file: str, problems: list) -> None:
    for col in columns:
        if col not in df.columns:
            continue
        raw = df[col]
        flags = raw.map(lambda v: isinstance(v, (bool, np.bool_))) if raw.dtype == object else None  # mixed column
        if pd.api.types.is_bool_dtype(raw) or (flags is not None and flags.any()):
            row = 1 if flags is None else _first_bad(flags.to_numpy())
            problems.append(Problem(file, col, row, f"true/false value {raw.iloc[row - 1]}, not a number"))
            continue
        vals = _numeric(raw)
        nonnum = np.isnan(vals) & raw.notna().to_numpy()
        row = _first_bad(nonnum)
        if row is not None:
            problems.append(Problem(file, col, row, f"non-numeric value {raw.iloc[row - 1]!r}"
                                    f"{_number_hint(raw.iloc[row - 1])}"))
            continue
        row = _first_bad(~np.isfinite(vals))
        if row is not None:
            problems.append(Problem(file, col, row, f"missing, NaN or infinite value ({raw.iloc[row - 1]})"))
            continue
        lo, hi, inclusive = RANGES.get(col, (None, None, True))
        bad = np.zeros(vals.shape, bool)
        if lo is not None:
            bad |= vals < lo if inclusive else vals <= lo
        if hi is not None:
            bad |= vals > hi if inclusive else vals >= hi
        row = _first_bad(bad)
        if row is not None:
            span = (f"{'[' if inclusive else '('}{'' if lo is None else lo}, "
                    f"{'' if hi is None else hi}{']' if inclusive else ')'}")
            problems.append(Problem(file, col, row, f"value {vals[row - 1]:g} outside the physical range {span}"))


def _gappy_channels(df: pd.DataFrame, file: str, problems: list) -> list[str]:
    """Optional numeric channels with missing or infinite values: each is reported (a warning
    naming its first gap) and left out of the record, so that no gap reaches the analysis."""
    known = set(REQUIRED_CHANNELS) | {"azimuth_deg", "shaft_power_hp", "pedal_pct"}
    out = []
    for col in df.columns:
        if col in known or not pd.api.types.is_numeric_dtype(df[col]):
            continue
        row = _first_bad(~np.isfinite(df[col].to_numpy(dtype=float)))
        if row is not None:
            problems.append(Problem(file, col, row, "gap (missing, NaN or infinite value): this optional channel "
                                    "is left out of the record", warning=True))
            out.append(col)
    return out


def _unwrap_azimuth(az_deg: np.ndarray) -> np.ndarray:
    return np.unwrap(az_deg, period=360.0)


def _integrate_azimuth(time_s: np.ndarray, rpm: np.ndarray) -> np.ndarray:
    """Rotor azimuth (deg, wrapped 0-360) by trapezoidal integration of rotor speed."""
    deg_per_s = rpm * 6.0
    inc = 0.5 * (deg_per_s[1:] + deg_per_s[:-1]) * np.diff(time_s)
    return np.mod(np.concatenate([[0.0], np.cumsum(inc)]), 360.0)


def _check_record(df: pd.DataFrame, file: str, constants: dict, problems: list) -> bool:
    """Check one time series' columns, values and sampling; returns True when they are usable."""
    n_before = len(problems)
    for col in REQUIRED_CHANNELS:
        if col in df.columns and col in constants:
            problems.append(Problem(file, col, None,
                                    "channel given both here and in counters.csv; give it in one place"))
        elif col not in df.columns and col not in constants:
            where = " (or as a constant in counters.csv)" if col in ("gross_weight_lb", "density_ratio") else ""
            problems.append(Problem(file, col, None, f"required column missing{where}"))
    extra = [c for c in ("azimuth_deg", "shaft_power_hp", "pedal_pct") if c in df.columns]
    _check_values(df, [c for c in REQUIRED_CHANNELS if c in df.columns] + extra, file, problems)
    if len(problems) > n_before:
        return False
    t = _numeric(df["time_s"])
    if len(t) < 3:
        problems.append(Problem(file, "time_s", None, f"only {len(t)} samples"))
        return False
    dt = np.diff(t)
    row = _first_bad(dt <= 0)
    if row is not None:
        problems.append(Problem(file, "time_s", row + 1,
                                f"time not strictly increasing ({t[row - 1]:g} then {t[row]:g})"))
        return False
    med = np.median(dt)
    row = _first_bad(np.abs(dt - med) > UNIFORM_TOLERANCE * med)
    if row is not None:
        problems.append(Problem(
            file, "time_s", row + 1,
            f"sampling not uniform: step {dt[row - 1]:g} s vs median {med:g} s (tolerance 1 %)",
        ))
        return False
    return True


def _check_length(df: pd.DataFrame, file: str, window_revs: float, problems: list) -> bool:
    """A record (constants broadcast) that covers at least one analysis window."""
    t, rpm = _numeric(df["time_s"]), _numeric(df["rotor_rpm"])
    dt = np.diff(t)
    revs = float(np.sum(0.5 * (rpm[1:] + rpm[:-1]) * dt) / 60.0 + rpm[-1] / 60.0 * np.median(dt))
    if revs < window_revs:
        problems.append(Problem(
            file, "time_s", None,
            f"record covers {revs:.2f} rotor revolutions, shorter than one analysis window ({window_revs:g} revs)",
        ))
        return False
    return True


_BOMS = {b"\xff\xfe": "UTF-16", b"\xfe\xff": "UTF-16", b"\x00\x00\xfe\xff": "UTF-32"}


def _header_problem(path: Path) -> str | None:
    """What is wrong with a CSV file before pandas reads it (pandas would guess or rename)."""
    head = path.read_bytes()[:65536]
    for bom, name in _BOMS.items():
        if head.startswith(bom):
            return f"{name} text; save it as UTF-8 CSV"
    text = head.decode("utf-8-sig", errors="replace")
    if not text.strip():
        return "file is empty"
    if text.lstrip().startswith("#"):
        return "line 1 starts with '#': comment lines above the header are not read; remove them (the header first)"
    names = next(csv.reader(io.StringIO(text.splitlines()[0])))
    if len(names) == 1:
        for sep, what in ((";", "semicolons"), ("\t", "tabs"), ("|", "vertical bars")):
            if sep in names[0]:
                return f"columns separated by {what}, not commas; save it as comma-separated CSV"
    stripped = [n.strip() for n in names]
    blank = [i + 1 for i, n in enumerate(stripped) if not n]
    if blank:
        return f"column {blank[0]} has no name in the header"
    seen: dict[str, int] = {}
    for i, n in enumerate(stripped):
        if n in seen:
            return f"column {n!r} appears twice in the header (columns {seen[n] + 1} and {i + 1})"
        seen[n] = i
    return None


def _read_table(path: Path, file: str, problems: list, **kwargs) -> pd.DataFrame | None:
    """A CSV or Parquet file as a DataFrame, or None with one problem saying what is wrong."""
    try:
        if path.suffix == ".parquet":
            try:
                return pd.read_parquet(path)
            except OSError:
                raise
            except Exception as e:  # pyarrow's errors for truncated or foreign files
                problems.append(Problem(file, None, None, f"not a readable Parquet file (truncated?): {e}"))
                return None
        what = _header_problem(path)
        if what is None:
            df = pd.read_csv(path, encoding="utf-8-sig", **kwargs)
            df.columns = [str(c).strip() for c in df.columns]
            return df
    except FileNotFoundError:
        what = "cannot read: a link to a missing file" if path.is_symlink() else "cannot read: file not found"
    except (OSError, UnicodeDecodeError) as e:
        what = f"cannot read: {e.strerror if isinstance(e, OSError) and e.strerror else e}"
    except pd.errors.ParserError as e:
        what = f"not a valid CSV file: {str(e).strip()}"
    problems.append(Problem(file, None, None, what))
    return None


_NUMBER = re.compile(r"[-+]?\d+(?:\.\d*)?(?:e[-+]?\d+)?")


def _collapsed(problems: list[Problem], at_least: int = 3) -> list[Problem]:
    """One rule broken in many time series (a column missing everywhere, every file's rotor
    speed in another unit) as one line that counts the files, in the place of its first
    occurrence: the same column, kind and message but for its numbers (each file's value and
    row), so the cause they share is read once. The line keeps the first file's numbers."""
    key = lambda p: (p.column, _NUMBER.sub("#", p.message), p.warning)  # noqa: E731
    files: dict = {}
    for p in problems:
        if p.file.startswith("timeseries/"):
            files.setdefault(key(p), []).append(p)
    out, done = [], set()
    for p in problems:
        k = key(p)
        same = files.get(k, ()) if p.file.startswith("timeseries/") else ()
        if len(same) < at_least:
            out.append(p)
        elif k not in done:
            done.add(k)
            rows = {q.row for q in same}
            out.append(Problem(f"{len(same)} time series ({p.file}, …)", p.column, p.row if len(rows) == 1 else None,
                               f"{p.message} — the same in each of the {len(same)}: look for the one cause they share "
                               "(the column's unit or mapping, campaign.toml), not a fault of each file", p.warning))
    return out
