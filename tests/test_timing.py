"""The stage stopwatch: seconds per named stage, summed over repeats, nested stages in both."""

import itertools

from pvvjax import _timing


def test_a_stage_that_runs_twice_sums_and_a_nested_stage_counts_in_both(monkeypatch):
    ticks = itertools.count()
    monkeypatch.setattr(_timing.time, "perf_counter", lambda: float(next(ticks)))  # 1 s a call
    clock = _timing.Stopwatch()
    with clock("prepare"):
        pass
    for _ in range(2):
        with clock("round"):
            with clock("confirm"):
                pass
    assert clock.seconds == {"prepare": 1.0, "round": 6.0, "confirm": 2.0}
    try:
        with clock("failed"):
            raise KeyError
    except KeyError:
        pass
    assert clock.seconds["failed"] == 1.0  # a stage that raised is timed too
