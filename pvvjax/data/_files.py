"""Reading a campaign's files: one clear problem for a file that is not what it claims
(empty, another separator, duplicated or blank headers, another encoding, unreadable,
truncated), and one line for a problem that many time series share."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pandas as pd

from .checks import Problem

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


def _collapsed(problems: list[Problem], at_least: int = 3) -> list[Problem]:
    """The same whole-file problem in many time series (a column missing everywhere) as one
    line that counts the files, in the place of its first occurrence."""
    key = lambda p: (p.column, p.message, p.warning)  # noqa: E731
    files: dict = {}
    for p in problems:
        if p.row is None and p.file.startswith("timeseries/"):
            files.setdefault(key(p), []).append(p.file)
    out, done = [], set()
    for p in problems:
        k = key(p)
        many = p.row is None and p.file.startswith("timeseries/") and len(files.get(k, ())) >= at_least
        if not many:
            out.append(p)
        elif k not in done:
            done.add(k)
            out.append(Problem(f"{len(files[k])} time series ({p.file}, …)", p.column, None, p.message, p.warning))
    return out
