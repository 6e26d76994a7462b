import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from conftest import small_job_config, small_sweep_config

from pvvjax import _apidoc
from pvvjax.cli import build_parser, main
from pvvjax.data.campaign import load_campaign

COMMANDS = ["validate", "build-db", "synth", "plot", "sweep", "export", "replay", "calibrate", "realtime", "discover",
            "run"]


def test_every_subcommand_has_help():
    parser = build_parser()
    for cmd in COMMANDS:
        with pytest.raises(SystemExit) as e:
            parser.parse_args([cmd, "--help"])
        assert e.value.code == 0


@pytest.mark.check
def test_console_script_help():
    out = subprocess.run([sys.executable, "-m", "pvvjax.cli", "--help"], capture_output=True, text=True)
    assert out.returncode == 0
    for cmd in COMMANDS:
        assert cmd in out.stdout


@pytest.mark.check
@pytest.mark.heavy
def test_main_job_on_the_embedded_campaign(tmp_path, capsys, default_campaign_dir):
    cfg = tmp_path / "paper.toml"
    cfg.write_text(f'name = "t"\nout_dir = "{tmp_path.as_posix()}"\n[analysis]\nwindow_revs = 8.0\n')
    assert main(["run", str(cfg)]) == 0
    out = capsys.readouterr().out
    assert "232 conditions" in out and "11022" in out and f"results in {tmp_path.as_posix()}/t" in out
    for name in ("db1", "db2", "db3", "peaks"):
        assert (tmp_path / "t" / "databases" / f"{name}.parquet").exists()
    assert (tmp_path / "t" / "figures" / "pullup_11022.png").exists()
    html = (tmp_path / "t" / "report.html").read_text()
    assert "<table" not in html or "</table>" in html
    assert 'src="figures/pullup_11022.png"' in html and "T1-level-135" in html


def test_missing_campaign_folder_is_a_clear_error(tmp_path, capsys):
    assert main(["build-db", "--campaign", str(tmp_path / "nope"), "--out", str(tmp_path / "o")]) == 2
    assert "campaign folder not found" in capsys.readouterr().err


def test_discover_on_fewer_conditions_than_folds_names_the_setting_and_the_campaign(tmp_path, capsys):
    from conftest import write_tiny

    folder = write_tiny(tmp_path / "two")  # 2 conditions, 5 folds by default
    assert main(["discover", "--campaign", str(folder), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert f"discovery.ensemble.folds (campaign {folder}, db1) = 5" in err and "number of conditions (2)" in err


@pytest.mark.check
@pytest.mark.heavy
def test_sweep_then_export_a_numpy_net(tmp_path, small_campaign_dir, small_sweep, capsys):
    # The shared small sweep (trained once by `pvvjax sweep`), resumed here with one database
    # and fold of its axes: nothing left to train.
    cfg = small_sweep_config(tmp_path / "s.toml", tmp_path, small_campaign_dir, databases=("db1",), test_folds=(0,))
    shutil.copytree(small_sweep, tmp_path / "s" / "sweep")
    assert main(["sweep", str(cfg)]) == 0
    assert "1 already finished, 0 to train" in capsys.readouterr().out
    assert main(["export", str(tmp_path / "s" / "sweep"), "--out", str(tmp_path / "exp")]) == 0
    code = ("import sys; sys.path.insert(0, sys.argv[1]); from npnet import NumpyNet; "
            "net = NumpyNet.load(sys.argv[1] + '/net.npz'); "
            "print(float(net([0.27, 16055, 255, 1.0, 2.0, 0])), 'jax' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "exp")], capture_output=True, text=True,
                         cwd=tmp_path)
    value, jax_loaded = out.stdout.split()
    assert 0.0 < float(value) < 1.0 and jax_loaded == "False"
    # The same sweep as a real-time element, played by the example host.
    assert main(["export", str(tmp_path / "s" / "sweep"), "--element", "--offset", "0.5", "--out",
                 str(tmp_path / "el")]) == 0
    counter = next(c for c in load_campaign(small_campaign_dir).counters.index if c == "11022")
    assert main(["realtime", "--model", str(tmp_path / "el"), "--record", counter, "--campaign",
                 str(small_campaign_dir), "--rate", "200", "--jitter", "0.3", "--out", str(tmp_path / "s.csv")]) == 0
    assert "latency per frame median" in capsys.readouterr().out
    import pandas as pd

    sig = pd.read_csv(tmp_path / "s.csv")
    assert sig.pvv_g.notna().all() and sig.pvv_g.max() > 0.05 and sig.shake_g.abs().max() > 0.0


def test_replay_config_mistakes_are_clear_errors(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the configs' default results folder, runs/experiment, goes here
    cfg = tmp_path / "bad.toml"
    cfg.write_text('[calibration]\nfree = ["offset"]\n')
    assert main(["calibrate", str(cfg)]) == 2
    assert "calibration.free" in capsys.readouterr().err
    cfg.write_text('[replay]\nsweep = "/nonexistent"\n')
    assert main(["replay", str(cfg)]) == 2
    assert "replay.sweep: /nonexistent: no such folder" in capsys.readouterr().err


def test_cli_reference_in_the_docs_is_current():
    from pvvjax.cli import cli_reference

    doc = Path(__file__).parents[1] / "docs" / "cli.md"
    assert doc.read_text() == cli_reference(), "regenerate with: python experiments/reference_docs.py --docs"


def _job_config(tmp_path, campaign, small_sweep, studies: bool) -> Path:
    """The main job's config with networks on the small campaign (`small_job_config`)."""
    return small_job_config(tmp_path, campaign, small_sweep,
                            run=f"[run]\nnetworks = true\nhtml = false\nstudies = {str(studies).lower()}\n")


def _main_job_with_networks(tmp_path, campaign, small_sweep, capsys, studies: bool):
    """The main job with networks on the small campaign: its config and report."""
    cfg = _job_config(tmp_path, campaign, small_sweep, studies)
    assert main(["run", str(cfg)]) == 0
    out = capsys.readouterr().out
    assert f"[4/{5 + studies}] networks" in out and "6 already finished, 0 to train" in out
    report = (tmp_path / "p" / "report.md").read_text()
    assert "| zero offset | db1 | 0.000 |" in report and "figures/fig13a_replay_11022.png" in report
    assert "| condition | paper test | test | paper db1 | db1 | paper db3 | db3 |" in report
    assert "| T1-level-135 | 0.100 |" in report and "figures/fig10_correlation_db1.png" in report
    assert (tmp_path / "p" / "figures" / "fig12_correlation_db3.png").exists()
    assert not (tmp_path / "p" / "report.html").exists()
    return cfg, report


@pytest.mark.check
@pytest.mark.heavy
def test_main_job_with_networks_reports_beside_the_paper(tmp_path, small_campaign_dir, small_sweep, capsys):
    # The micro twin of the research check below, without the studies (their twin:
    # tests/test_replay.py): the report beside the paper; the replay folder is the job's.
    cfg, report = _main_job_with_networks(tmp_path, small_campaign_dir, small_sweep, capsys, studies=False)
    checks = pd.read_csv(tmp_path / "p" / "paper_comparison.csv")
    assert checks[checks.item == "peak PVV, g"].iloc[0].agrees == "yes" and "## Window length" not in report
    assert main(["replay", str(cfg), "--offset", "0.5", "--plots", "1"]) == 2
    assert "part of the results folder" in capsys.readouterr().err


@pytest.mark.check
@pytest.mark.heavy
def test_replay_and_calibrate_commands_on_the_jobs_config(tmp_path, small_campaign_dir, small_sweep):
    # The research check's replay and calibrate commands, on the job's config without the job:
    # a replay at a given offset, one offset per maneuver kind, into folders of their own.
    cfg = _job_config(tmp_path, small_campaign_dir, small_sweep, studies=False)
    assert main(["replay", str(cfg), "--offset", "0.5", "--plots", "1", "--out", str(tmp_path / "replay")]) == 0
    summary = pd.read_csv(tmp_path / "replay" / "summary.csv")
    kinds = {"pullup", "pushover", "roll", "autorotation", "flare"}
    assert set(summary.maneuver) == kinds and (summary.offset_s == 0.5).all()
    assert set(summary.database) == {"db1", "db3"} and len(list((tmp_path / "replay").glob("replay_*.png"))) == 1
    assert main(["calibrate", str(cfg), "--groups", "maneuver", "--free", "offset_s", "--out",
                 str(tmp_path / "calibration")]) == 0
    cal = pd.read_csv(tmp_path / "calibration" / "calibration.csv")
    assert set(cal.group) == kinds and cal.offset_s.between(-1.0, 3.0).all() and cal.within_one_grid_step.all()
    assert (tmp_path / "calibration" / f"cost_map_db1_{cal.group[0]}.png").exists()


@pytest.mark.check
def test_main_job_with_networks_reports_table1_beside_the_paper(tmp_path, small_campaign_dir, small_sweep, capsys):
    cfg, report = _main_job_with_networks(tmp_path, small_campaign_dir, small_sweep, capsys, studies=True)
    # Every paper number in one table; Figs 1-9 one file each
    checks = pd.read_csv(tmp_path / "p" / "paper_comparison.csv")
    assert {"databases", "networks (Figs 10-12, Table 1)", "replay of the pull-up 11022 (Figs 13-14)"} <= set(
        checks.section)
    row = checks[checks.item == "peak PVV, g"].iloc[0]
    assert row.paper == "0.220" and row.agrees == "yes"
    assert "## Every number beside the paper's" in report
    for n in range(1, 10):
        assert f"**Fig. {n}." in report
    # Studies: each kind's own offset does at least as well on that kind as the common one, and the
    # gradient optimum of (offset, window length) is no worse than the brute-force grid's best point
    kinds = pd.read_csv(tmp_path / "p" / "studies" / "offset_per_kind.csv")
    cost = kinds.pivot_table(index=["database", "maneuver"], columns="offsets", values="cost")
    assert (cost["one per kind"] <= cost["one for all"] * 1.01 + 1e-6).all()
    wl = pd.read_csv(tmp_path / "p" / "studies" / "window_length.csv")
    assert (wl.gradient_cost <= wl.grid_cost * 1.02).all() and len(wl) == 4
    assert "## Window length" in report and "figures/window_length.png" in report
    # The replay and calibrate commands on the same config use the main job's nets (the sweep
    # resumes): a replay at a given offset, and one offset per maneuver kind (the study's fit),
    # each within a step of the brute-force grid's best, with the first group's cost map.
    # Their results go to folders of their own: the main job's replay folder holds its settings'.
    out = tmp_path / "p"
    assert main(["replay", str(cfg), "--offset", "0.5", "--plots", "1"]) == 2
    assert "part of the results folder" in capsys.readouterr().err
    assert main(["replay", str(cfg), "--offset", "0.5", "--plots", "1", "--out", str(tmp_path / "replay")]) == 0
    summary = pd.read_csv(tmp_path / "replay" / "summary.csv")
    assert set(summary.maneuver) == set(kinds.maneuver) and (summary.offset_s == 0.5).all()
    assert set(summary.database) == {"db1", "db3"} and len(list((tmp_path / "replay").glob("replay_*.png"))) == 1
    assert main(["calibrate", str(cfg), "--groups", "maneuver", "--free", "offset_s", "--out",
                 str(tmp_path / "calibration")]) == 0
    cal = pd.read_csv(tmp_path / "calibration" / "calibration.csv")
    fit = pd.read_csv(out / "studies" / "offset_per_kind_fit.csv")
    assert set(cal.group) == set(kinds.maneuver) and (cal.groups == "maneuver").all()
    assert cal.offset_s.between(-1.0, 3.0).all() and cal.within_one_grid_step.all()
    pd.testing.assert_series_equal(cal.sort_values(["database", "group"]).offset_s.reset_index(drop=True),
                                   fit.sort_values(["database", "group"]).offset_s.reset_index(drop=True))
    assert (tmp_path / "calibration" / f"cost_map_db1_{cal.group[0]}.png").exists()


def test_api_reference_is_current_and_covers_every_public_module():
    MODULES, api_reference = _apidoc.MODULES, _apidoc.api_reference

    text = api_reference()
    doc = Path(__file__).parents[1] / "docs" / "api.md"
    assert doc.read_text() == text, "regenerate with: python experiments/reference_docs.py --docs"
    package = Path(__file__).parents[1] / "pvvjax"
    public = {".".join(p.relative_to(package).with_suffix("").parts) for p in package.rglob("*.py")
              if not any(part.startswith("_") for part in p.relative_to(package).parts)}
    holds_private = {p.parent.name for p in package.glob("*/_*.py") if p.name != "__init__.py"}  # synth, discovery
    assert public | holds_private == set(MODULES), "add the new module to pvvjax._apidoc.MODULES"
    assert "### `discovery.discover` (function; also `pvvjax.discover`)" in text


def test_no_module_defines_a_name_twice():
    # A second `def` of a module-level name silently replaces the first for every caller (a
    # helper added under a name the module already used broke every discovery once).
    import ast
    from collections import Counter

    package = Path(__file__).parents[1] / "pvvjax"
    twice = {}
    for path in package.rglob("*.py"):
        body = ast.parse(path.read_text()).body
        names = Counter(n.name for n in body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)))
        twice.update({f"{path.relative_to(package)}:{k}": v for k, v in names.items() if v > 1})
    assert not twice, twice


def test_a_replay_whose_offset_leaves_no_window_is_a_clear_error(tmp_path, small_campaign_dir, small_sweep, capsys):
    cfg = tmp_path / "r.toml"
    cfg.write_text(f'[replay]\nsweep = "{small_sweep.as_posix()}"\ndatabases = ["db1"]\n')
    assert main(["replay", str(cfg), "--campaign", str(small_campaign_dir), "--offset", "-100", "--counters", "11022",
                 "--out", str(tmp_path / "r")]) == 2
    assert "offset -100 s, window 8 revs: no window of any counter lies within its record" in capsys.readouterr().err
    assert not (tmp_path / "r" / "windows.parquet").exists()
