"""Every notebook in notebooks/ (paired jupytext .py files) executes without error.

In `make test` each notebook's code runs cell by cell in the test process, on a micro or
small campaign with short training: its cell tagged "parameters" (papermill's convention)
gets the settings appended, and its cells tagged "checks" (what only a full-size run can
assert) are left out. The research lane executes every notebook in a Jupyter kernel: those
that assert on their own campaigns as written, checks included, the others on the small
campaign."""

from pathlib import Path

import pytest
from conftest import SMALL_COUNTS

NOTEBOOKS = sorted((Path(__file__).parents[1] / "notebooks").glob("*.py"))
SMALL = f"\ncampaign_config = SynthConfig(name='small', counts={SMALL_COUNTS!r})"
QUICK_DYNAMICS = "\ntrain = TrainConfig(max_steps=100, eval_every=50, patience=2)\nseeds, folds = 1, 3"
AS_WRITTEN = ("discovery", "paper")  # they assert on their own campaigns
# The settings appended to a notebook's parameters cell: in a kernel (the research lane) and
# in `make test`.
IN_A_KERNEL = {"offset_window": SMALL, "quickstart": SMALL, "dynamics": SMALL + QUICK_DYNAMICS}
MICRO = {**IN_A_KERNEL, "paper": SMALL,
         "discovery": "\ncounts = dict(level=6, climb=1, descent=2, turn=1, roll=1, pushover=1, pullup=1, flare=1)"
                      "\nseeds, max_steps = 1, 100"}


def _cells(path: Path, settings: str, checks: bool):
    """The notebook with `settings` appended to its parameters cell, without its cells tagged
    "checks" unless `checks`."""
    import jupytext

    nb = jupytext.read(path)
    if settings:
        cell = next(c for c in nb.cells if "parameters" in c.metadata.get("tags", []))
        cell.source += settings
    if not checks:
        nb.cells = [c for c in nb.cells if "checks" not in c.metadata.get("tags", [])]
    return nb


@pytest.mark.check
@pytest.mark.heavy
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_code_runs_on_a_micro_campaign(path, small_campaign_dir, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    monkeypatch.chdir(path.parent)
    namespace = {"__name__": "__main__"}
    try:
        for i, cell in enumerate(_cells(path, MICRO.get(path.stem, ""), checks=False).cells):
            if cell.cell_type == "code":
                exec(compile(cell.source, f"{path.name} cell {i}", "exec"), namespace)
    finally:
        plt.close("all")


@pytest.mark.check
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs_in_a_kernel(path, default_campaign_dir, small_campaign_dir):
    from nbclient import NotebookClient

    nb = _cells(path, IN_A_KERNEL.get(path.stem, ""), checks=True)
    NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}}).execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if o.output_type == "error"]
    assert not errors


def test_the_notebooks_with_checks_run_as_written_in_the_research_lane_and_have_parameters():
    import jupytext

    assert not IN_A_KERNEL.keys() & set(AS_WRITTEN)  # those run as written in a kernel
    for path in NOTEBOOKS:
        tags = [t for c in jupytext.read(path).cells for t in c.metadata.get("tags", [])]
        assert ("checks" in tags) == (path.stem in AS_WRITTEN), path
        assert ("parameters" in tags) == (path.stem in MICRO), path
