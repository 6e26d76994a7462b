"""Property-based tests: a small valid campaign mutated at random (dtypes, NaN and inf,
units ×1000 or ÷1000, swapped or renamed columns, truncated or reordered rows, bytes of
another format) and configs of random types and values. Every outcome is either a valid
result with finite numbers or a clear error (status 1 or 2) naming the file or the key;
never a traceback (an unexpected exception fails the test) and never exit 0 with a NaN or
infinite number in the output. `pvvjax dynamic` and `pvvjax axes` under random sections on a
mutated three-axis campaign: a result whose `best` is never degenerate, or a clear error,
and no user file changed. Derandomized, so that CI runs the same examples each time;
bounded to about a minute."""

from __future__ import annotations

import math
import shutil
import string

import numpy as np
import pandas as pd
import pytest
import tomli_w
from conftest import write_tiny
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from pvvjax._strict import ConfigError
from pvvjax.cli import main
from pvvjax.config import ExperimentConfig, from_dict

FUZZ = settings(derandomize=True, database=None, deadline=None, print_blob=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

COLUMNS = ["time_s", "az_g", "rotor_rpm", "airspeed_kt", "pitch_rate_dps", "roll_angle_deg", "climb_rate_fpm",
           "collective_pct", "lateral_pct", "longitudinal_pct"]
COUNTER_COLUMNS = ["counter", "maneuver", "gross_weight_lb", "density_ratio"]
ODD_TEXT = ["", "abc", "1e3x", "0,5", "16000 lb", "nan", "-inf", "True", "１２", "1_000", "0x10", " 7 "]


def _value():
    return st.one_of(st.sampled_from(ODD_TEXT), st.sampled_from([np.nan, np.inf, -np.inf, 0.0, -1.0, 1e30]),
                     st.floats(allow_nan=True, allow_infinity=True, width=32), st.booleans(),
                     st.integers(-10**12, 10**12))


@st.composite
def _mutation(draw):
    """One change to a table: (file, what, arguments)."""
    file = draw(st.sampled_from(["C1", "C1", "C2", "counters"]))
    cols = COUNTER_COLUMNS if file == "counters" else COLUMNS
    kind = draw(st.sampled_from(["cell", "column", "scale", "swap", "rename", "truncate", "reorder", "drop", "bytes"]))
    col, other = draw(st.sampled_from(cols)), draw(st.sampled_from(cols))
    return file, kind, dict(col=col, other=other, value=draw(_value()), row=draw(st.integers(0, 5)),
                            factor=draw(st.sampled_from([1000.0, 1e-3, -1.0])), keep=draw(st.integers(0, 40)),
                            name=draw(st.text(string.ascii_letters + "_ ", min_size=0, max_size=8)),
                            blob=draw(st.sampled_from(["parquet", "utf16", "garbage", "empty"])))


def _apply(df: pd.DataFrame, kind: str, a: dict) -> pd.DataFrame | str:
    """The mutated table, or the name of the bytes to write instead of it."""
    df = df.copy()
    if a["col"] not in df.columns and kind in ("cell", "column", "scale", "drop", "rename"):
        return df  # an earlier mutation renamed or dropped it
    if kind == "cell" and len(df):
        df[a["col"]] = df[a["col"]].astype(object)
        df.iloc[min(a["row"], len(df) - 1), df.columns.get_loc(a["col"])] = a["value"]
    elif kind == "column":
        df[a["col"]] = [a["value"]] * len(df)
    elif kind == "scale" and pd.api.types.is_numeric_dtype(df[a["col"]]):
        df[a["col"]] = df[a["col"]] * a["factor"]
    elif kind == "swap":
        df = df.rename(columns={a["col"]: a["other"], a["other"]: a["col"]})
    elif kind == "rename":
        df = df.rename(columns={a["col"]: a["name"]})
    elif kind == "truncate":
        df = df.iloc[: a["keep"] * (len(df) // 40 + 1)]
    elif kind == "reorder":
        df = df.iloc[::-1] if a["row"] % 2 else df.sample(frac=1.0, random_state=a["row"])
    elif kind == "drop":
        df = df.drop(columns=[a["col"]])
    elif kind == "bytes":
        return a["blob"]
    return df


def _write_blob(path, blob, df):
    if blob == "parquet":
        df.to_parquet(path)  # Parquet bytes under a .csv name
    elif blob == "utf16":
        path.write_text(df.to_csv(index=False), encoding="utf-16")
    elif blob == "garbage":
        path.write_bytes(bytes(range(256)) * 4)
    else:
        path.write_bytes(b"")


def _finite_tables(folder) -> bool:
    for p in folder.glob("*.parquet"):
        num = pd.read_parquet(p).select_dtypes("number")
        if not np.isfinite(num.to_numpy(float)).all():
            return False
    return True


@settings(FUZZ, max_examples=6)
@given(mutations=st.lists(_mutation(), min_size=1, max_size=3))
@pytest.mark.parametrize("_", [0])
def test_a_mutated_campaign_is_a_result_or_a_clear_error(_, mutations, tmp_path_factory, capsys):
    from conftest import tiny_records

    tmp = tmp_path_factory.mktemp("fuzz")
    counters, records = tiny_records()
    blobs = {}
    for file, kind, a in mutations:
        table = counters if file == "counters" else records[file]
        out = _apply(table, kind, a)
        if isinstance(out, str):
            blobs[file] = out
        elif file == "counters":
            counters = out
        else:
            records[file] = out
    folder = write_tiny(tmp / "c", counters, records)
    for file, blob in blobs.items():
        path = folder / ("counters.csv" if file == "counters" else f"timeseries/{file}.csv")
        _write_blob(path, blob, counters if file == "counters" else records[file])
    code = main(["validate", "--campaign", str(folder)])
    text = capsys.readouterr()
    event(f"validate exit {code}")
    assert code in (0, 1), text
    if code == 1:
        assert any(n in text.out for n in ("counters.csv", "timeseries/", "campaign")), text.out
    code = main(["build-db", "--campaign", str(folder), "--out", str(tmp / "db")])
    text = capsys.readouterr()
    event(f"build-db exit {code}")
    assert "Traceback" not in text.err
    if code == 0:
        assert _finite_tables(tmp / "db"), mutations
    else:
        assert code == 2 and str(folder) in text.err, text.err
    shutil.rmtree(tmp)


def _section_fields():
    import dataclasses

    return {f.name: [g.name for g in dataclasses.fields(f.default_factory())]
            for f in dataclasses.fields(ExperimentConfig) if f.default_factory is not dataclasses.MISSING}


SECTIONS = _section_fields()


def _toml_value():
    scalar = st.one_of(st.integers(-10**6, 10**6), st.floats(allow_nan=True, allow_infinity=True),
                       st.text(max_size=6), st.booleans())
    return st.one_of(scalar, st.lists(scalar, max_size=3), st.lists(st.lists(st.integers(-3, 30), max_size=3),
                                                                   max_size=2))


def _typed(section: str, key: str):
    """Values of the field's own type, extremes included (NaN, ±inf, 0, negative, huge)."""
    import dataclasses
    import typing

    cls = next(f.default_factory for f in dataclasses.fields(ExperimentConfig) if f.name == section)
    tp = typing.get_type_hints(cls).get(key)
    number = st.one_of(st.sampled_from([0.0, -1.0, 1e-300, 1e300, math.nan, math.inf, -math.inf]),
                       st.floats(-1e6, 1e6))
    whole = st.one_of(st.sampled_from([0, -1, 1, 2**40]), st.integers(-100, 100))
    if tp is float:
        return number
    if tp is int or tp == (int | None):
        return whole
    if tp is bool:
        return st.booleans()
    if typing.get_origin(tp) is tuple:
        item = typing.get_args(tp)[0]
        return st.lists(number if item is float else whole if item is int else st.text(max_size=4), max_size=3)
    return _toml_value()


@st.composite
def _config(draw):
    data: dict = {}
    for _ in range(draw(st.integers(1, 4))):
        section = draw(st.sampled_from(sorted(SECTIONS) + ["name", "seed", "nonsense"]))
        if section not in SECTIONS:
            data[section] = draw(_toml_value())
            continue
        key = draw(st.one_of(st.sampled_from(SECTIONS[section] or ["x"]), st.text(string.ascii_lowercase + "_",
                                                                                   min_size=1, max_size=10)))
        known = key in SECTIONS[section]
        data.setdefault(section, {})[key] = draw(_typed(section, key) if known and draw(st.booleans())
                                                 else _toml_value())
    return data


def _keys(data, prefix=""):
    for k, v in data.items():
        yield f"{prefix}{k}"
        if isinstance(v, dict):
            yield from _keys(v, f"{prefix}{k}.")


@settings(FUZZ, max_examples=300)
@given(data=_config())
def test_a_random_config_is_a_config_or_an_error_naming_its_key(data):
    try:
        cfg = from_dict(ExperimentConfig, data)
    except ConfigError as e:
        event("refused")
        assert any(k in str(e) for k in _keys(data)), (data, str(e))
        return
    event("a config")
    for v in _floats(cfg):
        assert math.isfinite(v), (data, cfg)


def _floats(obj):
    import dataclasses

    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            yield from _floats(getattr(obj, f.name))
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            yield from _floats(v)
    elif isinstance(obj, float):
        yield obj


@settings(FUZZ, max_examples=15)
@given(analysis=st.dictionaries(st.sampled_from(SECTIONS["analysis"]), st.none(), max_size=3).flatmap(
    lambda keys: st.fixed_dictionaries({k: st.one_of(_typed("analysis", k), _toml_value()) for k in keys})))
@pytest.mark.parametrize("_", [0])
def test_build_db_under_a_random_analysis_section_is_finite_or_a_clear_error(_, analysis, tmp_path_factory, capsys):
    tmp = tmp_path_factory.mktemp("cfg")
    folder = write_tiny(tmp / "c")
    try:
        text = tomli_w.dumps({"analysis": analysis})
    except (TypeError, ValueError):  # not TOML-able (a list of mixed types): a user cannot write it
        return
    (tmp / "cfg.toml").write_text(text)
    code = main(["build-db", "--campaign", str(folder), "--config", str(tmp / "cfg.toml"), "--out", str(tmp / "db")])
    err = capsys.readouterr().err
    event(f"build-db exit {code}")
    assert "Traceback" not in err
    if code == 0:
        assert _finite_tables(tmp / "db"), analysis
    else:
        assert code == 2 and ("cfg.toml" in err or str(folder) in err), (analysis, err)
    shutil.rmtree(tmp)


def _three_axis_campaign(folder, mutations):
    """A micro campaign of four conditions (two level flights in the cruise band, a pull-up
    and a turn) with both horizontal axes, each changed by `mutations`: (axis, kind, record)."""
    from conftest import tiny_records

    counters, records = tiny_records(n_counters=4)
    counters["maneuver"] = ["level", "level", "pullup", "turn"]
    for i, (name, df) in enumerate(records.items()):
        df["airspeed_kt"] = 125.0 + 3 * i  # advance ratio about 0.29: within the cruise band
        df["ax_g"] = 0.4 * (df.az_g - 1.0)
        df["ay_g"] = 0.6 * (df.az_g - 1.0) + 0.01 * np.cos(np.arange(len(df)) / 64 * 2 * np.pi)
    for axis, kind, record in mutations:
        df = records[record]
        if axis not in df:  # an earlier mutation dropped it
            continue
        if kind == "drop":
            records[record] = df.drop(columns=axis)
        elif kind == "zero":
            df[axis] = 0.0
        elif kind == "m/s2":
            df[axis] = 9.80665 * df[axis]
        elif kind == "swap":
            df[[axis, "az_g"]] = df[["az_g", axis]].to_numpy()
        elif kind == "nan":
            df.loc[5, axis] = np.nan
    return write_tiny(folder, counters, records)


def _snapshot(*folders) -> dict:
    import hashlib

    return {str(p): hashlib.sha256(p.read_bytes()).hexdigest() for f in folders for p in sorted(f.rglob("*"))
            if p.is_file()}


@st.composite
def _study_config(draw):
    """A `[dynamic]` or `[axes]` section of small settings with one or two keys drawn from the
    section's own type, extremes included, and the axis analysed drawn too."""
    section = draw(st.sampled_from(["dynamic", "axes"]))
    base = (dict(models=["window_static", "dynamic"], seeds=1, folds=3, kind_holdout=False, hidden=[3])
            if section == "dynamic" else dict(databases=["db1"], seeds=1, folds=3, hidden=[3], discovery=False))
    for key in draw(st.lists(st.sampled_from(SECTIONS[section]), max_size=2, unique=True)):
        base[key] = draw(_typed(section, key))
    data = {section: base, "train": dict(max_steps=20, eval_every=10, patience=1)}
    if draw(st.booleans()):
        data["analysis"] = dict(axis=draw(st.sampled_from(["az_g", "ax_g", "ay_g"])))
    return section, data


@pytest.mark.check
@settings(FUZZ, max_examples=8)
@given(study=_study_config(), mutations=st.lists(st.tuples(st.sampled_from(["ax_g", "ay_g"]),
                                                           st.sampled_from(["drop", "zero", "m/s2", "swap", "nan"]),
                                                           st.sampled_from(["C1", "C2", "C3", "C4"])), max_size=2))
@pytest.mark.parametrize("_", [0])
def test_a_random_study_on_a_mutated_three_axis_campaign_is_a_sound_result_or_a_clear_error(_, study, mutations,
                                                                                          tmp_path_factory, capsys):
    tmp = tmp_path_factory.mktemp("study")
    section, data = study
    folder = _three_axis_campaign(tmp / "c", mutations)
    try:
        (tmp / "cfg.toml").write_text(tomli_w.dumps(data))
    except (TypeError, ValueError):  # not TOML-able: a user cannot write it
        return
    before = _snapshot(folder, tmp / "cfg.toml")
    code = main([section, "--campaign", str(folder), "--config", str(tmp / "cfg.toml"), "--out", str(tmp / "o")])
    err = capsys.readouterr().err
    event(f"{section} exit {code}")
    assert "Traceback" not in err and code in (0, 2), err
    assert _snapshot(folder, tmp / "cfg.toml") == before  # no user file changed, moved or added
    if code == 2:
        assert "cfg.toml" in err or str(folder) in err or "." in err.split("error: ")[-1].split(" ")[0], err
    elif section == "dynamic":
        table = pd.read_csv(tmp / "o" / "comparison.csv", keep_default_na=False, na_values=[""])
        best = table[table.best]
        assert len(best) <= 1 and (best.degenerate.isna() | (best.degenerate == "")).all(), table
        assert np.isfinite(best.rms_g).all()
    else:
        table = pd.read_csv(tmp / "o" / "axes.csv", keep_default_na=False)
        sound = table.status.eq("no vibration") | table.faa_pass_share.astype(float).between(0, 1)
        assert sound.all() and np.isfinite(table.rms_g.astype(float)).all(), table
    shutil.rmtree(tmp)
