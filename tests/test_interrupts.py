"""Ctrl-C stops `pvvjax sweep` with status 130 and the resume message at every moment (the
trainer's compile, a training segment, a checkpoint, the results' writing), also where the
interrupt is swallowed where it lands (as inside a finalizer or a library's callback); the
same command then resumes to complete results."""

import os
import signal

import pandas as pd
import pytest
from conftest import small_sweep_config

from pvvjax import interrupts
from pvvjax.cli import main
from pvvjax.nets import batched
from pvvjax.nets import sweep as sweep_mod


def _ctrl_c():
    os.kill(os.getpid(), signal.SIGINT)


def _at_compile(monkeypatch):
    program = batched._program
    monkeypatch.setattr(batched, "_program", lambda *a: _ctrl_c() or program(*a))


def _in_training(monkeypatch):
    to_host = batched._to_host
    monkeypatch.setattr(batched, "_to_host", lambda tree: _ctrl_c() or to_host(tree))


def _writing(which):
    def patch(monkeypatch):
        write = sweep_mod._atomic_parquet

        def interrupted(df, path):
            if (path.parent.name == "parts") == (which == "checkpoint"):
                _ctrl_c()
            write(df, path)
        monkeypatch.setattr(sweep_mod, "_atomic_parquet", interrupted)
    return patch


def _swallowed(monkeypatch):
    to_host = batched._to_host

    def lost(tree):  # the interrupt lands where it is caught and dropped
        try:
            _ctrl_c()
        except KeyboardInterrupt:
            pass
        return to_host(tree)
    monkeypatch.setattr(batched, "_to_host", lost)


MOMENTS = {"compile": _at_compile, "training": _in_training, "checkpoint": _writing("checkpoint"),
           "results": _writing("results"), "swallowed in a callback": _swallowed}


# One moment in `make test`, the others (each a sweep trained twice) in the check lane.
@pytest.mark.parametrize("moment", [m if m == "training" else pytest.param(m, marks=pytest.mark.check)
                                    for m in MOMENTS])
def test_ctrl_c_stops_the_sweep_with_130_and_it_resumes(moment, tmp_path, small_campaign_dir, monkeypatch, capsys):
    cfg = small_sweep_config(tmp_path / "s.toml", tmp_path, small_campaign_dir, databases=("db1",), test_folds=(0, 1))
    with monkeypatch.context() as m:
        MOMENTS[moment](m)
        assert main(["sweep", str(cfg)]) == 130
    err = capsys.readouterr().err
    assert "interrupted; run the same command to resume" in err and "Exception ignored" not in err
    assert main(["sweep", str(cfg)]) == 0
    res = pd.read_parquet(tmp_path / "s" / "sweep" / "results.parquet")
    assert sorted(res.test_fold) == [0, 1] and res.net_id.is_unique


def test_outside_a_command_ctrl_c_is_pythons_own():
    # Python's own handler, or the one the process started with (a job started in the
    # background of a shell inherits Ctrl-C ignored): a command leaves it as it found it.
    before = signal.getsignal(signal.SIGINT)
    with interrupts.interruptible():
        assert signal.getsignal(signal.SIGINT) not in (before, signal.default_int_handler)
        interrupts.check_interrupt()  # nothing pending: no-op
    assert signal.getsignal(signal.SIGINT) is before
