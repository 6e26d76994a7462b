"""No command writes over a file it did not write: each command's output, given as a
user's file, a folder of the user's files, the campaign folder or a folder inside it, is
refused by name (exit 2) and leaves every file as it was."""

import hashlib
from pathlib import Path

import pytest
from conftest import write_tiny

from pvvjax.cli import main
from pvvjax.io import ResultsFolderError, new_file, own_folder
from pvvjax.synth import SynthConfig, write_synthetic


def _snapshot(folder: Path) -> dict:
    return {p.relative_to(folder): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def _argv(command, out, camp, tmp_path, small_sweep):
    cfg = tmp_path / "cfg.toml"
    return {
        "build-db": ["build-db", "--campaign", camp, "--out", out],
        "plot": ["plot", "--campaign", camp, "--out", out],
        "synth": ["synth", "--out", out],
        "synth --plots": ["synth", "--out", tmp_path / "new", "--plots", out],
        "synth --truth": ["synth", "--out", tmp_path / "new", "--truth", out],
        "sweep": ["sweep", cfg, "--campaign", camp, "--out", out],
        "export": ["export", small_sweep, "--out", out],
        "export --element": ["export", small_sweep, "--element", "--out", out],
        "realtime": ["realtime", "--model", tmp_path / "no-element", "--record", "C1", "--campaign", camp, "--out",
                     out],
        "replay": ["replay", cfg, "--campaign", camp, "--out", out],
        "calibrate": ["calibrate", cfg, "--campaign", camp, "--out", out],
        "discover": ["discover", "--campaign", camp, "--out", out],
    }[command]


WRITERS = ["build-db", "plot", "synth", "synth --plots", "synth --truth", "sweep", "export", "export --element",
           "realtime", "replay", "calibrate", "discover"]


@pytest.mark.parametrize("command", WRITERS)
def test_a_commands_output_over_a_users_files_or_a_campaign_is_refused(command, tmp_path, small_sweep, capsys):
    camp = write_tiny(tmp_path / "campaign")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("my notes")
    (mine / "sub").mkdir()
    (mine / "sub" / "data.csv").write_text("a,b\n1,2\n")
    (tmp_path / "cfg.toml").write_text(f'name = "x"\nout_dir = "{(tmp_path / "runs").as_posix()}"\n')
    before = _snapshot(tmp_path)
    single_file = command in ("realtime", "synth --truth")
    outs = [mine / "notes.txt", camp, camp / "results"] + ([] if single_file else [mine])
    for out in outs:
        argv = [str(a) for a in _argv(command, out, camp, tmp_path, small_sweep)]
        assert main(argv) == 2, (command, out)
        err = capsys.readouterr().err
        assert str(out) in err and "Traceback" not in err, (command, out, err)
        assert _snapshot(tmp_path) == before, (command, out)
    assert not (camp / "results").exists()


def test_the_main_job_refuses_a_campaign_folder_or_a_users_file_as_its_results(tmp_path, capsys):
    camp = write_tiny(tmp_path / "campaign")
    (tmp_path / "notes").write_text("mine")
    before = _snapshot(tmp_path)
    for out_dir, name in ((camp.parent, camp.name), (tmp_path, "notes"), (camp, "results")):
        cfg = tmp_path / "run.toml"
        cfg.write_text(f'name = "{name}"\nout_dir = "{out_dir.as_posix()}"\n')
        before[Path("run.toml")] = hashlib.sha256(cfg.read_bytes()).hexdigest()
        assert main(["run", str(cfg), "--campaign", str(camp)]) == 2
        assert str(out_dir / name) in capsys.readouterr().err
        assert _snapshot(tmp_path) == before


def test_an_owned_folder_is_written_again_by_its_command_only(tmp_path):
    out = own_folder(tmp_path / "el", "pvvjax export")
    (out / "net_0.npz").write_text("x")
    assert own_folder(out, "pvvjax export") == out  # written again: its files replaced
    with pytest.raises(ResultsFolderError, match="holds the output of pvvjax export"):
        own_folder(out, "pvvjax plot")
    (tmp_path / "f.csv").write_text("mine")
    with pytest.raises(ResultsFolderError, match="--out .*f.csv: exists"):
        new_file(tmp_path / "f.csv")
    assert new_file(tmp_path / "new" / "g.csv") == tmp_path / "new" / "g.csv" and (tmp_path / "new").is_dir()


def test_synth_replaces_only_its_own_files_and_says_so(tmp_path):
    cfg = SynthConfig(conditions=("T1-level-135",))
    out = tmp_path / "c"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="--force"):
        write_synthetic(out, cfg)
    said = []
    write_synthetic(out, cfg, force=True, log=said.append)  # beside the user's file
    (out / "sub").mkdir()
    (out / "sub" / "x.csv").write_text("mine too")
    (out / "timeseries" / "mine.csv").write_text("a user's record")
    write_synthetic(out, SynthConfig(conditions=("T1-level-135",), seed=3), log=said.append)
    assert (out / "notes.txt").read_text() == "mine" and (out / "sub" / "x.csv").read_text() == "mine too"
    assert (out / "timeseries" / "mine.csv").exists()
    assert "replacing the synthetic campaign" in said[-1] and "3 other file(s) kept" in said[-1]
    # A campaign the generator did not write, and a ground truth it did not write, are refused even with force.
    user = write_tiny(tmp_path / "user")
    with pytest.raises(ValueError, match="pvvjax.synth did not write"):
        write_synthetic(user, cfg, force=True)
    (tmp_path / "t.json").write_text("{}")
    with pytest.raises(ValueError, match="not a ground truth"):
        write_synthetic(tmp_path / "d", cfg, truth_path=tmp_path / "t.json")


def test_a_figure_with_nothing_to_draw_is_named_in_a_warning(tmp_path):
    import matplotlib.pyplot as plt

    from pvvjax.plots import save

    fig, ax = plt.subplots()
    with pytest.warns(UserWarning, match="empty.png: the figure has nothing to draw"):
        save(fig, tmp_path / "empty.png")
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert save(fig, tmp_path / "drawn.png").exists()
