"""Results a user can trust: a results folder belongs to one config and one campaign, and a
changed campaign is never taken for the one a result came from. Each through the CLI."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pandas as pd
import pytest
from conftest import small_sweep_config

from pvvjax.cli import main
from pvvjax.data import campaign_fingerprint
from pvvjax.io import ResultsFolderError, claim_folder, folder_kind
from pvvjax.nets.sweep import finished_sweep

_SWEEP = '''name = "r"\nout_dir = "{out}"\n[campaign]\npath = "{campaign}"
[sweep]\ndatabases = ["db1"]\nfamily = "rbf"\ncenters = [{centers}]\nseeds = 1\nfolds = 3\n'''


def _sweep(tmp_path, campaign, centers=6, name="cfg.toml"):
    cfg = tmp_path / name
    cfg.write_text(_SWEEP.format(out=tmp_path.as_posix(), campaign=campaign.as_posix(), centers=centers))
    return cfg


def _run(argv, capsys):
    code = main(argv)
    out = capsys.readouterr()
    assert "Traceback" not in out.out + out.err
    return code, out.out + out.err


@pytest.fixture
def campaign_copy(tmp_path, small_campaign_dir):
    return shutil.copytree(small_campaign_dir, tmp_path / "campaign")


def test_a_second_config_is_refused_in_a_sweep_folder_naming_the_setting(tmp_path, campaign_copy, capsys):
    out = tmp_path / "sweep"
    assert _run(["sweep", str(_sweep(tmp_path, campaign_copy)), "--out", str(out)], capsys)[0] == 0
    rows = len(pd.read_parquet(out / "results.parquet"))
    other = _sweep(tmp_path, campaign_copy, name="b.toml")
    other.write_text(other.read_text() + "split_seed = 3\n")
    code, text = _run(["sweep", str(other), "--out", str(out)], capsys)
    assert code == 2 and "sweep.split_seed" in text and str(out) in text and "another output folder" in text, text
    assert len(pd.read_parquet(out / "results.parquet")) == rows  # nothing mixed in
    code, text = _run(["sweep", str(_sweep(tmp_path, campaign_copy)), "--out", str(out)], capsys)
    assert code == 0 and "3 already finished, 0 to train" in text, text


def test_a_campaign_changed_in_place_is_never_already_finished(tmp_path, campaign_copy, capsys):
    cfg = _sweep(tmp_path, campaign_copy)
    before = campaign_fingerprint(campaign_copy)
    assert _run(["sweep", str(cfg), "--out", str(tmp_path / "a")], capsys)[0] == 0
    first = pd.read_parquet(tmp_path / "a" / "results.parquet")
    # Regenerated at the same path: one record's vibration changes (its size need not).
    p = next((campaign_copy / "timeseries").glob("*.parquet"))
    df = pd.read_parquet(p)
    df["az_g"] = 1.0 + (df.az_g - 1.0) * 1.5
    df.to_parquet(p, index=False)
    assert campaign_fingerprint(campaign_copy) != before
    code, text = _run(["sweep", str(cfg), "--out", str(tmp_path / "a")], capsys)
    assert code == 2 and "campaign content" in text, text
    assert _run(["sweep", str(cfg), "--out", str(tmp_path / "b")], capsys)[0] == 0
    second = pd.read_parquet(tmp_path / "b" / "results.parquet")
    assert not set(first.net_id) & set(second.net_id)
    assert not set(first.config_hash) & set(second.config_hash)


def test_the_fingerprint_is_the_content_not_the_place_or_the_time(tmp_path, campaign_copy):
    a = campaign_fingerprint(campaign_copy)
    moved = shutil.copytree(campaign_copy, tmp_path / "elsewhere")
    for p in (moved / "timeseries").iterdir():
        p.touch()  # new mtimes, same bytes
    assert campaign_fingerprint(moved) == a


def test_claims_resume_the_same_settings_and_refuse_files_and_foreign_folders(tmp_path):
    assert claim_folder(tmp_path / "o", {"a": 1}, "f") == tmp_path / "o"
    assert claim_folder(tmp_path / "o", {"a": 1}, "f") == tmp_path / "o"
    with pytest.raises(ResultsFolderError, match="a: 1 there, 2 now"):
        claim_folder(tmp_path / "o", {"a": 2}, "f")
    (tmp_path / "file").write_text("x")
    with pytest.raises(ResultsFolderError, match="is a file"):
        claim_folder(tmp_path / "file", {}, "")
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("x")
    with pytest.raises(ResultsFolderError, match="not pvvjax's to write into"):
        claim_folder(tmp_path / "mine", {}, "")
    # A folder is pvvjax's only if its marker says so: a user's folder that holds a config.toml and
    # results-like files is refused, never moved aside or written into.
    (tmp_path / "user" / "parts").mkdir(parents=True)
    for name in ("config.toml", "results.parquet", "notes.md"):
        (tmp_path / "user" / name).write_text("x")
    before = sorted(p.name for p in (tmp_path / "user").iterdir())
    with pytest.raises(ResultsFolderError, match="has no owner.json"):
        claim_folder(tmp_path / "user", {"a": 1}, "f")
    assert sorted(p.name for p in (tmp_path / "user").iterdir()) == before and not (tmp_path / "user.old").exists()
    # A folder holding only results folders (a sweep run into OUT_DIR/NAME/sweep) is a job's to claim.
    claim_folder(tmp_path / "job" / "sweep", {"s": 1}, "f")
    assert claim_folder(tmp_path / "job", {"a": 1}, "f") == tmp_path / "job"
    assert sorted(p.name for p in (tmp_path / "job").iterdir()) == ["owner.json", "sweep"]
    (tmp_path / "job2" / "mine").mkdir(parents=True)  # a user's folder among them: refused
    with pytest.raises(ResultsFolderError, match="not pvvjax's to write into"):
        claim_folder(tmp_path / "job2", {}, "")


def test_a_folder_knows_its_kind_and_is_diagnosed_by_it(tmp_path):
    claim_folder(tmp_path / "dyn", {"a": 1}, "f", kind="dynamic")
    (tmp_path / "dyn" / "parts").mkdir()
    (tmp_path / "dyn" / "config.toml").write_text("x")
    assert folder_kind(tmp_path / "dyn") == "dynamic" and folder_kind(tmp_path) is None
    with pytest.raises(ResultsFolderError, match="results of `pvvjax dynamic`, not of `pvvjax sweep`"):
        claim_folder(tmp_path / "dyn", {"a": 1}, "f", kind="sweep")
    with pytest.raises(FileNotFoundError, match="results of `pvvjax dynamic`, not a sweep") as err:
        finished_sweep(tmp_path / "dyn")
    assert "delete" not in str(err.value) and "unfinished" not in str(err.value)
    # A record written before kinds: the same settings resume and the kind is added.
    (tmp_path / "pre").mkdir()
    (tmp_path / "pre" / "owner.json").write_text(json.dumps({"settings": {"a": 1}, "campaign": "f"}))
    assert claim_folder(tmp_path / "pre", {"a": 1}, "f", kind="sweep") == tmp_path / "pre"
    assert folder_kind(tmp_path / "pre") == "sweep"
    with pytest.raises(ResultsFolderError) as err:
        claim_folder(tmp_path / "pre", {"a": 2}, "f", kind="sweep")
    assert "delete" not in str(err.value)


def test_the_main_jobs_sweep_folder_exports_an_element(tmp_path, campaign_copy, small_sweep, capsys):
    # A sweep folder trained elsewhere (the shared small sweep), on a copy of its campaign: the
    # claim is the campaign's content, so the sweep resumes there with nothing to train.
    cfg = small_sweep_config(tmp_path / "cfg.toml", tmp_path, campaign_copy, name="r")
    shutil.copytree(small_sweep, tmp_path / "r" / "sweep")
    code, text = _run(["sweep", str(cfg)], capsys)  # into OUT_DIR/NAME/sweep, as the main job does
    assert code == 0 and "6 already finished, 0 to train" in text, text
    code, text = _run(["export", str(tmp_path / "r" / "sweep"), "--element", "--out", str(tmp_path / "el")], capsys)
    assert code == 0 and (tmp_path / "el").is_dir(), text
    assert np.isfinite(pd.read_parquet(tmp_path / "r" / "sweep" / "results.parquet").test_rms_g).all()


def test_campaign_given_on_the_command_line_replaces_the_configs(tmp_path, campaign_copy, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(_SWEEP.format(out=tmp_path.as_posix(), campaign="/nowhere", centers=6))
    code, text = _run(["sweep", str(cfg), "--out", str(tmp_path / "s")], capsys)
    assert code == 2 and "/nowhere" in text
    assert _run(["sweep", str(cfg), "--campaign", str(campaign_copy), "--out", str(tmp_path / "s")], capsys)[0] == 0


def test_a_relative_campaign_path_is_recorded_absolute(tmp_path, monkeypatch, capsys):
    # The config names the campaign relative to where the command runs; the results record
    # it absolute, so that reading them from another folder finds the same campaign.
    from conftest import write_tiny

    from pvvjax.config import load_config

    monkeypatch.chdir(tmp_path)
    write_tiny(tmp_path / "camp")
    (tmp_path / "cfg.toml").write_text('[campaign]\npath = "camp"\n')
    assert main(["build-db", "--config", "cfg.toml", "--out", "dbs"]) == 0
    capsys.readouterr()
    assert load_config(tmp_path / "dbs" / "config.toml").campaign.path == str(tmp_path / "camp")
