"""Every notebook in notebooks/ (paired jupytext .py files) executes without error.

A notebook whose cells assert nothing that needs the embedded campaign runs on the tests'
small campaign: its cell tagged "parameters" (papermill's convention) gets the setting
appended."""

from pathlib import Path

import pytest
from conftest import SMALL_COUNTS

NOTEBOOKS = sorted((Path(__file__).parents[1] / "notebooks").glob("*.py"))
ON_THE_SMALL_CAMPAIGN = {"offset_window", "quickstart", "dynamics"}  # paper and discovery assert on their own
# Shorter training where a notebook trains (appended to its parameters cell after the campaign).
QUICK = {"dynamics": "train = TrainConfig(max_steps=100, eval_every=50, patience=2)\nseeds, folds = 1, 3"}


@pytest.mark.heavy
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path, default_campaign_dir, small_campaign_dir):
    import jupytext
    from nbclient import NotebookClient

    nb = jupytext.read(path)
    if path.stem in ON_THE_SMALL_CAMPAIGN:
        cell = next(c for c in nb.cells if "parameters" in c.metadata.get("tags", []))
        cell.source += f"\ncampaign_config = SynthConfig(name='small', counts={SMALL_COUNTS!r})"
        cell.source += "\n" + QUICK.get(path.stem, "")
    NotebookClient(nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}}).execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", []) if o.output_type == "error"]
    assert not errors
