"""Every command's code path in process, on micro inputs: the fast lane's integration test of
the commands that `make test` would otherwise only see refuse bad input. Each runs the
command's `main` on the small campaign and the shared small sweep (already trained, so a
command on its config resumes it), with the fewest steps that still give a result, and checks
what it writes. The whole-command runs at their own settings (the README's blocks, the
notebooks, the main job with networks, JSBSim's flights) are in the check lane."""

import numpy as np
import pandas as pd
import pytest
from conftest import small_job_config

from pvvjax.cli import main


@pytest.fixture
def job(tmp_path, small_campaign_dir, small_sweep):
    """The main job's config on the small campaign, replaying db1, whose sweep folder holds
    the shared small sweep: replay and calibrate resume it with nothing to train."""
    return small_job_config(tmp_path, small_campaign_dir, small_sweep, replay_databases=("db1",))


def test_the_main_job_builds_the_databases_and_reports_them(tmp_path, small_campaign_dir, capsys):
    # Its research twin runs it on the embedded campaign (tests/test_cli.py).
    cfg = tmp_path / "j.toml"
    cfg.write_text(f'name = "j"\nout_dir = "{tmp_path.as_posix()}"\n'
                   f'[campaign]\npath = "{small_campaign_dir.as_posix()}"\n[run]\nhtml = false\n')
    assert main(["run", str(cfg)]) == 0
    assert f"results in {tmp_path.as_posix()}/j" in capsys.readouterr().out
    for name in ("db1", "db2", "db3", "peaks"):
        assert (tmp_path / "j" / "databases" / f"{name}.parquet").exists()
    report = (tmp_path / "j" / "report.md").read_text()
    assert "figures/pullup_11022.png" in report and (tmp_path / "j" / "figures" / "pullup_11022.png").exists()


def test_plot_draws_the_campaigns_figures(tmp_path, small_campaign_dir):
    assert main(["plot", "--campaign", str(small_campaign_dir), "--out", str(tmp_path / "fig")]) == 0
    figures = list((tmp_path / "fig").glob("*.png"))
    assert figures and all(f.stat().st_size > 5_000 for f in figures)


def test_sweep_resumes_exports_an_element_and_realtime_streams_it(job, tmp_path, small_campaign_dir, capsys):
    assert main(["sweep", str(job)]) == 0
    assert "already finished, 0 to train" in capsys.readouterr().out
    sweep = tmp_path / "p" / "sweep"
    assert main(["export", str(sweep), "--out", str(tmp_path / "net")]) == 0
    assert (tmp_path / "net" / "net.npz").exists() and (tmp_path / "net" / "npnet.py").exists()
    assert main(["export", str(sweep), "--element", "--offset", "0.5", "--out", str(tmp_path / "el")]) == 0
    assert main(["realtime", "--model", str(tmp_path / "el"), "--record", "11022", "--campaign",
                 str(small_campaign_dir), "--rate", "200", "--out", str(tmp_path / "s.csv")]) == 0
    assert "latency per frame median" in capsys.readouterr().out
    sig = pd.read_csv(tmp_path / "s.csv")
    assert sig.pvv_g.notna().all() and sig.pvv_g.max() > 0.05 and sig.shake_g.abs().max() > 0.0


def test_replay_and_calibrate_write_their_tables(job, tmp_path):
    assert main(["replay", str(job), "--offset", "0.5", "--counters", "11022", "--plots", "1",
                 "--out", str(tmp_path / "replay")]) == 0
    summary = pd.read_csv(tmp_path / "replay" / "summary.csv")
    assert list(summary.counter.astype(str)) == ["11022"] and (summary.offset_s == 0.5).all()
    assert len(list((tmp_path / "replay").glob("replay_*.png"))) == 1
    assert main(["calibrate", str(job), "--groups", "all", "--free", "offset_s", "--out",
                 str(tmp_path / "calibration")]) == 0
    cal = pd.read_csv(tmp_path / "calibration" / "calibration.csv")
    assert len(cal) == 1 and cal.offset_s.between(-1.0, 3.0).all() and cal.within_one_grid_step.all()
    assert "at_bound" in cal  # a parameter stopped on its bound is named there (empty: none)


def test_dynamic_compares_its_models_and_exports_the_best(tmp_path, small_campaign_dir):
    (tmp_path / "d.toml").write_text('[train]\nmax_steps = 50\neval_every = 25\n[dynamic]\nseeds = 1\nfolds = 3\n'
                                     'models = ["quasi_static", "window_static"]\nkind_holdout = false\n')
    assert main(["dynamic", "--campaign", str(small_campaign_dir), "--out", str(tmp_path / "dyn"), "--config",
                 str(tmp_path / "d.toml")]) == 0
    table = pd.read_csv(tmp_path / "dyn" / "comparison.csv")
    assert list(table.model) == ["quasi_static", "window_static"] and table.best.sum() == 1
    assert np.isfinite(table.rms_g).all() and (tmp_path / "dyn" / "report.md").exists()
    assert main(["export", str(tmp_path / "dyn"), "--element", "--out", str(tmp_path / "el")]) == 0
    assert (tmp_path / "el" / "element.json").exists()


def test_axes_scores_every_axis(tmp_path, small_campaign_dir):
    (tmp_path / "a.toml").write_text('[axes]\ndatabases = ["db1"]\nseeds = 1\nfolds = 3\nhidden = [4]\n'
                                     '[train]\nmax_steps = 100\neval_every = 50\n')
    assert main(["axes", "--campaign", str(small_campaign_dir), "--config", str(tmp_path / "a.toml"), "--out",
                 str(tmp_path / "ax"), "--no-discovery"]) == 0
    table = pd.read_csv(tmp_path / "ax" / "axes.csv")
    assert list(table.axis) == ["az_g", "ax_g", "ay_g"] and (table.rms_g > 0).all()
    assert (tmp_path / "ax" / "report.md").exists()


def test_an_element_that_never_becomes_ready_is_named_in_a_warning():
    from types import SimpleNamespace

    from pvvjax.realtime import stream

    class Waiting:  # an element whose first window never completes
        def step(self, t, az, x):
            return SimpleNamespace(pvv_g=0.0, ready=False)

    t = np.linspace(0.0, 0.5, 11)
    with pytest.warns(UserWarning, match="never became ready on record C1"):
        out, lat = stream(Waiting(), t, np.zeros(11), np.zeros((11, 2)), ["pvv_g"], "record C1")
    assert out.shape == (11, 1) and (lat >= 0).all()
