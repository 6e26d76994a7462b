"""`make test`'s time budget (tests/_budget.py): the tests over it are reported, warm or cold,
and never fail the run."""

import subprocess
import sys
from pathlib import Path

import pytest
from _budget import over_budget

HERE = Path(__file__).parent


def test_the_tests_over_the_budget_are_those_outside_the_research_lane_slowest_first():
    seconds = {"a": 3.0, "b": 16.0, "c": 40.0, "d": 15.0, "e": 90.0}
    assert over_budget(seconds, {"e"}, 15.0) == [("c", 40.0), ("b", 16.0)]
    assert over_budget(seconds, set(), 100.0) == []


def _run(tmp_path, body: str):
    (tmp_path / "conftest.py").write_text(f"import sys\nsys.path.insert(0, {str(HERE)!r})\n"
                                          "from _budget import *  # noqa\n\n"
                                          "def pytest_configure(config):\n    start_counting()\n")
    (tmp_path / "test_x.py").write_text(body)
    (tmp_path / "pytest.ini").write_text("[pytest]\nmarkers = check: r\ntest_budget_s = 0.3\n")
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(tmp_path)],
                          capture_output=True, text=True, cwd=tmp_path)


@pytest.mark.check
def test_a_warm_run_with_a_test_over_the_budget_passes_and_names_it(tmp_path):
    # A shared fixture's setup over the budget is reported, not judged.
    out = _run(tmp_path, "import time, pytest\n\n@pytest.fixture(scope='module')\ndef shared():\n"
                         "    time.sleep(0.5)\n\ndef test_quick(shared):\n    pass\n\n"
                         "def test_slow():\n    time.sleep(0.5)\n\n"
                         "@pytest.mark.check\ndef test_research():\n    time.sleep(0.5)\n")
    assert out.returncode == 0, out.stdout
    assert "fixture setups over the 0.3 s budget" in out.stdout and "test_x.py::test_quick (setup)" in out.stdout
    late = out.stdout.split("a warm run: every program came from the compilation cache")[1]
    assert "1 tests over the 0.3 s" in out.stdout and "test_x.py::test_slow" in late
    assert "test_research" not in late and "test_quick" not in late and "3 passed" in out.stdout


@pytest.mark.check
def test_a_cold_run_reports_the_tests_over_the_budget_and_passes(tmp_path):
    # A program compiled (no persistent cache here: every compile is a miss) makes the run cold.
    out = _run(tmp_path, "import time, jax, jax.numpy as jnp\n\n"
                         "def test_compiles():\n    jax.config.update('jax_compilation_cache_dir', "
                         f"{str(tmp_path / 'cache')!r})\n    jax.jit(lambda x: x * 3.0)(jnp.ones(3))\n"
                         "    time.sleep(0.5)\n")
    assert out.returncode == 0, out.stdout
    assert "programs compiled, their compile time included" in out.stdout and "test_x.py::test_compiles" in out.stdout
