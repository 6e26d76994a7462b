"""The time budget of `make test`: no test outside the research lane takes longer than
`test_budget_s` (15 s by default, on a 2-core machine) once its programs are compiled.

A pytest plugin that `conftest.py` loads. Every test process counts the programs it had to
compile because the persistent compilation cache did not hold them (JAX's
`/jax/compilation_cache/cache_misses` event), test by test; the controller reads each test's
call duration (pytest's durations). A run in which no test compiled anything is a warm run:
there, a test over the budget fails the session, naming the test and its seconds, so that the
lane cannot grow back. A cold run (a new machine) compiles, so its durations say little about
the tests: it only reports the tests over the budget. The setup of a shared fixture (a
campaign generated, a small sweep trained once per code version) is reported where it passes
the budget, not judged: it is paid once for all the tests that use it."""

from __future__ import annotations

import pytest

_MISS = "/jax/compilation_cache/cache_misses"
_misses = [0]
_start: dict = {}
_seconds: dict = {}
_not_judged: set = set()  # research checks and the setup and teardown phases
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
    parser.addini("test_budget_s", "seconds a test outside the research lane may take, warm", default="15")


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
    if "research" in report.keywords or report.when != "call":
        _not_judged.add(key)
    if report.when == "teardown":
        _compiled[0] += dict(report.user_properties).get("compile_misses", 0)


def pytest_sessionfinish(session, exitstatus):
    if hasattr(session.config, "workerinput"):  # an xdist worker: the controller judges
        return
    budget = float(session.config.getini("test_budget_s"))
    late = over_budget(_seconds, _not_judged, budget)
    shared = [(k, s) for k, s in over_budget(_seconds, set(), budget) if k.endswith("(setup)")]
    tr = session.config.pluginmanager.get_plugin("terminalreporter")

    def write(text, **markup):
        tr.write_line(text, **markup) if tr else print(text)

    if shared:
        write(f"\nfixture setups over the {budget:g} s budget (paid once for the tests that share them):")
        for k, s in shared:
            write(f"  {s:6.1f} s  {k}")
    if not late:
        return
    lines = [f"  {s:6.1f} s  {k}" for k, s in late]
    if _compiled[0]:
        write(f"\n{len(late)} tests over the {budget:g} s budget in a cold run ({_compiled[0]} programs compiled; "
              "the budget is judged on a warm run):")
        for line in lines:
            write(line)
        return
    write(f"\n{len(late)} tests over the {budget:g} s budget of `make test` (a warm run): move each to the "
          "research lane (`@pytest.mark.research`) with a micro twin here, or make it faster:", red=True)
    for line in lines:
        write(line, red=True)
    session.exitstatus = pytest.ExitCode.TESTS_FAILED
