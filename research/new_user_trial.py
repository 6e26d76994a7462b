"""A new user's trial: many kinds of defect, each on its own copy of a small campaign, through
the commands a new user runs (`pvvjax validate`, then `pvvjax build-db`, or the command the
kind is about), each outcome judged against what the data contract and the issue promise.

Verdicts (one per kind):
    correct    good input, the command ran and the result is the expected one;
    clear      a refusal or a warning that names what the kind says it must (file or counter,
               column or key, and the row where one sample is at fault);
    unclear    a refusal or warning that misses one of those names, a cause said once per file
               where it is one cause, or good input refused;
    silent     a result written without a word where the input was bad, or another record's
               numbers moved by one record's defect;
    traceback  a Python traceback or an unexpected exit status.
Files touched: any file under the kind's folder changed, removed or added outside the output
folder the command owns (a user's folder included).

    python research/new_user_trial.py [--campaign DIR] [--work DIR] [--jobs 2] [--only NAME ...]
        [--docs docs/new-user-trial.md]

The campaign defaults to the small synthetic campaign (the test suite's), cut to twelve counters
of every maneuver kind so that each kind takes seconds.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import hashlib
import json
import os
import platform
import re
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from pvvjax.synth import SynthConfig, cached_campaign

SMALL_COUNTS = dict(level=10, climb=3, descent=3, turn=3, roll=3, pushover=2, pullup=3, autorotation=1, flare=2)
KEEP = ("T1-level-135", "T1-descent-160", "T1-climb-62", "T1-turn45-145", "11022", "11539", "11540",
        "LS15k-050", "LS15k-100", "R001", "PO001", "F001")
T = "11022"  # the record a one-record defect is put into (the paper's pull-up)
ROW = 2000  # the sample a one-sample defect is put at (0-based index of the time series)


# --------------------------------------------------------------------------- editing a campaign copy

def ts_path(camp: Path, counter: str) -> Path:
    for ext in (".parquet", ".csv"):
        if (camp / "timeseries" / f"{counter}{ext}").exists():
            return camp / "timeseries" / f"{counter}{ext}"
    raise FileNotFoundError(counter)


def read_ts(camp: Path, counter: str = T) -> pd.DataFrame:
    p = ts_path(camp, counter)
    return pd.read_parquet(p) if p.suffix == ".parquet" else pd.read_csv(p)


def write_ts(camp: Path, df: pd.DataFrame, counter: str = T, fmt: str | None = None) -> Path:
    old = ts_path(camp, counter)
    fmt = fmt or old.suffix[1:]
    old.unlink()
    new = camp / "timeseries" / f"{counter}.{fmt}"
    if fmt == "parquet":
        df.to_parquet(new, index=False)
    else:
        df.to_csv(new, index=False)
    return new


def edit_ts(fn: Callable[[pd.DataFrame], pd.DataFrame | None], counters=(T,), fmt: str | None = None):
    def change(camp: Path):
        for c in (KEEP if counters == "all" else counters):
            df = read_ts(camp, c)
            out = fn(df)
            write_ts(camp, df if out is None else out, c, fmt)
    return change


def at(column: str, value, row: int = ROW):
    def fn(df):
        col = df[column].to_numpy().astype(float).copy() if np.isscalar(value) else df[column].to_numpy().copy()
        col = col.astype(object) if isinstance(value, str) else col
        col[row] = value
        df[column] = col
    return fn


def scaled(column: str, factor: float = 1.0, offset: float = 0.0):
    def fn(df):
        df[column] = df[column] * factor + offset
    return fn


def dropped(*columns: str):
    return lambda df: df.drop(columns=list(columns))


def csv_text(fn: Callable[[str], str], counter: str = T):
    """Rewrites the record as CSV, then edits its text."""
    def change(camp: Path):
        path = write_ts(camp, read_ts(camp, counter), counter, "csv")
        path.write_text(fn(path.read_text()))
    return change


def csv_bytes(data: bytes, counter: str = T):
    def change(camp: Path):
        path = write_ts(camp, read_ts(camp, counter), counter, "csv")
        path.write_bytes(data)
    return change


def counters_edit(fn: Callable[[pd.DataFrame], pd.DataFrame | None]):
    def change(camp: Path):
        df = pd.read_csv(camp / "counters.csv", dtype={"counter": str})
        out = fn(df)
        (df if out is None else out).to_csv(camp / "counters.csv", index=False)
    return change


def counters_cell(counter: str, column: str, value):
    def fn(df):
        df[column] = df[column].astype(object)
        df.loc[df.counter == counter, column] = value
    return counters_edit(fn)


def text_edit(name: str, fn: Callable[[str], str]):
    def change(camp: Path):
        p = camp / name
        p.write_text(fn(p.read_text() if p.exists() else ""))
    return change


def aircraft(text: str):
    return text_edit("campaign.toml", lambda s: s + "\n[aircraft]\n" + text + "\n")


def both(*changes):
    def change(camp: Path):
        for c in changes:
            c(camp)
    return change


def decimate(step: int):
    return lambda df: df.iloc[::step].reset_index(drop=True)


def tiled(n: int):
    def fn(df):
        dt = float(df.time_s.iloc[1] - df.time_s.iloc[0])
        turns = np.unwrap(np.deg2rad(df.azimuth_deg.to_numpy()))
        span = turns[-1] - turns[0] + (turns[1] - turns[0])
        out = pd.concat([df] * n, ignore_index=True)
        out["time_s"] = np.arange(len(out)) * dt
        out["azimuth_deg"] = np.rad2deg(np.concatenate([turns + i * span for i in range(n)])) % 360.0
        return out
    return fn


def jitter(fraction: float):
    def fn(df):
        dt = float(df.time_s.iloc[1] - df.time_s.iloc[0])
        rng = np.random.default_rng(0)
        df["time_s"] = df.time_s + rng.uniform(-fraction / 2, fraction / 2, len(df)) * dt
    return fn


# --------------------------------------------------------------------------- the kinds

@dataclasses.dataclass(frozen=True)
class Kind:
    """One kind of input a new user might bring.

    expect: "refuse" (an error naming `names`), "flag" (an error or a warning naming them),
        "accept" (runs; `same`: the databases equal the clean campaign's), "isolate" (a defect
        in one record: refused or warned by name, or run with every other condition's row
        bitwise unchanged), "either" (accepted as the clean campaign, or refused by name).
    names: what a clear message names (case-insensitive); "ROW" stands for the faulty row.
    once: the cause is shared by every file; a clear message says it in at most two lines.
    command: the argv after `pvvjax` (placeholders CAMP, OUT, ROOT); default validate + build-db.
    """

    name: str
    change: Callable[[Path], None]
    expect: str
    names: tuple[str, ...] = ()
    same: bool = True
    once: bool = False
    commands: tuple[tuple[str, ...], ...] = (("validate", "--campaign", "CAMP"),
                                             ("build-db", "--campaign", "CAMP", "--out", "OUT"))
    setup: Callable[[Path], None] | None = None  # prepares ROOT (configs, folders) beside the campaign


def nothing(camp):
    return None


def kinds() -> list[Kind]:
    k: list[Kind] = []

    def add(name, change, expect, names=(), **kw):
        k.append(Kind(name, change, expect, tuple(names), **kw))

    # one sample of one record
    for col in ("az_g", "time_s", "azimuth_deg", "rotor_rpm", "airspeed_kt", "collective_pct", "lateral_pct",
                "longitudinal_pct", "pitch_rate_dps", "roll_angle_deg", "climb_rate_fpm"):
        add(f"NaN in {col} at one sample", edit_ts(at(col, np.nan)), "refuse", (T, col, "ROW"))
    for col in ("az_g", "airspeed_kt", "rotor_rpm"):
        add(f"+inf in {col} at one sample", edit_ts(at(col, np.inf)), "refuse", (T, col, "ROW"))
    add("text 'n/a' in az_g at one sample (CSV)", edit_ts(at("az_g", "n/a"), fmt="csv"), "refuse", (T, "az_g", "ROW"))
    add("empty cell in airspeed_kt at one sample (CSV)", edit_ts(at("airspeed_kt", ""), fmt="csv"), "refuse",
        (T, "airspeed_kt", "ROW"))
    add("az_g spike of 60 g at one sample", edit_ts(at("az_g", 60.0)), "flag", (T, "az_g"))
    add("azimuth reads 0 at one sample (logger glitch)", edit_ts(at("azimuth_deg", 0.0)), "refuse",
        (T, "azimuth_deg", "ROW"))
    add("azimuth repeats the previous sample",
        edit_ts(lambda df: at("azimuth_deg", float(df.azimuth_deg[ROW - 1]))(df)), "refuse", (T, "azimuth_deg", "ROW"))
    add("time stands still at one sample", edit_ts(lambda df: at("time_s", float(df.time_s[ROW - 1]))(df)),
        "refuse", (T, "time_s", "ROW"))
    add("time steps back at one sample", edit_ts(lambda df: at("time_s", float(df.time_s[ROW - 2]))(df)),
        "refuse", (T, "time_s", "ROW"))
    add("rotor_rpm 0 at one sample", edit_ts(at("rotor_rpm", 0.0)), "refuse", (T, "rotor_rpm", "ROW"))
    add("rotor_rpm negative at one sample", edit_ts(at("rotor_rpm", -255.0)), "refuse", (T, "rotor_rpm", "ROW"))
    add("collective 150 % at one sample", edit_ts(at("collective_pct", 150.0)), "refuse", (T, "collective_pct", "ROW"))
    add("lateral cyclic -5 % at one sample", edit_ts(at("lateral_pct", -5.0)), "refuse", (T, "lateral_pct", "ROW"))
    add("bank angle 120 deg at one sample", edit_ts(at("roll_angle_deg", 120.0)), "refuse",
        (T, "roll_angle_deg", "ROW"))
    add("a whole row duplicated", edit_ts(lambda df: pd.concat([df.iloc[:ROW + 1], df.iloc[ROW:]],
                                                               ignore_index=True)), "refuse", (T, "time_s", "ROW"))
    add("100 samples missing mid-record", edit_ts(lambda df: df.drop(index=range(ROW, ROW + 100)).reset_index(
        drop=True)), "refuse", (T, "time_s"))
    add("NaN in optional shaft_power_hp at one sample", edit_ts(at("shaft_power_hp", np.nan)), "flag",
        (T, "shaft_power_hp"))
    add("NaN in optional nz_g at one sample", edit_ts(at("nz_g", np.nan)), "flag", (T, "nz_g"))

    # one record, whole channel
    add("az_g in m/s^2 in one record", edit_ts(scaled("az_g", 9.80665)), "refuse", (T, "az_g"))
    add("az_g in m/s^2 in every record", edit_ts(scaled("az_g", 9.80665), "all"), "refuse", ("az_g",), once=True)
    add("time_s in milliseconds in one record", edit_ts(scaled("time_s", 1000.0)), "refuse", (T, "time_s"))
    add("time_s in milliseconds in every record", edit_ts(scaled("time_s", 1000.0), "all"), "refuse",
        ("time_s",), once=True)
    add("time_s starts at 1000 s in one record", edit_ts(scaled("time_s", 1.0, 1000.0)), "isolate", (T,))
    add("time jitter of 3 % of a step", edit_ts(jitter(0.03)), "refuse", (T, "time_s"))
    add("time jitter of 0.2 % of a step", edit_ts(jitter(0.002)), "isolate", (T,))
    add("azimuth in radians in one record", edit_ts(lambda df: scaled("azimuth_deg", np.pi / 180.0)(df)), "refuse",
        (T, "azimuth_deg"))
    add("azimuth decreasing (rotor turning the other way)",
        edit_ts(lambda df: scaled("azimuth_deg", -1.0, 360.0)(df)), "flag", (T, "azimuth_deg"))
    add("azimuth cumulative, not wrapped", edit_ts(lambda df: df.assign(azimuth_deg=np.rad2deg(np.unwrap(
        np.deg2rad(df.azimuth_deg.to_numpy()))))), "either", (T, "azimuth_deg"))
    add("azimuth wrapped to -180..180", edit_ts(lambda df: df.assign(azimuth_deg=(df.azimuth_deg + 180.0) % 360.0
                                                                     - 180.0)), "accept")
    add("azimuth of another reference blade (+90 deg)", edit_ts(lambda df: df.assign(
        azimuth_deg=(df.azimuth_deg + 90.0) % 360.0)), "accept")
    add("azimuth absent in one record (integrated from rpm)", edit_ts(dropped("azimuth_deg")), "isolate", (T,))
    add("azimuth absent in every record", edit_ts(dropped("azimuth_deg"), "all"), "either", ("azimuth_deg",))
    add("rotor_rpm in % of nominal in one record", edit_ts(scaled("rotor_rpm", 100.0 / 258.0)), "refuse",
        (T, "rotor_rpm", "%"))
    add("rotor_rpm in % of nominal in every record", edit_ts(scaled("rotor_rpm", 100.0 / 258.0), "all"), "refuse",
        ("rotor_rpm", "%"), once=True)
    add("rotor_rpm in rad/s in one record", edit_ts(scaled("rotor_rpm", 2 * np.pi / 60.0)), "refuse",
        (T, "rotor_rpm", "rad/s"))
    add("rotor_rpm in Hz (rev/s) in one record", edit_ts(scaled("rotor_rpm", 1.0 / 60.0)), "refuse",
        (T, "rotor_rpm"))
    add("airspeed 2000 kt in one record", edit_ts(scaled("airspeed_kt", 0.0, 2000.0)), "refuse", (T, "airspeed_kt"))
    add("collective as a fraction 0-1 in every record", edit_ts(scaled("collective_pct", 0.01), "all"), "flag",
        ("collective_pct",), once=True)
    add("az_g with gravity removed (vibration only) in one record", edit_ts(scaled("az_g", 1.0, -1.0)), "flag",
        (T, "az_g"))
    add("az_g constant (sensor dead) in one record", edit_ts(scaled("az_g", 0.0, 1.0)), "flag", (T, "az_g"))
    add("az_g sign flipped (-1 g) in one record", edit_ts(scaled("az_g", -1.0)), "flag", (T, "az_g"))
    add("airspeed_kt text column ('fast') in one record (CSV)", edit_ts(lambda df: df.assign(airspeed_kt="fast"),
                                                                       fmt="csv"), "refuse", (T, "airspeed_kt"))
    add("nz_g missing in one record", edit_ts(dropped("nz_g")), "isolate", (T,))
    add("shaft_power_hp missing in one record", edit_ts(dropped("shaft_power_hp")), "isolate", (T,))
    add("extra unknown column (oat_c)", edit_ts(lambda df: df.assign(oat_c=15.0)), "accept")
    add("columns in another order", edit_ts(lambda df: df[df.columns[::-1]]), "accept")
    add("az_g column missing in one record", edit_ts(dropped("az_g")), "refuse", (T, "az_g"))
    add("rotor_rpm column missing in one record", edit_ts(dropped("rotor_rpm")), "refuse", (T, "rotor_rpm"))
    add("time_s column missing in one record", edit_ts(dropped("time_s")), "refuse", (T, "time_s"))
    add("collective_pct missing in every record", edit_ts(dropped("collective_pct"), "all"), "refuse",
        ("collective_pct",), once=True)
    add("column named AZ_G (upper case)", edit_ts(lambda df: df.rename(columns={"az_g": "AZ_G"})), "refuse",
        (T, "az_g"))
    add("column named ' az_g' (leading space, CSV)", edit_ts(lambda df: df.rename(columns={"az_g": " az_g"}),
                                                             fmt="csv"), "either", (T, "az_g"))
    add("a channel both in counters.csv and the time series", edit_ts(lambda df: df.assign(gross_weight_lb=16000.0)),
        "refuse", (T, "gross_weight_lb"))
    add("record shorter than one window (50 samples)", edit_ts(lambda df: df.iloc[:50]), "refuse", (T,))
    add("record decimated to 8 samples per revolution", edit_ts(decimate(8)), "refuse", (T,))
    add("record at twice the sampling rate (every other sample dropped elsewhere)",
        edit_ts(decimate(2), counters=("T1-level-135",)), "isolate", ("T1-level-135",))
    add("one record ten times longer", edit_ts(tiled(10)), "isolate", (T,))
    add("parquet column az_g stored as text", edit_ts(lambda df: df.assign(az_g=df.az_g.map("{:.6f}".format))),
        "either", (T, "az_g"))
    add("parquet in float16", edit_ts(lambda df: df.astype({c: "float16" for c in df.columns if c != "time_s"})),
        "isolate", (T,))
    add("parquet with an index column", lambda camp: read_ts(camp).set_index("time_s", drop=False).to_parquet(
        ts_path(camp, T)), "accept")

    # the file itself
    add("empty time-series file (0 bytes)", csv_bytes(b""), "refuse", (T,))
    add("time-series CSV with the header only", csv_text(lambda s: s.splitlines()[0] + "\n"), "refuse", (T,))
    add("last CSV line cut mid-row", csv_text(lambda s: s[: s.rstrip().rfind(",")]), "refuse", (T,))
    add("binary garbage in a .parquet", lambda camp: ts_path(camp, T).write_bytes(os.urandom(4096)), "refuse", (T,))
    add("CSV separated by semicolons", csv_text(lambda s: s.replace(",", ";")), "refuse", (T,))
    add("CSV with decimal commas and semicolons", csv_text(lambda s: s.replace(",", ";").replace(".", ",")),
        "refuse", (T,))
    add("CSV with a byte-order mark", csv_text(lambda s: "\ufeff" + s), "accept")
    add("CSV with CRLF line ends", csv_text(lambda s: s.replace("\n", "\r\n")), "accept")
    add("CSV with a units row under the header", csv_text(
        lambda s: s.split("\n", 1)[0] + "\n" + ",".join(["unit"] * s.split("\n", 1)[0].count(",")) + ",x\n"
        + s.split("\n", 1)[1]), "refuse", (T,))
    add("CSV with two comment lines on top", csv_text(lambda s: "# logger v2\n# exported\n" + s), "refuse", (T,))
    add("CSV with a blank line in the middle", csv_text(lambda s: "\n".join(
        (lambda lines: lines[:ROW] + [""] + lines[ROW:])(s.split("\n")))), "either", (T,))
    add("both 11022.csv and 11022.parquet", lambda camp: read_ts(camp).to_csv(camp / "timeseries" / f"{T}.csv",
                                                                              index=False), "refuse", (T,))
    add("file named 11022.CSV (upper-case extension)", lambda camp: (
        read_ts(camp).to_csv(camp / "timeseries" / f"{T}.CSV", index=False), ts_path(camp, T).unlink()), "either",
        (T,))
    add("stray notes.txt in timeseries/", lambda camp: (camp / "timeseries" / "notes.txt").write_text("ok\n"),
        "either", ("notes.txt",))
    add("stray .DS_Store in timeseries/", lambda camp: (camp / "timeseries" / ".DS_Store").write_bytes(b"\0\1"),
        "accept")
    add("time series in a subfolder timeseries/day1/", lambda camp: (
        (camp / "timeseries" / "day1").mkdir(), shutil.move(ts_path(camp, T), camp / "timeseries" / "day1")),
        "refuse", (T,))
    add("timeseries/ folder missing", lambda camp: shutil.rmtree(camp / "timeseries"), "refuse", ("timeseries",))
    add("a time-series file for no counter (extra.parquet)", lambda camp: shutil.copy(
        ts_path(camp, "R001"), camp / "timeseries" / "extra.parquet"), "refuse", ("extra",))

    # counters.csv
    add("counters.csv missing", lambda camp: (camp / "counters.csv").unlink(), "refuse", ("counters.csv",))
    add("counters.csv empty (0 bytes)", lambda camp: (camp / "counters.csv").write_text(""), "refuse",
        ("counters.csv",))
    add("counters.csv header only", text_edit("counters.csv", lambda s: s.splitlines()[0] + "\n"), "refuse",
        ("counters.csv",))
    add("a counter listed twice", counters_edit(lambda df: pd.concat([df, df[df.counter == T]])), "refuse",
        ("counters.csv", T))
    add("unknown maneuver 'hover'", counters_cell(T, "maneuver", "hover"), "refuse", ("counters.csv", "maneuver",
                                                                                        "hover"))
    add("maneuver 'Pullup' (capitalised)", counters_cell(T, "maneuver", "Pullup"), "either", ("maneuver", "Pullup"))
    add("maneuver ' pullup' (leading space)", counters_cell(T, "maneuver", " pullup"), "either", ("maneuver",))
    add("maneuver column missing", counters_edit(lambda df: df.drop(columns=["maneuver"])), "refuse",
        ("counters.csv", "maneuver"))
    add("counter column missing", counters_edit(lambda df: df.drop(columns=["counter"])), "refuse",
        ("counters.csv", "counter"))
    add("a counter with no time-series file", counters_edit(lambda df: pd.concat([df, df[df.counter == T].assign(
        counter="99999")])), "refuse", ("99999",))
    add("counter '011022' for file 11022 (leading zero)", counters_cell(T, "counter", "011022"), "refuse",
        ("011022",))
    add("counter named '../escape'", counters_cell(T, "counter", "../escape"), "refuse", ("../escape",))
    add("segment 'a'", counters_cell("11540", "segment", "a"), "refuse", ("counters.csv", "segment"))
    add("segment 0", counters_cell("11540", "segment", 0), "flag", ("segment",))
    add("two segments with the same number", counters_cell("11540", "segment", 1), "flag", ("segment",))
    add("one condition of two maneuver kinds", counters_cell("11540", "maneuver", "flare"), "flag",
        ("AR60", "maneuver"))
    add("condition left blank for one counter", counters_cell("R001", "condition", np.nan), "accept")
    add("gross_weight_lb 0", counters_cell(T, "gross_weight_lb", 0.0), "refuse", (T, "gross_weight_lb"))
    add("gross_weight_lb blank", counters_cell(T, "gross_weight_lb", np.nan), "refuse", (T, "gross_weight_lb"))
    add("gross_weight_lb 'heavy'", counters_cell(T, "gross_weight_lb", "heavy"), "refuse", (T, "gross_weight_lb"))
    add("gross_weight in kg for every counter", counters_edit(lambda df: df.assign(
        gross_weight_lb=df.gross_weight_lb * 0.4536)), "flag", ("gross_weight_lb", "kg"), once=True)
    add("gross_weight in N for every counter", counters_edit(lambda df: df.assign(
        gross_weight_lb=df.gross_weight_lb * 4.448)), "flag", ("gross_weight_lb",), once=True)
    add("density_ratio 1.5", counters_cell(T, "density_ratio", 1.5), "refuse", (T, "density_ratio"))
    add("density_ratio blank", counters_cell(T, "density_ratio", np.nan), "refuse", (T, "density_ratio"))
    add("density in kg/m^3 for every counter (1.225)", counters_edit(lambda df: df.assign(
        density_ratio=df.density_ratio * 1.225)), "flag", ("density_ratio",), once=True)
    add("counters.csv with a byte-order mark", text_edit("counters.csv", lambda s: "\ufeff" + s), "accept")
    add("counters.csv separated by semicolons", text_edit("counters.csv", lambda s: s.replace(",", ";")), "refuse",
        ("counters.csv",))
    add("description with a quoted newline", counters_cell(T, "description", "pull-up,\nsecond try"), "accept")
    add("extra column 'pilot' in counters.csv", counters_edit(lambda df: df.assign(pilot="A")), "accept")

    # campaign.toml
    add("blades = 3 on four-bladed data", aircraft("blades = 3"), "flag", ("blades", "campaign.toml"))
    add("blades = 0", aircraft("blades = 0"), "refuse", ("campaign.toml", "blades"))
    add("blades = 'four'", aircraft('blades = "four"'), "refuse", ("campaign.toml", "blades"))
    add("blades = 4.5", aircraft("blades = 4.5"), "refuse", ("campaign.toml", "blades"))
    add("rotor_radius_ft = -26.8", aircraft("rotor_radius_ft = -26.8"), "refuse", ("campaign.toml", "rotor_radius_ft"))
    add("nominal_rpm = 500 (another aircraft's)", aircraft("nominal_rpm = 500.0"), "flag", ("rotor_rpm", "nominal_rpm"))
    add("unknown aircraft key 'blade_count'", aircraft("blade_count = 4"), "refuse", ("campaign.toml", "blade_count"))
    add("unknown table [rotor]", text_edit("campaign.toml", lambda s: s + "\n[rotor]\nblades = 4\n"), "refuse",
        ("campaign.toml", "rotor"))
    add("campaign.toml not TOML", text_edit("campaign.toml", lambda s: s + "\nblades: 4\n"), "refuse",
        ("campaign.toml",))
    add("campaign.toml missing (UH-60A defaults)", lambda camp: (camp / "campaign.toml").unlink(), "accept")
    add("campaign.toml is a folder", lambda camp: ((camp / "campaign.toml").unlink(), (camp / "campaign.toml").mkdir()),
        "refuse", ("campaign.toml", "a folder"))

    # the command line, the config and the folders
    cfg = ("build-db", "--campaign", "CAMP", "--out", "OUT", "--config", "ROOT/config.toml")

    def config(text):
        return lambda root: (root / "config.toml").write_text(text)

    add("--campaign that does not exist", nothing, "refuse", ("nope",),
        commands=(("build-db", "--campaign", "ROOT/nope", "--out", "OUT"),))
    add("--campaign is a file", nothing, "refuse", ("counters.csv",),
        commands=(("build-db", "--campaign", "CAMP/counters.csv", "--out", "OUT"),))
    add("--campaign one level too deep (timeseries/)", nothing, "refuse", ("timeseries",),
        commands=(("build-db", "--campaign", "CAMP/timeseries", "--out", "OUT"),))
    add("--campaign an empty folder", nothing, "refuse", ("empty",),
        commands=(("validate", "--campaign", "ROOT/empty"),), setup=lambda root: (root / "empty").mkdir())
    add("--out is the campaign folder", nothing, "refuse", ("campaign",),
        commands=(("build-db", "--campaign", "CAMP", "--out", "CAMP"),))
    add("--out is a user's folder with a config.toml and notes", nothing, "refuse", ("mine",),
        commands=(("build-db", "--campaign", "CAMP", "--out", "ROOT/mine"),),
        setup=lambda root: ((root / "mine").mkdir(), (root / "mine" / "config.toml").write_text("name = 'x'\n"),
                            (root / "mine" / "notes.md").write_text("my notes\n")))
    add("--out is an existing file", nothing, "refuse", ("file.txt",),
        commands=(("build-db", "--campaign", "CAMP", "--out", "ROOT/file.txt"),),
        setup=lambda root: (root / "file.txt").write_text("keep me\n"))
    add("--out under an existing file", nothing, "refuse", ("file.txt",),
        commands=(("build-db", "--campaign", "CAMP", "--out", "ROOT/file.txt/out"),),
        setup=lambda root: (root / "file.txt").write_text("keep me\n"))
    add("build-db run twice into one folder", nothing, "accept",
        commands=(("build-db", "--campaign", "CAMP", "--out", "OUT"),) * 2)
    add("build-db again with other settings into the same folder", nothing, "refuse", ("out",),
        commands=(("build-db", "--campaign", "CAMP", "--out", "OUT"), cfg),
        setup=config("[analysis]\nwindow_revs = 6.0\n"))
    add("--config that does not exist", nothing, "refuse", ("nope.toml",),
        commands=(("build-db", "--campaign", "CAMP", "--out", "OUT", "--config", "ROOT/nope.toml"),))
    add("config: unknown key window_rev", nothing, "refuse", ("config.toml", "window_rev"), commands=(cfg,),
        setup=config("[analysis]\nwindow_rev = 8.0\n"))
    add("config: unknown section [analyse]", nothing, "refuse", ("config.toml", "analyse"), commands=(cfg,),
        setup=config("[analyse]\nwindow_revs = 8.0\n"))
    add("config: window_revs = -8", nothing, "refuse", ("window_revs",), commands=(cfg,),
        setup=config("[analysis]\nwindow_revs = -8.0\n"))
    add("config: window_revs = '8'", nothing, "refuse", ("window_revs",), commands=(cfg,),
        setup=config('[analysis]\nwindow_revs = "8"\n'))
    add("config: window_revs = 2000 (longer than any record)", nothing, "refuse", ("window_revs",), commands=(cfg,),
        setup=config("[analysis]\nwindow_revs = 2000.0\n"))
    add("config: harmonic = 4.5", nothing, "refuse", ("harmonic",), commands=(cfg,),
        setup=config("[analysis]\nharmonic = 4.5\n"))
    add("config: harmonic = 40 (above what the sampling resolves)", nothing, "refuse", ("harmonic",), commands=(cfg,),
        setup=config("[analysis]\nharmonic = 40\n"))
    add("config: axis = 'az'", nothing, "refuse", ("axis",), commands=(cfg,), setup=config('[analysis]\naxis = "az"\n'))
    add("config: not TOML", nothing, "refuse", ("config.toml",), commands=(cfg,),
        setup=config("[analysis]\nwindow_revs: 8\n"))
    add("config: a column mapped to an unknown channel", nothing, "refuse", ("columns", "'vertical_g' is not a"),
        commands=(cfg,),
        setup=config('[campaign.columns.az_g]\nto = "vertical_g"\nunit = "g"\n'))
    add("config: a mapping with an unknown unit", nothing, "refuse", ("furlongs",), commands=(cfg,),
        setup=config('[campaign.columns.airspeed_kt]\nto = "airspeed_kt"\nunit = "furlongs"\n'))
    add("renamed column mapped back by the config", edit_ts(lambda df: df.rename(columns={"airspeed_kt": "IAS"}),
                                                            "all"), "accept", commands=(cfg,),
        setup=config('[campaign.columns.IAS]\nto = "airspeed_kt"\n'))
    add("airspeed in m/s mapped by a unit", edit_ts(lambda df: df.assign(airspeed_kt=df.airspeed_kt * 0.514444)
                                                    .rename(columns={"airspeed_kt": "V_ms"}), "all"), "accept",
        commands=(cfg,), setup=config('[campaign.columns.V_ms]\nto = "airspeed_kt"\nunit = "m/s"\n'))
    add("replay pointed at a build-db folder", nothing, "refuse", ("build-db",),
        commands=(("build-db", "--campaign", "CAMP", "--out", "OUT"),
                  ("replay", "ROOT/replay.toml", "--campaign", "CAMP", "--out", "ROOT/replay")),
        setup=lambda root: (root / "replay.toml").write_text(f'name = "r"\n[replay]\nsweep = "{root}/out"\n'))
    add("export from a folder that holds no sweep", nothing, "refuse", ("mine",),
        commands=(("export", "ROOT/mine", "--out", "ROOT/element"),),
        setup=lambda root: (root / "mine").mkdir())
    disc = (("discover", "--campaign", "CAMP", "--out", "OUT"),)
    add("discover with nz_g missing in one record", edit_ts(dropped("nz_g")), "flag", ("nz_g", T), commands=disc)
    add("discover with one record's columns in another order", edit_ts(lambda df: df[df.columns[::-1]]), "accept",
        commands=disc)
    add("discover on a vertical axis of noise with no 4/rev", edit_ts(lambda df: df.assign(
        az_g=1.0 + 0.05 * np.random.default_rng(0).standard_normal(len(df))), "all"), "flag", ("az_g", "4/rev"),
        commands=disc)
    add("validate --config with a mapping that matches no column", nothing, "refuse", ("IAS",),
        commands=(("validate", "--campaign", "CAMP", "--config", "ROOT/config.toml"),),
        setup=config('[campaign.columns.IAS]\nto = "airspeed_kt"\n'))
    return k


# --------------------------------------------------------------------------- running and judging

def snapshot(root: Path, skip: set[Path]) -> dict[str, str]:
    out = {}
    for p in sorted(root.rglob("*")):
        if any(p == s or s in p.parents for s in skip) or not p.is_file():
            continue
        out[str(p.relative_to(root))] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def _argv(cmd, root: Path) -> list[str]:
    return [a.replace("CAMP", str(root / "campaign")).replace("OUT", str(root / "out")).replace("ROOT", str(root))
            for a in cmd]


def run_kind(kind: Kind, base: Path, work: Path, reference: dict[str, pd.DataFrame]) -> dict:
    root = work / kind.name.replace("/", "_").replace(" ", "_").replace("'", "")
    shutil.rmtree(root, ignore_errors=True)
    root.mkdir(parents=True)
    shutil.copytree(base, root / "campaign")
    kind.change(root / "campaign")
    if kind.setup:
        kind.setup(root)
    argvs = [_argv(c, root) for c in kind.commands]
    owned = {Path(a[a.index("--out") + 1]) for a in argvs if "--out" in a}
    owned = {p for p in owned if not p.exists()}
    before = snapshot(root, owned)
    runs = []
    for argv in argvs:
        p = subprocess.run([sys.executable, "-m", "pvvjax", *argv], capture_output=True, text=True, cwd=root,
                           env={**os.environ, "PYTHONWARNINGS": "default"})
        runs.append(dict(argv=argv, rc=p.returncode, text=p.stdout + p.stderr))
    after = snapshot(root, owned)
    (work / "_logs").mkdir(exist_ok=True)
    (work / "_logs" / f"{root.name}.txt").write_text(
        "\n\n".join(f"$ pvvjax {' '.join(r['argv'])}\n[exit {r['rc']}]\n{r['text']}" for r in runs))
    touched = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
    verdict, why = judge(kind, runs, root, reference)
    return dict(kind=kind.name, expect=kind.expect, verdict=verdict, why=why, touched=touched,
                rcs=[r["rc"] for r in runs], message=_said(runs, kind))


def _said(runs, kind) -> str:
    """The lines of the last command that say something about the input (errors and warnings)."""
    lines = []
    for r in runs[::-1]:
        lines = [s.strip() for s in r["text"].splitlines()
                 if s.strip().startswith(("error", "warning", "-", "Traceback")) or "Warning" in s]
        if lines:
            break
    return " | ".join(lines[:4])[:600]


def _names_ok(text: str, names, row: bool) -> bool:
    low = text.lower()
    for n in names:
        if n == "ROW":
            if not any(str(r) in text for r in (ROW, ROW + 1, ROW + 2)):
                return False
        elif n.lower() not in low:
            return False
    return True


def _databases(folder: Path) -> dict[str, pd.DataFrame] | None:
    if not (folder / "peaks.csv").exists():
        return None
    return {name: pd.read_csv(folder / f"{name}.csv", dtype={"counter": str, "condition": str})
            for name in ("db1", "db2", "db3", "peaks")}


def _same(a: dict, b: dict, except_condition: str | None = None) -> bool:
    """The databases equal: bitwise for every condition but `except_condition` where given,
    else to float32's rounding (the same data in another form, e.g. an unwrapped azimuth)."""
    for name in b:
        x, y = a[name], b[name]
        if except_condition is not None:
            x, y = x[x.condition != except_condition], y[y.condition != except_condition]
        x, y = x.reset_index(drop=True), y.reset_index(drop=True)
        try:
            pd.testing.assert_frame_equal(x, y, check_exact=except_condition is not None, rtol=1e-4, atol=1e-6)
        except AssertionError:
            return False
    return True


def judge(kind: Kind, runs, root: Path, reference) -> tuple[str, str]:
    if any("Traceback (most recent call last)" in r["text"] or r["rc"] not in (0, 1, 2) for r in runs):
        return "traceback", "a traceback or an unexpected exit status"
    last = runs[-1]
    text = "\n".join(r["text"] for r in runs)
    named = _names_ok(last["text"], kind.names, "ROW" in kind.names)
    said = [s for s in last["text"].splitlines() if s.startswith(("error", "warning")) or "Warning" in s
            or s.strip().startswith("- ")]
    if kind.once and named:
        col = kind.names[0]
        if sum(col in s for s in text.splitlines()) > 2 * len(runs):
            return "unclear", f"{col} said once per file, not once"
    dbs = _databases(root / "out")
    if kind.expect == "refuse":
        if last["rc"] != 0:
            return ("clear", "refused by name") if named else ("unclear", "refused without naming " + str(kind.names))
        if said and named:
            return "clear", "warned by name, ran"
        return ("unclear", "ran with a warning that names the wrong thing") if said else ("silent", "ran, no word")
    if kind.expect == "flag":
        if named and (last["rc"] != 0 or said):
            return "clear", "refused or warned by name"
        return ("unclear", "said something, not by name") if (said or last["rc"] != 0) else ("silent", "no word")
    if kind.expect == "accept":
        if last["rc"] != 0:
            return "unclear", "good input refused"
        if kind.same and dbs is not None and not _same(dbs, reference):
            return "silent", "ran, but the databases differ from the clean campaign's"
        return "correct", "ran as the clean campaign"
    if kind.expect == "either":
        if last["rc"] != 0:
            return ("clear", "refused by name") if named else ("unclear", "refused without naming the cause")
        if dbs is not None and not _same(dbs, reference):
            return ("clear", "ran, warned by name") if said and named else ("silent", "ran, databases differ")
        return "correct", "ran as the clean campaign"
    if kind.expect == "isolate":
        if last["rc"] != 0:
            return ("clear", "the record refused by name") if named else ("unclear", "refused without naming it")
        if dbs is None:
            return "unclear", "ran but wrote no databases"
        cond = reference["peaks"].set_index("counter").condition.get(kind.names[0], kind.names[0])
        if not _same(dbs, reference, except_condition=cond):
            return "silent", "another condition's row moved"
        return "correct", "every other condition's row bitwise unchanged"
    raise ValueError(kind.expect)


def base_campaign(work: Path, source: Path | None) -> Path:
    src = source or cached_campaign(SynthConfig(name="small", counts=SMALL_COUNTS))
    base = work / "_base"
    if not (base / "counters.csv").exists():
        shutil.rmtree(base, ignore_errors=True)
        (base / "timeseries").mkdir(parents=True)
        shutil.copy(src / "campaign.toml", base / "campaign.toml")
        counters = pd.read_csv(src / "counters.csv", dtype={"counter": str})
        counters[counters.counter.isin(KEEP)].to_csv(base / "counters.csv", index=False)
        for c in KEEP:
            shutil.copy(src / "timeseries" / f"{c}.parquet", base / "timeseries" / f"{c}.parquet")
    return base


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--campaign", type=Path, default=None, help="campaign to cut (default: the small synthetic one)")
    ap.add_argument("--work", type=Path, default=Path("/tmp/pvvjax-new-user-trial"))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", nargs="*", default=None, help="kinds whose name contains any of these")
    ap.add_argument("--docs", type=Path, default=None, help="write the report (Markdown) here")
    ap.add_argument("--report-only", action="store_true", help="write --docs from the last run's results")
    args = ap.parse_args(argv)
    if args.report_only:
        table = pd.read_json(args.work / "results.json", orient="records")
        args.docs.write_text(report(table, json.loads((args.work / "meta.json").read_text()), args.work))
        print(f"wrote {args.docs}")
        return 0
    args.work.mkdir(parents=True, exist_ok=True)
    git = lambda *a: subprocess.run(["git", *a], capture_output=True, text=True).stdout.strip()  # noqa: E731
    meta = dict(commit=git("rev-parse", "--short", "HEAD"), changed=bool(git("status", "--porcelain", "pvvjax")),
                date=datetime.date.today().isoformat(),
                machine=f"{platform.machine()} {os.cpu_count()} cores, Python {platform.python_version()}")
    (args.work / "meta.json").write_text(json.dumps(meta))
    base = base_campaign(args.work, args.campaign)
    ref_out = args.work / "_reference"
    if not (ref_out / "peaks.csv").exists():
        shutil.rmtree(ref_out, ignore_errors=True)
        subprocess.run([sys.executable, "-m", "pvvjax", "build-db", "--campaign", str(base), "--out", str(ref_out)],
                       check=True, capture_output=True)
    reference = _databases(ref_out)
    todo = [k for k in kinds() if not args.only or any(s in k.name for s in args.only)]
    names = [k.name for k in kinds()]
    assert len(set(names)) == len(names), "kind names repeat"
    with ThreadPoolExecutor(args.jobs) as pool:
        rows = []
        for i, row in enumerate(pool.map(lambda k: run_kind(k, base, args.work, reference), todo), 1):
            rows.append(row)
            print(f"[{i}/{len(todo)}] {row['verdict']:9s} {row['kind']}: {row['message'][:160]}", flush=True)
    table = pd.DataFrame(rows)
    table.to_json(args.work / "results.json", orient="records", indent=1)
    counts = table.verdict.value_counts()
    print(counts.to_string(), f"\nfiles touched: {sum(bool(t) for t in table.touched)}")
    if args.docs:
        args.docs.write_text(report(table, meta, args.work))
        print(f"wrote {args.docs}")
    return 0


def report(table: pd.DataFrame, meta: dict, work: Path) -> str:
    """The Markdown report of a run: the verdicts' counts, then every kind with what it said
    (each kind's folder under `work` left out of the paths)."""
    counts = table.verdict.value_counts()
    order = ["correct", "clear", "unclear", "silent", "traceback"]
    lines = [
        "# A new user's trial",
        "",
        f"{len(table)} kinds of input a new user might bring, each on its own copy of a small campaign "
        f"(the small synthetic campaign cut to {len(KEEP)} counters of every maneuver kind), through "
        "`pvvjax validate` and `pvvjax build-db` or the command the kind is about, run as a user runs them "
        "(a new process each). Generated by `python research/new_user_trial.py --docs docs/new-user-trial.md`; "
        "the verdicts are judged by the script, from what the kind says a clear message must name.",
        "",
        f"Commit `{meta['commit']}`{' (with changes to pvvjax/ not yet committed)' if meta['changed'] else ''}, "
        f"{meta['date']}, {meta['machine']}.",
        "",
        "| verdict | count | meaning |",
        "|---|---|---|",
    ]
    meaning = dict(correct="good input, run as expected", clear="refused or warned, naming what the kind asks",
                   unclear="a message missing a name, a cause repeated per file, or good input refused",
                   silent="a result without a word on bad input, or another record's numbers moved",
                   traceback="a Python traceback or an unexpected exit status")
    for v in order:
        lines.append(f"| {v} | {int(counts.get(v, 0))} | {meaning[v]} |")
    touched = int(sum(bool(t) for t in table.touched))
    lines += ["", f"Files touched outside the folder the command owns: {touched}.", "",
              "| kind | expected | verdict | what it said (first lines) |", "|---|---|---|---|"]
    for _, r in table.iterrows():
        msg = re.sub(re.escape(str(work)) + r"/[^/ ]+/", "", str(r.message)).replace("|", "\\|").replace("\n", " ")
        lines.append(f"| {r.kind} | {r.expect} | {r.verdict} | {msg[:300]} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
