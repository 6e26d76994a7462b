"""The time budget of `make test`, reported, never asserted: at the end of a run, the tests
outside the check lane whose call took longer than `test_budget_s` (15 s by default, meant
for a 2-core machine with its programs compiled), slowest first.

A pytest plugin that `conftest.py` loads. Speed belongs to benchmarks (`benchmarks/bench_suite.py`
times the suite as a newcomer runs it); a slow or loaded machine must not turn a green suite
red, so the list is information for whoever adds a test: a test on it belongs in the check
lane (`@pytest.mark.check`), or should be made faster.

Every test process counts the programs it had to compile because the persistent compilation
cache did not hold them (JAX's `/jax/compilation_cache/cache_misses` event), test by test, so
that the report says whether the run was cold (its durations include compiling) or warm. The
setup of a shared fixture (a campaign generated, a small sweep trained once per code version)
is listed apart: it is paid once for all the tests that use it."""

from __future__ import annotations

import pytest

_MISS = "/jax/compilation_cache/cache_misses"
_misses = [0]
_start: dict = {}
_seconds: dict = {}
_not_judged: set = set()  # the check lane and the setup and teardown phases
_compiled = [0]


def _count(event, **kw):
    if event == _MISS:
        _misses[0] += 1


def start_counting():
    """Count this process's persistent-cache misses (call once, before the first test)."""
    import jax

    jax.monitoring.register_event_listener(_count)


def over_budget(seconds: dict, research: set, budget_s: float) -> list[tuple[str, float]]:
    """The entries of `seconds` (test id -> seconds of its call) outside `research` that
    took longer than `budget_s`, slowest first."""
    out = [(k, s) for k, s in seconds.items() if k not in research and s > budget_s]
    return sorted(out, key=lambda kv: -kv[1])


def pytest_addoption(parser):
    parser.addini("test_budget_s", "seconds a test outside the check lane should take, warm (reported)",
                  default="15")


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    if call.when == "setup":
        _start[item.nodeid] = _misses[0]
    elif call.when == "teardown":
        item.user_properties.append(("compile_misses", _misses[0] - _start.pop(item.nodeid, _misses[0])))
    return (yield)


def pytest_runtest_logreport(report):
    key = report.nodeid if report.when == "call" else f"{report.nodeid} ({report.when})"
    _seconds[key] = _seconds.get(key, 0.0) + report.duration
    if "check" in report.keywords or report.when != "call":
        _not_judged.add(key)
    if report.when == "teardown":
        _compiled[0] += dict(report.user_properties).get("compile_misses", 0)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """The report: fixture setups and tests over the budget (the controller's, under xdist)."""
    if hasattr(config, "workerinput"):
        return
    budget = float(config.getini("test_budget_s"))
    late = over_budget(_seconds, _not_judged, budget)
    shared = [(k, s) for k, s in over_budget(_seconds, set(), budget) if k.endswith("(setup)")]
    write = terminalreporter.write_line
    if shared:
        write(f"\nfixture setups over the {budget:g} s budget (paid once for the tests that share them):")
        for k, s in shared:
            write(f"  {s:6.1f} s  {k}")
    if not late:
        return
    run = (f"a cold run: {_compiled[0]} programs compiled, their compile time included" if _compiled[0]
           else "a warm run: every program came from the compilation cache")
    write(f"\n{len(late)} tests over the {budget:g} s budget of `make test` ({run}; reported, not judged: "
          "a test that stays over it on a warm 2-core machine belongs in the check lane):", yellow=True)
    for k, s in late:
        write(f"  {s:6.1f} s  {k}", yellow=True)
