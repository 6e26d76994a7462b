import subprocess
import sys

import pytest

from pvvjax.cli import build_parser, main

COMMANDS = ["validate", "build-db", "synth", "plot", "run"]


def test_every_subcommand_has_help():
    parser = build_parser()
    for cmd in COMMANDS:
        with pytest.raises(SystemExit) as e:
            parser.parse_args([cmd, "--help"])
        assert e.value.code == 0


def test_console_script_help():
    out = subprocess.run([sys.executable, "-m", "pvvjax.cli", "--help"], capture_output=True, text=True)
    assert out.returncode == 0
    for cmd in COMMANDS:
        assert cmd in out.stdout


def test_main_job_on_the_embedded_campaign(tmp_path, capsys, default_campaign_dir):
    cfg = tmp_path / "paper.toml"
    cfg.write_text(f'name = "t"\nout_dir = "{tmp_path.as_posix()}"\n[analysis]\nwindow_revs = 8.0\n')
    assert main(["run", str(cfg)]) == 0
    out = capsys.readouterr().out
    assert "232 conditions" in out and "11022" in out and f"results in {tmp_path.as_posix()}/t" in out
    for name in ("db1", "db2", "db3", "peaks"):
        assert (tmp_path / "t" / "databases" / f"{name}.parquet").exists()
    assert (tmp_path / "t" / "figures" / "pullup_11022.png").exists()


def test_missing_campaign_folder_is_a_clear_error(tmp_path, capsys):
    assert main(["build-db", str(tmp_path / "nope"), "--out", str(tmp_path / "o")]) == 2
    assert "campaign folder not found" in capsys.readouterr().err
