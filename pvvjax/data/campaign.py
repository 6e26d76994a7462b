"""Flight-test campaigns (data-contract §1): validation, loading, writing.

`validate_campaign` reads a campaign folder and reports every problem at once, each naming
the file, the column and the first bad row. `load_campaign` returns a `Campaign` only for
a campaign with no problems, with channels in canonical units, per-counter constants
broadcast into the time series, and rotor azimuth integrated from rotor speed where the
record lacks it. Rows are numbered from 1 (the first data row under the CSV header).
"""

from __future__ import annotations

import dataclasses
import functools
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np
import pandas as pd

from .._arguments import path as path_argument
from .._strict import ConfigError, from_dict
from .checks import (
    RANGES,
    REQUIRED_CHANNELS,
    Problem,
    _check_length,
    _check_record,
    _check_values,
    _collapsed,
    _first_bad,
    _gappy_channels,
    _integrate_azimuth,
    _numeric,
    _read_table,
)
from .constants import UH60A, Aircraft
from .fingerprint import campaign_fingerprint, frames_fingerprint
from .plausibility import condition_consistency, plausibility, rebase_time
from .units import ColumnMap

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "Campaign",
    "CampaignError",
    "CampaignWarning",
    "MANEUVERS",
    "Problem",
    "REQUIRED_CHANNELS",
    "campaign_from_frames",
    "load_campaign",
    "validate_campaign",
    "write_campaign",
]

MANEUVERS = ("level", "climb", "descent", "turn", "roll", "pushover", "pullup", "autorotation", "flare")

COUNTER_COLUMNS = ("counter", "maneuver", "condition", "segment", "description")


class CampaignWarning(UserWarning):
    """A suspicious but possible value in a campaign (the campaign is loaded)."""


class CampaignError(ValueError):
    """A campaign folder with problems; `.problems` lists them all (its errors)."""

    def __init__(self, problems: list[Problem], source: str = ""):
        self.problems = [p for p in problems if not p.warning]
        lines = "\n".join(f"  - {p}" for p in self.problems)
        where = f"campaign {source}" if source else "campaign"
        super().__init__(f"{len(self.problems)} problem(s) in {where}:\n{lines}")


@dataclass(frozen=True)
class Campaign:
    """A validated flight-test campaign in canonical units.

    Attributes:
        counters: one row per counter, indexed by `counter` (str), with `maneuver`,
            `condition`, `segment`, `description` and any per-counter constants.
        records: counter -> time series (`time_s`, `az_g`, `azimuth_deg`, every required
            channel with constants broadcast, and any extra columns passed through).
        aircraft: rotor constants (UH-60A unless `campaign.toml` overrides them).
        source: where the campaign was read from.
        provenance: the `[provenance]` table of `campaign.toml`, if any.
        fingerprint: content hash of the campaign (of its folder's files where it was read
            from one, else of its tables): results record it, so that a changed campaign is
            never taken for this one.
    """

    counters: pd.DataFrame
    records: Mapping[str, pd.DataFrame]
    aircraft: Aircraft = Aircraft()
    source: str = ""
    provenance: dict = field(default_factory=dict)
    folder_fingerprint: str = field(default="", repr=False)

    @functools.cached_property
    def fingerprint(self) -> str:
        return self.folder_fingerprint or frames_fingerprint(self.counters, self.records)

    def __len__(self) -> int:
        return len(self.counters)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.counters.index)

    def conditions(self) -> dict[str, list[str]]:
        """Condition -> its counters in segment order."""
        c = self.counters.sort_values(["condition", "segment"], kind="stable")
        return {k: list(g.index) for k, g in c.groupby("condition", sort=False)}

    def numeric_channels(self) -> tuple[str, ...]:
        """Numeric channels present in every record (candidates for discovery)."""
        sets = [
            {c for c in r.columns if pd.api.types.is_numeric_dtype(r[c])} for r in self.records.values()
        ]
        common = set.intersection(*sets) if sets else set()
        first = next(iter(self.records.values())).columns if self.records else []
        return tuple(c for c in first if c in common)

    def subset(self, counters) -> "Campaign":
        counters = list(counters)
        return dataclasses.replace(
            self, counters=self.counters.loc[counters], records={c: self.records[c] for c in counters},
            folder_fingerprint="",
        )


# --------------------------------------------------------------------------- reading


def _apply_mapping(df: pd.DataFrame, mapping: Mapping[str, ColumnMap], file: str, problems: list) -> pd.DataFrame:
    """Rename foreign columns to canonical names and convert their units."""
    present = [src for src in mapping if src in df.columns]
    if not present:
        return df
    df = df.copy()
    for src in present:
        m = mapping[src]
        if m.to in df.columns and m.to != src:
            problems.append(Problem(file, src, None, f"maps to {m.to!r}, which the file also has"))
            continue
        values = pd.to_numeric(df[src], errors="coerce") if m.factor() != 1.0 or m.offset else df[src]
        if m.factor() != 1.0 or m.offset:
            values = values * m.factor() + m.offset
        df = df.drop(columns=src)
        df[m.to] = values
    return df


def _read_campaign_toml(folder: Path, problems: list) -> tuple[Aircraft, dict]:
    path = folder / "campaign.toml"
    if not path.exists():
        return Aircraft(), {}
    if path.is_dir():
        problems.append(Problem("campaign.toml", None, None, "a folder, not the campaign's TOML file of aircraft "
                                                             "constants and provenance"))
        return Aircraft(), {}
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        problems.append(Problem("campaign.toml", None, None, f"not valid TOML: {e}"))
        return Aircraft(), {}
    unknown = set(data) - {"aircraft", "provenance"}
    for key in sorted(unknown):
        problems.append(Problem("campaign.toml", key, None, "unknown key; allowed: aircraft, provenance"))
    aircraft = Aircraft()
    if "aircraft" in data:
        try:
            aircraft = from_dict(_AircraftTable, data["aircraft"], where="aircraft").to_aircraft()
        except ConfigError as e:
            problems.append(Problem("campaign.toml", None, None, str(e)))
    return aircraft, dict(data.get("provenance", {}))


@dataclass(frozen=True)
class _AircraftTable:
    rotor_radius_ft: float = UH60A.rotor_radius_ft
    blades: int = UH60A.blades
    nominal_rpm: float = UH60A.nominal_rpm
    chord_ft: float = UH60A.chord_ft
    solidity: float = UH60A.solidity
    rho0_slug_ft3: float = UH60A.rho0_slug_ft3
    g_ft_s2: float = UH60A.g_ft_s2

    def __post_init__(self):
        for f in dataclasses.fields(self):
            if not getattr(self, f.name) > 0:
                raise ValueError(f"aircraft.{f.name} must be > 0, got {getattr(self, f.name)}")

    def to_aircraft(self) -> Aircraft:
        return Aircraft(**dataclasses.asdict(self))


def _read_counters(folder: Path, problems: list) -> pd.DataFrame | None:
    path = folder / "counters.csv"
    if not path.exists():
        problems.append(Problem("counters.csv", None, None, "file missing"))
        return None
    df = _read_table(path, "counters.csv", problems, dtype={"counter": str, "condition": str})
    if df is not None and df.empty:
        problems.append(Problem("counters.csv", None, None, "no counters: the file has a header and no rows"))
        return None
    return df


def _check_counters(df: pd.DataFrame, mapping, problems: list) -> pd.DataFrame | None:
    df = _apply_mapping(df, mapping, "counters.csv", problems)
    for col in ("counter", "maneuver"):
        if col not in df.columns:
            problems.append(Problem("counters.csv", col, None, "required column missing"))
    if "counter" not in df.columns:
        return None
    df["counter"] = df["counter"].astype(str).str.strip()
    dup = df["counter"].duplicated()
    if dup.any():
        row = _first_bad(dup.to_numpy())
        problems.append(Problem("counters.csv", "counter", row, f"duplicate counter {df['counter'].iloc[row - 1]!r}"))
    if "maneuver" in df.columns:
        m = df["maneuver"].astype(str).str.strip().str.lower()
        bad = ~m.isin(MANEUVERS).to_numpy()
        row = _first_bad(bad)
        if row is not None:
            problems.append(Problem(
                "counters.csv", "maneuver", row,
                f"unknown maneuver {df['maneuver'].iloc[row - 1]!r}; allowed: {', '.join(MANEUVERS)}",
            ))
        df["maneuver"] = m
    if "condition" not in df.columns:
        df["condition"] = df["counter"]
    df["condition"] = df["condition"].fillna(df["counter"]).astype(str)
    if "segment" in df.columns:
        seg = _numeric(df["segment"])
        bad = ~np.isfinite(seg) | (seg < 1) | (seg != np.round(seg))
        row = _first_bad(bad)
        if row is not None:
            problems.append(Problem("counters.csv", "segment", row,
                                    f"segment must be an integer >= 1, got {df['segment'].iloc[row - 1]}"))
            seg = np.where(bad, 1, seg)
        df["segment"] = seg.astype(int)
    else:
        df["segment"] = 1
    if "description" not in df.columns:
        df["description"] = ""
    if "maneuver" in df.columns and not dup.any():
        problems.extend(condition_consistency(df))
    constants = [c for c in df.columns if c not in COUNTER_COLUMNS]
    first = len(problems)
    _check_values(df, [c for c in constants if c in RANGES or c in REQUIRED_CHANNELS], "counters.csv", problems)
    for i in range(first, len(problems)):  # a value's row, and whose it is
        p = problems[i]
        if p.row is not None and 1 <= p.row <= len(df):
            problems[i] = dataclasses.replace(p, message=f"counter {df['counter'].iloc[p.row - 1]!r}: {p.message}")
    return df


def _check_mapping(mapping: Mapping[str, ColumnMap], counter_columns, records: Mapping[str, pd.DataFrame],
                   problems: list) -> None:
    """A mapped column that no file has (a typo, or another campaign's name): one problem
    listing the columns that are there."""
    present = set(counter_columns).union(*(df.columns for df in records.values()))
    for src, m in mapping.items():
        if src not in present:
            there = ", ".join(sorted(str(c) for c in present))
            problems.append(Problem("campaign.columns", src, None,
                                    f"maps to {m.to!r} but no file has a column {src!r}; columns there: {there}"))


def _timeseries_files(folder: Path, problems: list) -> dict[str, Path]:
    ts = folder / "timeseries"
    if not ts.is_dir():
        problems.append(Problem("timeseries/", None, None, "a file, not the folder of the records" if ts.exists()
                                else "folder missing"))
        return {}
    files: dict[str, Path] = {}
    for p in sorted(ts.iterdir()):
        if p.suffix not in (".csv", ".parquet"):
            if p.suffix.lower() in (".csv", ".parquet"):
                problems.append(Problem(f"timeseries/{p.name}", None, None, f"extension {p.suffix!r} is not read: "
                                        f"name the file {p.stem}{p.suffix.lower()} (lower case)"))
            continue
        if p.stem in files:
            problems.append(Problem(f"timeseries/{p.name}", None, None,
                                    f"counter {p.stem!r} has both a CSV and a Parquet file"))
            continue
        files[p.stem] = p
    return files


def _read(folder, mapping, window_revs, harmonic, progress=None) -> tuple[Campaign | None, list[Problem]]:
    folder = Path(folder)
    problems: list[Problem] = []
    if not folder.is_dir():
        return None, [Problem(str(folder), None, None, "campaign folder not found")]
    aircraft, provenance = _read_campaign_toml(folder, problems)
    counters = _read_counters(folder, problems)
    files = _timeseries_files(folder, problems)
    if counters is None:
        return None, problems
    columns = set(counters.columns)
    counters = _check_counters(counters, mapping or {}, problems)
    if counters is None:
        return None, problems
    raw: dict[str, pd.DataFrame] = {}
    items = files.items() if progress is None else progress(files.items(), total=len(files))
    for name, p in items:  # an unreadable file is reported; the rest are still checked
        df = _read_table(p, f"timeseries/{p.name}", problems)
        if df is not None:
            raw[name] = df
    _check_mapping(mapping or {}, columns, raw, problems)
    fnames = {name: f"timeseries/{p.name}" for name, p in files.items()}
    campaign = _assemble(counters, raw, fnames, mapping, (window_revs, harmonic), problems, aircraft, provenance,
                         str(folder))
    return campaign, _collapsed(problems)


def _assemble(counters: pd.DataFrame, raw: Mapping[str, pd.DataFrame], fnames: Mapping[str, str], mapping,
              analysis: tuple, problems: list, aircraft: Aircraft, provenance: dict, source: str) -> Campaign | None:
    """Check every record against its counter row and build the campaign (None on errors).
    `analysis`: (window_revs, harmonic or None for the aircraft's blade count)."""
    window_revs, harmonic = analysis
    names = list(dict.fromkeys(counters["counter"]))
    for i, name in enumerate(counters["counter"]):
        if name not in fnames:
            problems.append(Problem("counters.csv", "counter", i + 1,
                                    f"counter {name!r} has no file timeseries/{name}.csv or .parquet"))
    for name, f in fnames.items():
        if name not in names:
            problems.append(Problem(f, None, None, f"no counter {name!r} in counters.csv"))
    constant_cols = [c for c in counters.columns if c not in COUNTER_COLUMNS]
    records: dict[str, pd.DataFrame] = {}
    counters_ok = not any(p.file == "counters.csv" and not p.warning for p in problems)
    by_name = counters.drop_duplicates("counter").set_index("counter")
    for name in names:
        if name not in raw:
            continue
        file = fnames[name]
        df = _apply_mapping(raw[name], mapping or {}, file, problems)
        row = by_name.loc[name]
        consts = {c: _constant(c, row[c]) for c in constant_cols if pd.notna(row[c])}
        if not _check_record(df, file, consts, problems):
            continue
        df = df.drop(columns=_gappy_channels(df, file, problems))
        df, found = rebase_time(df, file)
        problems.extend(found)
        if any(not p.warning for p in found):
            continue
        for c, v in consts.items():
            df[c] = float(v) if isinstance(v, (int, float, np.number)) else v
        if counters_ok:  # plausibility of values that passed their checks (counters' constants too)
            found = plausibility(df, file, aircraft, harmonic or aircraft.blades, str(row.get("maneuver", "")))
            problems.extend(found)
            if any(not p.warning for p in found):
                continue
        if not _check_length(df, file, window_revs, problems):
            continue
        if "azimuth_deg" not in df.columns:
            df["azimuth_deg"] = _integrate_azimuth(_numeric(df["time_s"]), _numeric(df["rotor_rpm"]))
        for c in df.columns:
            if c in REQUIRED_CHANNELS or c == "azimuth_deg":
                df[c] = df[c].astype(np.float64)
        records[name] = df.reset_index(drop=True)
    if any(not p.warning for p in problems):
        return None
    table = by_name.copy()
    table.index.name = "counter"
    return Campaign(table, records, aircraft, source, provenance)


def _constant(column: str, value):
    """A counters-table value as a record's constant: a channel's value as a number (NaN
    where it is not one: `counters.csv`'s own check has reported it), anything else as is."""
    if column in REQUIRED_CHANNELS or column in RANGES:
        return pd.to_numeric(pd.Series([value]), errors="coerce").iloc[0]
    return value


def campaign_from_frames(counters: pd.DataFrame, records: Mapping[str, pd.DataFrame], *,
                         aircraft: Aircraft = Aircraft(), mapping: Mapping[str, ColumnMap] | None = None,
                         window_revs: float = 8.0, harmonic: int | None = None,
                         source: str = "<memory>") -> Campaign:
    """Build a campaign from in-memory tables with the same checks as `load_campaign`.

    Raises:
        CampaignError: listing every problem.
    """
    problems: list[Problem] = []
    _check_mapping(mapping or {}, counters.columns, records, problems)
    counters = _check_counters(counters.copy(), mapping or {}, problems)
    campaign = None
    if counters is not None:
        fnames = {name: f"timeseries/{name}" for name in records}
        campaign = _assemble(counters, records, fnames, mapping, (window_revs, harmonic), problems, aircraft, {},
                             source)
    return _checked(campaign, problems, source)


def _checked(campaign, problems, source: str = ""):
    """The campaign, its warnings issued as `CampaignWarning`s; a `CampaignError` (naming
    the folder or source) on errors."""
    if any(not p.warning for p in problems):
        raise CampaignError(problems, source)
    for p in problems:
        warnings.warn(str(dataclasses.replace(p, warning=False)), CampaignWarning, stacklevel=3)
    return campaign


def validate_campaign(folder, mapping: Mapping[str, ColumnMap] | None = None, window_revs: float = 8.0,
                      progress=None, harmonic: int | None = None) -> list[Problem]:
    """Check a campaign folder against data-contract §1.

    Args:
        folder: the campaign folder.
        mapping: foreign column name -> `ColumnMap` (from the experiment config).
        window_revs: analysis window length; a record shorter than one window is refused.
        progress: optional wrapper `progress(iterable, total=n)` (e.g. a tqdm factory).
        harmonic: harmonic order analysed, per rev (default: the aircraft's blade count);
            a record sampled too slowly to resolve it is refused.

    Returns:
        Every problem found, errors and warnings (`Problem.warning`); a campaign is valid when
        none is an error.
    """
    return _read(folder, mapping, window_revs, harmonic, progress)[1]


def load_campaign(folder, mapping: Mapping[str, ColumnMap] | None = None, window_revs: float = 8.0,
                  progress=None, harmonic: int | None = None) -> Campaign:
    """Load a campaign folder (arguments as `validate_campaign`).

    Raises:
        CampaignError: listing every error. Warnings are issued as `CampaignWarning`s.
    """
    path_argument("load_campaign", "folder", folder)
    campaign = _checked(*_read(folder, mapping, window_revs, harmonic, progress), str(folder))
    return dataclasses.replace(campaign, folder_fingerprint=campaign_fingerprint(folder))  # not for validation


# --------------------------------------------------------------------------- writing


def write_campaign(folder, counters: pd.DataFrame, records: Mapping[str, pd.DataFrame], *,
                   aircraft: Aircraft | None = None, provenance: dict | None = None,
                   fmt: str = "parquet") -> Path:
    """Write a campaign folder in the data-contract format.

    Args:
        folder: output folder (created).
        counters: one row per counter with at least `counter` and `maneuver`.
        records: counter -> time-series DataFrame.
        aircraft: constants for `campaign.toml` (omitted: UH-60A defaults apply).
        provenance: free table recorded in `campaign.toml`.
        fmt: "parquet" or "csv" for the time series.
    """
    folder = Path(folder)
    (folder / "timeseries").mkdir(parents=True, exist_ok=True)
    counters.to_csv(folder / "counters.csv", index=False)
    for name, df in records.items():
        if fmt == "parquet":
            df.to_parquet(folder / "timeseries" / f"{name}.parquet", index=False)
        else:
            df.to_csv(folder / "timeseries" / f"{name}.csv", index=False, float_format="%.10g")
    table = {}
    if aircraft is not None:
        table["aircraft"] = dict(aircraft._asdict())
    if provenance:
        table["provenance"] = dict(provenance)
    if table:
        import tomli_w

        (folder / "campaign.toml").write_text(tomli_w.dumps(table))
    return folder

