"""The bad-input suite: every kind of bad campaign file, column mapping and config a user can
hand the CLI, each run through `pvvjax` as a user would. Each asserts the exit status, that
the message names the file and the column (or key), and that no traceback is printed.
`docs/data-contract.md` ("Bad input") lists the same kinds."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from conftest import tiny_records, write_tiny

from pvvjax.cli import main
from pvvjax.data.campaign import write_campaign

DOCS = Path(__file__).parents[1] / "docs" / "data-contract.md"


def _records(fn):
    """A case that edits the tiny campaign's first record (`fn(df) -> df`) before writing it."""
    def make(folder):
        c, r = tiny_records()
        r["C1"] = fn(r["C1"].copy())
        return write_tiny(folder, c, r)
    return make


def _counters(fn):
    def make(folder):
        c, r = tiny_records()
        return write_tiny(folder, fn(c.copy()), r)
    return make


def _file(name, edit):
    """A case that edits one written file's bytes or path (`edit(path)`)."""
    def make(folder):
        write_tiny(folder)
        edit(folder / name)
        return folder
    return make


def _set(column, value, row=None):
    def fn(df):
        if row is None:
            df[column] = value
        else:
            df[column] = df[column].astype(float)
            df.loc[row - 1, column] = value
        return df
    return fn


def _scaled(column, factor):
    def fn(df):
        df[column] = df[column] * factor
        return df
    return fn


def _text(replace):
    return lambda p: p.write_text(replace(p.read_text()))


def _symlink_to_nothing(p):
    p.unlink()
    p.symlink_to(p.parent / "elsewhere.csv")


def _directory(p):
    p.unlink()
    p.mkdir()


def _truncated_parquet(folder):
    c, r = tiny_records()
    write_tiny(folder, c, r, fmt="parquet")
    p = folder / "timeseries" / "C1.parquet"
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
    return folder


def _fractions(df):
    for s in ("collective_pct", "lateral_pct", "longitudinal_pct"):
        df[s] = df[s] / 100.0
    return df


def _one_stick_fraction(df):
    df["lateral_pct"] = df["lateral_pct"] / 100.0
    return df


def _swapped_axes(df):
    df["ay_g"] = df["az_g"]  # the lateral carrying the vertical's 1 g (and its vibration)
    return df


def _horizontal_in_m_s2(df):
    df["ax_g"] = 9.80665 * 0.8 * (df["az_g"] - 1.0)  # a longitudinal vibration 0.8x the vertical's, in m/s²
    return df


def _horizontal_large(df):
    df["ay_g"] = 4.5 * (df["az_g"] - 1.0)  # a lateral vibration 4.5x the vertical's, in g: a steep turn's
    return df


def _azimuth(fn):
    """A record given the azimuth its rotor speed integrates to, as `fn(degrees)` writes it."""
    def edit(df):
        deg = (df.rotor_rpm * 6.0 * df.time_s) % 360.0
        return df.assign(azimuth_deg=fn(deg))
    return edit


def _units_row(text):
    header, rest = text.split("\n", 1)
    return header + "\n" + ",".join(["unit"] * (header.count(",") + 1)) + "\n" + rest


def _toml_folder(folder):
    write_tiny(folder)
    (folder / "campaign.toml").unlink(missing_ok=True)
    (folder / "campaign.toml").mkdir()
    return folder


def _nominal_500(folder):
    """The tiny campaign (258 rpm) with another rotor's nominal speed in its campaign.toml."""
    from pvvjax.data.constants import UH60A

    c, r = tiny_records()
    return write_campaign(folder, c, r, fmt="csv", aircraft=UH60A._replace(nominal_rpm=500.0))


def _three_blades(folder):
    """The tiny campaign (a 4/rev vibration) with blades = 3 in its campaign.toml."""
    from pvvjax.data.constants import UH60A

    c, r = tiny_records()
    return write_campaign(folder, c, r, fmt="csv", aircraft=UH60A._replace(blades=3))


def _slow(df):
    return df.iloc[::25].reset_index(drop=True)  # 11 samples per revolution: < 3 per 4/rev cycle


def _gap(df):
    df["altitude_ft"] = 1000.0
    df.loc[4, "altitude_ft"] = np.nan
    return df


# (kind as the docs list it, make(folder), exit status, file named, column or key named,
# config text or None). Exit 1: `validate` found errors; 0: warnings only.
def _text_value(column, value, row=0):
    def edit(c):
        c = c.astype({column: object})
        c.loc[row, column] = value
        return c
    return _counters(edit)


CAMPAIGN = {
    "a channel of true/false values": (_records(lambda d: d.assign(collective_pct=d.collective_pct > 40)), 1,
                                       "C1.csv", "collective_pct", "true/false value True"),
    "azimuth in radians": (_records(_azimuth(np.deg2rad)), 1, "C1.csv", "azimuth_deg", "in radians?"),
    "azimuth running backwards": (_records(_azimuth(lambda d: (360.0 - d) % 360.0)), 1, "C1.csv", "azimuth_deg",
                                  "runs backwards"),
    "one azimuth sample reading 0 (a logger glitch)": (_records(_azimuth(lambda d: np.where(np.arange(len(d)) == 40,
                                                                                          0.0, d))),
                                                       1, "C1.csv", "azimuth_deg", "row 41"),
    "blades = 3 on a four-bladed rotor's data (a warning)": (_three_blades, 0, "C1.csv", "az_g",
                                                             "vibrates at 4/rev, far more than at the analysed 3/rev"),
    "a vibration channel without vibration": (_records(_set("az_g", 1.0)), 1, "C1.csv", "az_g", "no vibration"),
    "a vertical axis of noise with no 4/rev in it (a warning)": (
        _records(lambda d: d.assign(az_g=1.0 + 0.05 * np.random.default_rng(1).standard_normal(len(d)))), 0,
        "C1.csv", "az_g", "carries no 4/rev above its noise"),
    "time stamps of the day (a warning)": (_records(lambda d: d.assign(time_s=d.time_s + 52312.5)), 0, "C1.csv",
                                           "time_s", "rebased to start at 0 s"),
    "one condition, two maneuver kinds": (_counters(lambda c: c.assign(condition="K1", segment=[1, 2],
                                                                        maneuver=["level", "climb"])), 1,
                                          "counters.csv", "maneuver", "one condition, one maneuver kind"),
    "a condition's segment twice": (_counters(lambda c: c.assign(condition="K1", maneuver="level")), 1,
                                    "counters.csv", "segment", "segment 1 twice"),
    "a unit in a counters.csv value": (_text_value("gross_weight_lb", "16000 lb"), 1, "counters.csv", "gross_weight_lb",
                                       "a unit in the value"),
    "a decimal comma in counters.csv": (_text_value("density_ratio", "0,95", row=1), 1, "counters.csv",
                                        "density_ratio", "write 0.95"),
    "az_g of 1e30": (_records(_set("az_g", 1e30, row=3)), 1, "C1.csv", "az_g", "row 3"),
    "az_g of 1e39 (beyond float32)": (_records(_set("az_g", 1e39, row=3)), 1, "C1.csv", "az_g", "row 3"),
    "acceleration in m/s²": (_records(_scaled("az_g", 9.80665)), 1, "C1.csv", "az_g", "m/s²"),
    "the vibration without its 1 g mean": (_records(lambda d: d.assign(az_g=d.az_g - 1.0)), 1, "C1.csv", "az_g",
                                           "1 g mean"),
    "time in milliseconds": (_records(_scaled("time_s", 1000.0)), 1, "C1.csv", "time_s", "milliseconds"),
    "sampling too slow for the harmonic": (_records(_slow), 1, "C1.csv", "time_s", "samples per cycle"),
    "sticks as fractions": (_records(_fractions), 1, "C1.csv", "collective_pct", "fraction"),
    "axes swapped: the lateral carrying the vertical's 1 g": (_records(_swapped_axes), 1, "C1.csv", "ay_g",
                                                              "axes swapped"),
    "a horizontal axis in m/s²": (_records(_horizontal_in_m_s2), 1, "C1.csv", "ax_g", "m/s²"),
    "a horizontal axis 4.5x the vertical (a warning)": (_records(_horizontal_large), 0, "C1.csv", "ay_g",
                                                        "warning"),
    "a horizontal axis that carries no vibration": (_records(_set("ax_g", 0.0)), 1, "C1.csv", "ax_g",
                                                    "carries no vibration"),
    "one stick a fraction, the others in % (a warning)": (_records(_one_stick_fraction), 0, "C1.csv", "lateral_pct",
                                                          "the other sticks are not"),
    "negative airspeed": (_records(_set("airspeed_kt", -5.0, row=2)), 1, "C1.csv", "airspeed_kt", "row 2"),
    "airspeed beyond any rotor (advance ratio > 0.6)": (_records(_set("airspeed_kt", 400.0, row=2)), 1, "C1.csv",
                                                         "airspeed_kt", "advance ratio"),
    "rotor speed in rad/s": (_records(_scaled("rotor_rpm", np.pi / 30)), 1, "C1.csv", "rotor_rpm", "in rad/s?"),
    "rotor speed in % of nominal": (_records(_scaled("rotor_rpm", 100 / 257.8)), 1, "C1.csv", "rotor_rpm",
                                    "in % of the nominal rotor speed?"),
    "climb rate beyond ±10 000 ft/min": (_records(_set("climb_rate_fpm", 20000.0, row=7)), 1, "C1.csv",
                                         "climb_rate_fpm", "row 7"),
    "pitch rate beyond ±200 deg/s": (_records(_set("pitch_rate_dps", 500.0, row=2)), 1, "C1.csv", "pitch_rate_dps",
                                     "row 2"),
    "weight in newtons": (_counters(lambda c: c.assign(gross_weight_lb=16000 * 4.448)), 1, "C1.csv",
                          "gross_weight_lb", "weight in N"),
    "air density in kg/m³, not the ratio (a warning)": (_counters(lambda c: c.assign(density_ratio=1.225)), 0,
                                                        "C1.csv", "density_ratio", "a density in kg/m³"),
    "weight in kg (a warning)": (_counters(lambda c: c.assign(gross_weight_lb=16000 / 2.2046)), 0, "C1.csv",
                                 "gross_weight_lb", "weight in kg"),
    "level flight far from 1 g (a warning)": (_records(lambda d: d.assign(az_g=d.az_g - 0.4)), 0, "C1.csv", "az_g",
                                              "warning"),
    "a gap in an optional channel (a warning; the channel is left out)": (_records(_gap), 0, "C1.csv",
                                                                          "altitude_ft", "row 5"),
    "NaN in a required channel": (_records(_set("rotor_rpm", np.nan, row=4)), 1, "C1.csv", "rotor_rpm", "row 4"),
    "non-numeric value": (_records(lambda d: d.assign(airspeed_kt=["fast"] + list(d.airspeed_kt[1:]))), 1,
                          "C1.csv", "airspeed_kt", "'fast'"),
    "time not increasing": (_records(_set("time_s", 0.0, row=5)), 1, "C1.csv", "time_s", "row 5"),
    "time not uniform": (_records(_set("time_s", 0.0186, row=6)), 1, "C1.csv", "time_s", "not uniform"),
    "record shorter than one window": (_records(lambda d: d.iloc[:200]), 1, "C1.csv", "time_s", "revolutions"),
    "stick outside 0–100 %": (_records(_set("lateral_pct", 140.0, row=9)), 1, "C1.csv", "lateral_pct", "row 9"),
    "density ratio outside 0.3–1.3": (_counters(lambda c: c.assign(density_ratio=[1.0, 0.1])), 1, "counters.csv",
                                      "density_ratio", "row 2: counter 'C2': value 0.1 outside"),
    "missing required column": (_records(lambda d: d.drop(columns="climb_rate_fpm")), 1, "C1.csv",
                                "climb_rate_fpm", "missing"),
    "a channel in both places": (_records(lambda d: d.assign(gross_weight_lb=16000.0)), 1, "C1.csv",
                                 "gross_weight_lb", "one place"),
    "duplicate counter": (_counters(lambda c: c.assign(counter=["C1", "C1"])), 1, "counters.csv", "counter",
                          "duplicate"),
    "unknown maneuver": (_counters(lambda c: c.assign(maneuver=["level", "hover taxi"])), 1, "counters.csv",
                         "maneuver", "row 2"),
    "segment not an integer ≥ 1": (_counters(lambda c: c.assign(segment=[1, 0.5])), 1, "counters.csv", "segment",
                                   "row 2"),
    "counter without its file": (_file("timeseries/C2.csv", Path.unlink), 1, "counters.csv", "counter", "C2"),
    "file without its counter": (_file("timeseries/C3.csv", lambda p: p.write_text("time_s\n0\n")), 1, "C3.csv",
                                 "", "no counter"),
    "empty counters.csv": (_file("counters.csv", lambda p: p.write_text("")), 1, "counters.csv", "", "empty"),
    "counters.csv with a header only": (_file("counters.csv", _text(lambda t: t.splitlines()[0] + "\n")), 1,
                                        "counters.csv", "", "no rows"),
    "semicolon-separated file": (_file("counters.csv", _text(lambda t: t.replace(",", ";"))), 1, "counters.csv", "",
                                 "semicolons"),
    "tab-separated file": (_file("timeseries/C1.csv", _text(lambda t: t.replace(",", "\t"))), 1, "C1.csv", "",
                           "tabs"),
    "duplicated header": (_file("timeseries/C1.csv", _text(lambda t: t.replace("pitch_rate_dps", "az_g", 1))), 1,
                          "C1.csv", "az_g", "twice"),
    "blank header": (_file("timeseries/C1.csv", _text(lambda t: t.replace("pitch_rate_dps", " ", 1))), 1, "C1.csv",
                     "column 5", "no name"),
    "UTF-16 file": (_file("counters.csv", lambda p: p.write_bytes(p.read_text().encode("utf-16"))), 1,
                    "counters.csv", "", "UTF-16"),
    "comment lines above the header": (_file("timeseries/C1.csv", _text(lambda t: "# logger v2\n" + t)), 1, "C1.csv",
                                       "", "comment lines above the header"),
    "a units row under the header": (_file("timeseries/C1.csv", _text(_units_row)), 1, "C1.csv", "", "a units row"),
    "an upper-case extension": (_file("timeseries/C1.csv", lambda p: p.rename(p.with_suffix(".CSV"))), 1, "C1.CSV",
                                "", "name the file C1.csv"),
    "a link to a missing file": (_file("timeseries/C1.csv", _symlink_to_nothing), 1, "C1.csv", "", "missing file"),
    "a folder in the place of a file": (_file("timeseries/C1.csv", _directory), 1, "C1.csv", "", "cannot read"),
    "truncated Parquet file": (_truncated_parquet, 1, "C1.parquet", "", "Parquet"),
    "campaign.toml not TOML": (_file("campaign.toml", lambda p: p.write_text("[aircraft\n")), 1, "campaign.toml", "",
                               "TOML"),
    "campaign.toml unknown key": (_file("campaign.toml", lambda p: p.write_text("[rotor]\nblades = 4\n")), 1,
                                  "campaign.toml", "rotor", "unknown key"),
    "campaign.toml is a folder": (_toml_folder, 1, "campaign.toml", "", "a folder, not the campaign's TOML file"),
    "another rotor's nominal_rpm in campaign.toml (a warning)": (_nominal_500, 0, "C1.csv", "rotor_rpm",
                                                                 "nominal_rpm (500) another rotor's"),
    "campaign.toml bad aircraft value": (_file("campaign.toml", lambda p: p.write_text("[aircraft]\nblades = 0\n")),
                                         1, "campaign.toml", "blades", "> 0"),
}

MAPPING = {
    "mapping that matches no column": ('[campaign.columns.IAS]\nto = "airspeed_kt"\nunit = "kt"\n', "campaign.columns",
                                       "'IAS'", "columns there"),
    "mapping with a unit of the wrong dimension": ('[campaign.columns.az_g]\nto = "az_g"\nunit = "kt"\n', "az_g",
                                                   "unit", ""),
    "mapping onto a name that is not a channel, with a unit": (
        '[campaign.columns.az_g]\nto = "vertical_g"\nunit = "g"\n', "campaign.columns.az_g", "'vertical_g'",
        "is not a data-contract channel"),
    "mapping onto a column the file has": ('[campaign.columns.airspeed_kt]\nto = "rotor_rpm"\n', "C1.csv",
                                           "airspeed_kt", "also has"),
}

def _cli_out_is_a_file(tmp_path):
    (tmp_path / "f").write_text("x")
    return ["build-db", "--campaign", str(write_tiny(tmp_path / "c")), "--out", str(tmp_path / "f")], str(
        tmp_path / "f")


def _cli_missing_campaign(tmp_path):
    return ["build-db", "--campaign", str(tmp_path / "nope"), "--out", str(tmp_path / "o")], "nope"


def _cli_missing_config(tmp_path):
    return ["validate", "--campaign", str(write_tiny(tmp_path / "c")), "--config", str(tmp_path / "no.toml")], "no.toml"


def _cli_unwritable_out(tmp_path):
    (tmp_path / "f").write_text("x")
    return ["build-db", "--campaign", str(write_tiny(tmp_path / "c")), "--out", str(tmp_path / "f" / "sub")], "f/sub"


def _cli_synth_over_user_data(tmp_path):
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("mine")
    return ["synth", "--out", str(tmp_path / "mine")], "--force"


def _cli_synth_over_a_campaign(tmp_path):
    return ["synth", "--force", "--out", str(write_tiny(tmp_path / "mine"))], "pvvjax.synth did not write"


def _cli_not_a_sweep(tmp_path):
    return ["export", str(tmp_path), "--element", "--out", str(tmp_path / "e")], "not a sweep folder"


def _cli_process_id(tmp_path):
    (tmp_path / "cfg.toml").write_text("")
    return ["sweep", str(tmp_path / "cfg.toml"), "--coordinator", "127.0.0.1:1", "--num-processes", "2",
            "--process-id", "2"], "--process-id 2"


def _flag(command, flag, value, needle):
    """A command whose flag is out of its range: refused by argparse before any work."""
    def case(tmp_path):
        (tmp_path / "cfg.toml").write_text("")
        argv = {"realtime": ["realtime", "--model", str(tmp_path), "--record", "C1"],
                "replay": ["replay", str(tmp_path / "cfg.toml")],
                "sweep": ["sweep", str(tmp_path / "cfg.toml")]}[command]
        return argv + [flag, value] if value is not None else argv + [flag], needle
    return case


def _cli_processes_without_coordinator(tmp_path):
    (tmp_path / "cfg.toml").write_text("")
    return ["sweep", str(tmp_path / "cfg.toml"), "--num-processes", "2"], "need --coordinator"


def _cli_unfinished_sweep(tmp_path):
    (tmp_path / "sweep" / "parts").mkdir(parents=True)
    (tmp_path / "sweep" / "config.toml").write_text("")
    return ["export", str(tmp_path / "sweep"), "--out", str(tmp_path / "e")], "an unfinished sweep (0 nets finished"


def _dynamic(setting, needle):
    """`pvvjax dynamic` on the tiny campaign (3 conditions of 12 s) with one `[dynamic]`
    setting it cannot support: refused by its key before any folder is claimed."""
    def case(tmp_path):
        settings = {"folds": "3", "seeds": "1", **dict([setting.split(" = ")])}
        (tmp_path / "cfg.toml").write_text("[dynamic]\n" + "".join(f"{k} = {v}\n" for k, v in settings.items()))
        camp = write_tiny(tmp_path / "c", *tiny_records(n_counters=3))
        return ["dynamic", "--campaign", str(camp), "--config", str(tmp_path / "cfg.toml"), "--out",
                str(tmp_path / "d")], needle
    return case


def _axes_folds(tmp_path):
    (tmp_path / "cfg.toml").write_text("[axes]\nfolds = 5\n")
    return ["axes", "--campaign", str(write_tiny(tmp_path / "c", *tiny_records(n_counters=3))), "--config",
            str(tmp_path / "cfg.toml"), "--out", str(tmp_path / "a")], "axes.folds = 5: campaign"


def _cli_axis_the_campaign_lacks(tmp_path):
    (tmp_path / "cfg.toml").write_text('[analysis]\naxis = "ay_g"\n')
    return ["dynamic", "--campaign", str(write_tiny(tmp_path / "c")), "--config", str(tmp_path / "cfg.toml"), "--out",
            str(tmp_path / "d")], "analysis.axis = 'ay_g': campaign"


def _export_flags(kind, flags, needle):
    """`pvvjax export` of a folder of `kind` (its marker file only: the flags are refused
    before anything is read) with flags that kind does not honour, or that contradict."""
    def case(tmp_path):
        folder = tmp_path / kind
        folder.mkdir()
        marker = {"dynamic": "comparison.parquet", "axes": "axes.parquet", "sweep": "results.parquet"}[kind]
        (folder / marker).write_bytes(b"")
        return ["export", str(folder), *flags, "--out", str(tmp_path / "e")], needle
    return case


def _comparison_of(models, degenerate, needle, flags=()):
    """A `pvvjax dynamic` folder whose comparison holds `models` of db1 (each `degenerate`
    as given, none `best`): its default export (with `flags`) is refused, naming why."""
    def case(tmp_path):
        import pandas as pd

        folder = tmp_path / "dyn"
        folder.mkdir()
        pd.DataFrame(dict(database="db1", model=models, rms_g=0.05, degenerate=degenerate,
                          best=False)).to_parquet(folder / "comparison.parquet")
        (folder / "config.toml").write_text("")
        return ["export", str(folder), "--element", *flags, "--out", str(tmp_path / "e")], needle
    return case


def _cli_replay_unknown_counter(tmp_path):
    (tmp_path / "cfg.toml").write_text("")
    return ["replay", str(tmp_path / "cfg.toml"), "--campaign", str(write_tiny(tmp_path / "c")), "--counters", "C1",
            "NOPE", "--out", str(tmp_path / "r")], "--counters: NOPE not in the campaign"


def _cli_element_of_another_rotor(tmp_path):
    import json

    from pvvjax.data.constants import Aircraft

    (tmp_path / "el").mkdir()
    (tmp_path / "el" / "element.json").write_text(json.dumps(dict(
        nets=[], inputs=["advance_ratio"], window_revs=8.0, hop_revs=1.0,
        aircraft=dict(rotor_radius_ft=Aircraft().rotor_radius_ft, g_ft_s2=32.174, blades=4))))
    c, r = tiny_records()
    camp = write_campaign(tmp_path / "c", c, r, aircraft=Aircraft(blades=2, rotor_radius_ft=22.0, nominal_rpm=324.0))
    return ["realtime", "--model", str(tmp_path / "el"), "--record", "C1", "--campaign", str(camp)], (
        "a 4-bladed rotor of radius 26.83 ft, but the campaign")


def _cli_replay_of_an_untrained_database(tmp_path):
    (tmp_path / "cfg.toml").write_text('[sweep]\ndatabases = ["db1"]\n[replay]\ndatabases = ["db1", "db3"]\n')
    return ["replay", str(tmp_path / "cfg.toml"), "--out", str(tmp_path / "r")], "names db3, which sweep.databases"


def _cli_run_without_its_scenario(tmp_path):
    (tmp_path / "cfg.toml").write_text(f'out_dir = "{tmp_path.as_posix()}"\n[run]\ndiscovery_scenario = "nope.toml"\n')
    return ["run", str(tmp_path / "cfg.toml"), "--campaign", str(write_tiny(tmp_path / "c"))], (
        "run.discovery_scenario: ")


def _cli_element_not_json(tmp_path):
    (tmp_path / "element.json").write_text("{not json")
    return ["realtime", "--model", str(tmp_path), "--record", "C1"], "element.json: not valid JSON"


def _cli_realtime_over_a_file(tmp_path):
    (tmp_path / "s.csv").write_text("mine")
    return ["realtime", "--model", str(tmp_path), "--record", "C1", "--out", str(tmp_path / "s.csv")], "s.csv: exists"


def _cli_out_in_a_campaign(tmp_path):
    camp = write_tiny(tmp_path / "c")
    return ["build-db", "--campaign", str(camp), "--out", str(camp / "db")], f"lies inside the campaign folder {camp}"


def _cli_dynamic_without_cruise(tmp_path):
    (tmp_path / "cfg.toml").write_text("[dynamic]\nfolds = 3\nseeds = 1\n[train]\nmax_steps = 10\neval_every = 5\n")
    return ["dynamic", "--campaign", str(write_tiny(tmp_path / "c", *tiny_records(n_counters=3))), "--config",
            str(tmp_path / "cfg.toml"), "--out", str(tmp_path / "d")], \
        "no level flight with an advance ratio in [0.25, 0.35]"


def _cli_axis_the_campaign_lacks(tmp_path):
    (tmp_path / "cfg.toml").write_text('[analysis]\naxis = "ay_g"\n')
    return ["build-db", "--campaign", str(write_tiny(tmp_path / "c")), "--config", str(tmp_path / "cfg.toml"),
            "--out", str(tmp_path / "d")], "analysis.axis = 'ay_g': campaign"


def _cli_export_study_without_element(tmp_path):
    (tmp_path / "axes.parquet").write_text("")
    return ["export", str(tmp_path), "--out", str(tmp_path / "e")], "export its three-axis nets with --element"


def _cli_export_comparison_without_element(tmp_path):
    (tmp_path / "comparison.parquet").write_text("")
    return ["export", str(tmp_path), "--out", str(tmp_path / "e")], "export its models with --element"


def _element(flag, value, needle):
    def case(tmp_path):
        return ["export", str(tmp_path), "--element", flag, value, "--out", str(tmp_path / "e")], needle
    return case


# kind -> case(tmp_path) -> (argv, what the message names). Exit 2, no traceback.
CLI_KINDS = {
    "dynamic seeds of zero": lambda tmp_path: (["dynamic", "--out", str(tmp_path / "d"), "--seeds", "0"], "--seeds"),
    "dynamic on a campaign without cruise flights": _cli_dynamic_without_cruise,
    "export of a dynamic comparison without --element": _cli_export_comparison_without_element,
    "an analysis axis the campaign does not carry": _cli_axis_the_campaign_lacks,
    "export of a three-axis study without --element": _cli_export_study_without_element,
    "--out on a file": _cli_out_is_a_file,
    "--out under a file": _cli_unwritable_out,
    "a campaign folder that is not there": _cli_missing_campaign,
    "a config file that is not there": _cli_missing_config,
    "synth --out over a folder it did not write": _cli_synth_over_user_data,
    "synth --force over a campaign it did not write": _cli_synth_over_a_campaign,
    "export from a folder that is not a sweep": _cli_not_a_sweep,
    "element offset NaN": _element("--offset", "nan", "argument --offset: nan"),
    "element offset beyond the calibration's bounds": _element("--offset", "7", "--offset 7"),
    "element window negative": _element("--window", "-3", "--window -3"),
    "element stick offset beyond the bounds": _element("--stick-offset", "5", "--stick-offset 5"),
    "element hop longer than the window": _element("--hop", "20", "--hop 20"),
    "element format without --element": lambda tmp_path: (
        ["export", str(tmp_path), "--format", "c", "--out", str(tmp_path / "e")], "add --element"),
    "element frame rate not above 0": _element("--max-rate", "0", "argument --max-rate: 0"),
    "sweep process id outside the processes": _cli_process_id,
    "sweep processes without a coordinator": _cli_processes_without_coordinator,
    "sweep no processes": _flag("sweep", "--num-processes", "0", "argument --num-processes: 0: must be at least 1"),
    "sweep coordinator without a port": _flag("sweep", "--coordinator", "localhost", "give HOST:PORT"),
    "realtime frame rate negative": _flag("realtime", "--rate", "-5", "argument --rate: -5: must be a finite number"),
    "realtime frame rate of a gigahertz": _flag("realtime", "--rate", "1e9", "argument --rate: 1e9"),
    "realtime jitter of a whole frame": _flag("realtime", "--jitter", "1", "argument --jitter: 1"),
    "replay window of zero revolutions": _flag("replay", "--window", "0", "argument --window: 0"),
    "replay figures negative": _flag("replay", "--plots", "-1", "argument --plots: -1"),
    "realtime --out over a file": _cli_realtime_over_a_file,
    "export from an unfinished sweep": _cli_unfinished_sweep,
    "realtime element.json not JSON": _cli_element_not_json,
    "run with a discovery scenario that is not there": _cli_run_without_its_scenario,
    "replay of a database the sweep does not train": _cli_replay_of_an_untrained_database,
    "realtime element of another rotor": _cli_element_of_another_rotor,
    "replay of a counter not in the campaign": _cli_replay_unknown_counter,
    "--out inside a campaign folder": _cli_out_in_a_campaign,
    "dynamic delay longer than the records": _dynamic("delay_s = 1e6", "dynamic.delay_s = 1e+06 s: outside 0 to"),
    "dynamic natural frequency above the window rate": _dynamic("f_n_hz = 50.0", "dynamic.f_n_hz = 50 Hz: outside"),
    "dynamic windows longer than a condition": _dynamic("window_revs = 60.0", "dynamic.window_revs = 60:"),
    "dynamic more folds than conditions": _dynamic("folds = 5", "dynamic.folds = 5: campaign"),
    "axes more folds than conditions": _axes_folds,
    "an analysis axis the campaign lacks": _cli_axis_the_campaign_lacks,
    "export a comparison's model with window flags": _export_flags(
        "dynamic", ["--element", "--window", "4", "--hop", "0.5", "--offset", "2"],
        "--offset, --window, --hop: not used when exporting a model of a `pvvjax dynamic` comparison"),
    "export --net with --architecture": _export_flags("sweep", ["--element", "--net", "3", "--architecture", "x"],
                                                      "--net 3 and --architecture"),
    "export --net with --database": _export_flags("sweep", ["--net", "3", "--database", "db2"],
                                                  "--net 3 and --database"),
    "export an element setting without --element": _export_flags("sweep", ["--window", "6"],
                                                                 "--window: not used when exporting one net"),
    "export --max-rate with the NumPy element": _export_flags("sweep", ["--element", "--max-rate", "500"],
                                                              "--max-rate: sizes the buffers of the C and FMU"),
    "export an axes study's nets with --net": _export_flags("axes", ["--element", "--net", "3"],
                                                            "--net: not used when exporting the nets of a `pvvjax "
                                                            "axes` study"),
    "export a database the comparison lacks": _comparison_of(["rnn", "window_static_rates"], "",
                                                             "no model of db2: it compares db1", ["--database", "db2"]),
    "export a comparison whose every model is degenerate": _comparison_of(
        ["quasi_static", "dynamic"], "a constant prediction", "no model is fit to export (quasi_static (db1): a "
                                                              "constant prediction"),
}

CONFIG = {
    "unknown config key": ("[analysis]\nwindow_revz = 8.0\n", "analysis.window_revz"),
    "mistyped config value": ("[analysis]\nwindow_revs = \"eight\"\n", "analysis.window_revs"),
    "config out of range": ("[analysis]\nharmonic = 0\n", "harmonic"),
    "config file not TOML": ("[analysis\n", "cfg.toml"),
    "config value NaN": ("[analysis]\nhop_revs = nan\n", "analysis.hop_revs: nan is not a finite number"),
    "config value infinite": ("[train]\nweight_decay = inf\n", "train.weight_decay: inf is not a finite number"),
    "config saved as UTF-16": ("[analysis]\nwindow_revs = 8.0\n".encode("utf-16"), "cfg.toml: saved as UTF-16"),
    "config not UTF-8": ('name = "Müller"\n'.encode("latin-1"), "cfg.toml: not UTF-8 text (byte 0xfc on line 1)"),
    "analysis hop below one sample": ("[analysis]\nhop_revs = 1e-6\n", "analysis.hop_revs"),
    "a campaign folder and a synthetic campaign at once": ('[campaign]\npath = "a"\nsynthetic = "b.toml"\n',
                                                           "campaign.path = 'a' and campaign.synthetic"),
    "a discovery level that is not a probability": ("[discovery]\nlevel = 5.0\n", "discovery.level must lie in (0, 1)"),
    "a column map of scale 0": ('[campaign.columns.airspeed_kt]\nto = "airspeed_kt"\nscale = 0.0\n',
                                "campaign.columns.airspeed_kt: scale 0"),
    "config list with a value twice": ('[sweep]\ndatabases = ["db1", "db1"]\n', "sweep.databases: 'db1' given twice"),
    "dynamic model unknown": ('[dynamic]\nmodels = ["lstm"]\n', "dynamic.models: unknown ['lstm']"),
    "dynamic delay negative": ("[dynamic]\ndelay_s = -0.1\n", "dynamic.delay_s must be >= 0"),
    "dynamic hop above one revolution": ("[dynamic]\nhop_revs = 2.0\n", "dynamic.hop_revs must lie in (0, 1]"),
    "dynamic cruise band reversed": ("[dynamic]\ncruise_advance_ratio = [0.3, 0.2]\n",
                                     "dynamic.cruise_advance_ratio must be [lo, hi]"),
    "an analysis axis not in the data contract": ('[analysis]\naxis = "a_lat"\n', "analysis.axis"),
    "axes pass share above 1": ("[axes]\npass_share = 1.5\n", "axes.pass_share must lie in (0, 1]"),
    "dynamic transient kind unknown": ('[dynamic]\ntransients = ["nope"]\n',
                                       "dynamic.transients: unknown maneuver kind(s) ['nope']"),
    "dynamic damping beyond a physical range": ("[dynamic]\nzeta = 50.0\n", "dynamic.zeta = 50: a damping ratio"),
    "dynamic offset grid of one point": ("[dynamic]\noffset_bounds = [0.0, 0.05]\n",
                                         "dynamic.offset_step_s = 0.1 leaves one point of dynamic.offset_bounds"),
    "dynamic seeds beyond what a trainer holds": ("[dynamic]\nseeds = 1000000\n", "dynamic.seeds = 1000000"),
    "dynamic transients empty": ("[dynamic]\ntransients = []\n", "dynamic.transients is empty"),
    "axes hidden layer of a million units": ("[axes]\nhidden = [1000000]\n", "axes.hidden = [1000000]"),
    "axes cruise band beyond advance ratio 1": ("[axes]\ncruise_advance_ratio = [0.2, 5.0]\n",
                                                "axes.cruise_advance_ratio = [0.2, 5.0]"),
    "replay maneuver kind unknown": ('[replay]\nmaneuvers = ["pullupp"]\n', "replay.maneuvers: unknown"),
    "calibration coarse grid of one point": ("[calibration]\ncoarse_window_step_revs = 20.0\n",
                                             "calibration.coarse_window_step_revs = 20 leaves one point"),
    "train evaluation after the last step": ("[train]\nmax_steps = 10\n", "train.eval_every = 50"),
    "train divergence factor not above 1": ("[train]\ndivergence_factor = 0.5\n", "train.divergence_factor = 0.5"),
    "sweep without an architecture": ("[sweep]\nhidden = []\n", "sweep.hidden is empty"),
    "seed negative": ("seed = -1\n", "seed = -1"),
    "experiment name with a path separator": ('name = "a/b"\n', "name = 'a/b'"),
}


def _run(argv, capsys):
    code = main(argv)
    out = capsys.readouterr()
    text = out.out + out.err
    assert "Traceback" not in text, text
    return code, text


@pytest.mark.parametrize("kind", list(CAMPAIGN))
def test_bad_campaign_is_refused_naming_file_and_column(kind, tmp_path, capsys):
    make, status, file, column, detail = CAMPAIGN[kind]
    folder = make(tmp_path / "c")
    code, text = _run(["validate", "--campaign", str(folder)], capsys)
    assert code == status, text
    line = next((ln for ln in text.splitlines() if file in ln and column in ln and detail in ln), None)
    assert line is not None, (file, column, detail, text)
    if kind != "sticks as fractions":  # one mistake, one line for its file (not one per rule it breaks)
        where = [ln.replace("warning: ", "").split(":")[0] for ln in text.splitlines() if ln.startswith("  - ")]
        assert sum(file in w for w in where) == 1, text
    if column:
        assert f"'{column}'" in line or column in line


def test_a_gap_in_an_optional_channel_is_left_out_of_the_loaded_record(tmp_path):
    from pvvjax.data import CampaignWarning, load_campaign

    folder = CAMPAIGN["a gap in an optional channel (a warning; the channel is left out)"][0](tmp_path / "c")
    with pytest.warns(CampaignWarning, match="altitude_ft"):
        camp = load_campaign(folder)
    assert "altitude_ft" not in camp.records["C1"] and "altitude_ft" not in camp.numeric_channels()


def test_a_column_missing_everywhere_is_one_line(tmp_path, capsys):
    c, r = tiny_records(n_counters=4)
    folder = write_tiny(tmp_path / "c", c, {k: v.drop(columns="pitch_rate_dps") for k, v in r.items()})
    code, text = _run(["validate", "--campaign", str(folder)], capsys)
    lines = [ln for ln in text.splitlines() if "pitch_rate_dps" in ln]
    assert code == 1 and len(lines) == 1 and "4 time series" in lines[0], text


def test_one_rule_broken_in_every_file_is_one_line_with_the_likely_unit(tmp_path, capsys):
    # Every file's rotor speed in % of nominal: each file's value differs, the cause is one.
    c, r = tiny_records(n_counters=4)
    folder = write_tiny(tmp_path / "c", c, {k: v.assign(rotor_rpm=100.0 + 0.1 * i) for i, (k, v) in
                                            enumerate(r.items())})
    code, text = _run(["validate", "--campaign", str(folder)], capsys)
    lines = [ln for ln in text.splitlines() if "rotor_rpm" in ln]
    assert code == 1 and len(lines) == 1, text
    assert "4 time series" in lines[0] and "in % of the nominal rotor speed?" in lines[0], text
    assert "the same in each of the 4" in lines[0], text


@pytest.mark.parametrize("kind", list(MAPPING))
def test_bad_column_mapping_is_refused_naming_it(kind, tmp_path, capsys):
    toml, file, column, detail = MAPPING[kind]
    folder = write_tiny(tmp_path / "c")
    (tmp_path / "cfg.toml").write_text(toml)
    code, text = _run(["validate", "--campaign", str(folder), "--config", str(tmp_path / "cfg.toml")], capsys)
    assert code in (1, 2), text
    assert any(file in ln and column in ln and detail in ln for ln in text.splitlines()), text


@pytest.mark.parametrize("kind", [k for k, case in CAMPAIGN.items() if case[1] == 1])
def test_what_validate_refuses_build_db_refuses_with_the_same_message(kind, tmp_path, capsys):
    make, _, file, column, detail = CAMPAIGN[kind]
    code, text = _run(["build-db", "--campaign", str(make(tmp_path / "c")), "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and detail in text and file in text, text
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("kind", list(CONFIG))
def test_bad_config_is_refused_naming_the_key(kind, tmp_path, capsys):
    toml, key = CONFIG[kind]
    (tmp_path / "cfg.toml").write_bytes(toml if isinstance(toml, bytes) else toml.encode())
    code, text = _run(["build-db", "--campaign", str(write_tiny(tmp_path / "c")), "--config",
                       str(tmp_path / "cfg.toml"), "--out", str(tmp_path / "o")], capsys)
    assert code == 2 and key in text, text


def test_a_config_with_a_utf8_byte_order_mark_is_read(tmp_path, capsys):
    (tmp_path / "cfg.toml").write_bytes(b"\xef\xbb\xbf[analysis]\nwindow_revs = 6.0\n")  # as Notepad saves it
    from pvvjax.config import load_config

    assert load_config(tmp_path / "cfg.toml").analysis.window_revs == 6.0


def test_a_utf8_byte_order_mark_is_read(tmp_path, capsys):
    folder = write_tiny(tmp_path / "c")
    p = folder / "counters.csv"
    p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes())  # as Excel writes CSV
    code, text = _run(["validate", "--campaign", str(folder)], capsys)
    assert code == 0 and "valid" in text, text


def _partial_axis(tmp_path):
    c, r = tiny_records(n_counters=3)
    for name in ("C1", "C2"):
        r[name]["ay_g"] = 0.5 * (r[name].az_g - 1.0)
    return ["build-db", "--campaign", str(write_tiny(tmp_path / "c", c, r)), "--out", str(tmp_path / "o")]


def _transients_not_flown(tmp_path):
    from pvvjax.config import ExperimentConfig
    from pvvjax.data import load_campaign
    from pvvjax.dynamics.checks import check_dynamic

    cfg = ExperimentConfig().with_(dynamic=ExperimentConfig().dynamic.__class__(folds=3, seeds=1))
    check_dynamic(cfg, load_campaign(write_tiny(tmp_path / "c", *tiny_records(n_counters=3))))


# Kinds that are said as a warning while the command goes on: (run it, the warning's words).
WARNINGS = {
    "a horizontal axis in some records only (a warning; the axis is left out)": (
        lambda tmp_path: main(_partial_axis(tmp_path)), "ay_g is in 2 of 3 records and missing from C3"),
    "dynamic transient kinds the campaign does not fly (a warning; their scores are NaN)": (
        _transients_not_flown, "flies no pullup, pushover, roll, autorotation, flare"),
}


@pytest.mark.parametrize("kind", list(WARNINGS))
def test_what_is_left_out_is_said_naming_it(kind, tmp_path, capsys):
    run, needle = WARNINGS[kind]
    with pytest.warns(UserWarning, match=re.escape(needle)):
        assert run(tmp_path) in (0, None)
    assert "Traceback" not in capsys.readouterr().err


def test_the_docs_list_every_kind():
    text = DOCS.read_text()
    table = text[text.index("| kind | verdict |"):].split("\n\n")[0]
    listed = set(re.findall(r"^\| (.+?) \|", table, flags=re.M)) - {"kind"}
    kinds = set(CAMPAIGN) | set(MAPPING) | set(CONFIG) | set(CLI_KINDS) | set(WARNINGS)
    assert kinds == listed, (kinds - listed, listed - kinds)
    assert len(kinds) >= 40



@pytest.mark.parametrize("kind", list(CLI_KINDS))
def test_cli_mistakes_are_one_clear_message(kind, tmp_path, capsys):
    argv, needle = CLI_KINDS[kind](tmp_path)
    code, text = _run(argv, capsys)
    assert code == 2 and "error: " in text and needle in text, text


def test_version_and_every_options_default_in_its_help():
    import argparse

    from pvvjax import __version__
    from pvvjax.cli import build_parser

    parser = build_parser()
    with pytest.raises(SystemExit) as e:
        parser.parse_args(["--version"])
    assert e.value.code == 0 and __version__
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, sp in sub.choices.items():
        for a in sp._actions:
            if not a.option_strings or a.dest == "help" or a.required:
                continue
            assert "default" in (a.help or ""), f"pvvjax {name} {a.option_strings[0]}: help states no default"
        campaign = [a for a in sp._actions if a.dest == "campaign"]
        assert [a.option_strings for a in campaign] == ([] if name in ("synth", "export") else [["--campaign"]]), name


def test_ctrl_c_says_how_to_resume(tmp_path, capsys, monkeypatch):
    import pvvjax.data.campaign

    def interrupted(*args, **kwargs):  # Ctrl-C while the campaign is read
        raise KeyboardInterrupt
    monkeypatch.setattr(pvvjax.data.campaign, "validate_campaign", interrupted)
    code, text = _run(["validate", "--campaign", str(tmp_path)], capsys)
    assert code == 130 and "interrupted; run the same command to resume" in text


@pytest.mark.check
def test_a_closed_pipe_ends_quietly(tmp_path):
    # `pvvjax validate … | head` on a long report: the reader leaves before the writer is done.
    import subprocess
    import sys

    code = ("import sys, pvvjax.cli as cli\n"
            "def long(*args, **kwargs):\n    for i in range(200000): print(f'  - problem {i}')\n    return []\n"
            "import pvvjax.data.campaign as c; c.validate_campaign = long\n"
            "sys.exit(cli.main(['validate', '--campaign', '.']))\n")
    r = subprocess.run(f"{sys.executable} -c \"$CODE\" | head -n 2", shell=True, capture_output=True, text=True,
                       env={**__import__("os").environ, "CODE": code}, cwd=tmp_path)
    assert r.stdout.splitlines() == ["  - problem 0", "  - problem 1"]
    assert r.stderr == "", r.stderr  # quiet: no traceback, no error line


def test_plot_of_a_campaign_without_the_papers_counters_says_so(tmp_path, capsys):
    code, text = _run(["plot", "--campaign", str(write_tiny(tmp_path / "c")), "--out", str(tmp_path / "p"), "--paper"],
                      capsys)
    assert code == 0 and "neither the pull-up 11022 nor the autorotation AR60" in text


def test_synth_replaces_its_own_campaign_only_and_never_a_users(tmp_path, capsys):
    small = tmp_path / "small.toml"
    small.write_text('conditions = ["T1-level-135"]\n')
    out = tmp_path / "synth"
    assert _run(["synth", "--out", str(out), "--config", str(small)], capsys)[0] == 0
    (out / "timeseries" / "stray.csv").write_text("x\n")
    code, text = _run(["synth", "--out", str(out), "--config", str(small), "--seed", "2"], capsys)
    assert code == 0 and "replacing the synthetic campaign" in text and "1 other file(s) kept" in text
    assert (out / "timeseries" / "stray.csv").read_text() == "x\n"  # not the generator's: kept
    mine = write_tiny(tmp_path / "mine")
    before = sorted(p.read_bytes() for p in mine.rglob("*") if p.is_file())
    code, text = _run(["synth", "--out", str(mine), "--config", str(small), "--force"], capsys)
    assert code == 2 and "pvvjax.synth did not write" in text
    assert sorted(p.read_bytes() for p in mine.rglob("*") if p.is_file()) == before
