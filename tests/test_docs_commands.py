"""The README and the docs run verbatim: every ```sh block (what a newcomer pastes) is run
here, line by line, in a fresh folder, so that a command that stops working fails CI.
Synopses with placeholders are ```text blocks and are not run. A block that names a config
runs it with small settings: each experiment config is copied with a small overlay (the
small campaign, one seed, few steps), so the commands stay the same and finish in seconds.
`make demo` runs its recipe's command; `make test` and `make check` are what CI itself runs."""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def sh_blocks(path: Path) -> list[list[str]]:
    """The command lines of each ```sh block of a Markdown file (comments stripped)."""
    blocks = re.findall(r"^```sh\n(.*?)^```", path.read_text(), flags=re.M | re.S)
    return [[ln.split("  #")[0].strip() for ln in b.splitlines() if ln.strip() and not ln.startswith("#")]
            for b in blocks]


def _small(data: dict, campaign: Path, micro: bool = False) -> dict:
    """An experiment config's settings made small (same sections, seconds to run); `micro`:
    three of the models through time, on one seed and three folds (`make test`'s)."""
    def merge(a, b):
        return {**a, **{k: merge(a.get(k, {}), v) if isinstance(v, dict) else v for k, v in b.items()}}
    small = {"sweep": {"hidden": [[4]], "seeds": 1, "folds": 3, "test_folds": [0], "cpu_devices": 1},
             "train": {"max_steps": 300, "learning_rate": 0.01}, "run": {"networks": False, "discovery_scenario": ""},
             "axes": {"databases": ["db1"], "hidden": [4], "seeds": 1, "folds": 3, "discovery": False}}
    if not data.get("campaign", {}).get("path"):
        small["campaign"] = {"path": str(campaign)}
    if micro:
        small["dynamic"] = {"seeds": 1, "folds": 3, "models": ["quasi_static", "window_static", "dynamic"]}
    if "sweep" in data and "databases" in data["sweep"]:
        small["sweep"]["databases"] = data["sweep"]["databases"][:1]
    return merge(data, small)


@pytest.fixture
def workdir(tmp_path, monkeypatch, small_campaign_dir, small_sweep, request):
    """A fresh folder holding `experiments/` with every experiment config made small (micro
    outside the research lane). A config whose sweep is trained as the shared small sweep
    finds that sweep in its folder (`OUT_DIR/NAME/sweep`), so its `pvvjax sweep` resumes it
    instead of training."""
    micro = "micro" in request.node.name
    import tomli_w

    from pvvjax.config import ExperimentConfig, from_dict, load_config, load_toml
    from pvvjax.nets import sweep_settings

    shared = sweep_settings(load_config(small_sweep / "config.toml"))
    shutil.copytree(ROOT / "experiments", tmp_path / "experiments", ignore=shutil.ignore_patterns("*.py"))
    for p in (tmp_path / "experiments").rglob("*.toml"):
        data = load_toml(p)
        try:
            from_dict(ExperimentConfig, data)
        except Exception:  # a generator or benchmark config: left as it is
            continue
        small = _small(data, small_campaign_dir, micro)
        p.write_text(tomli_w.dumps(small))
        cfg = from_dict(ExperimentConfig, small)
        if sweep_settings(cfg) == shared and not (tmp_path / cfg.out_dir / cfg.name / "sweep").exists():
            shutil.copytree(small_sweep, tmp_path / cfg.out_dir / cfg.name / "sweep")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PVVJAX_CACHE", str(Path(small_campaign_dir).parents[1]))
    return tmp_path


def _run_line(line: str, capsys):
    from pvvjax.cli import main

    argv = shlex.split(line)
    if argv[:2] in (["make", "test"], ["make", "check"]):  # .ci/run runs both; here they would run this test again
        assert " ".join(argv[:2]) in (ROOT / ".ci" / "run").read_text()
        return
    if argv[:2] == ["make", "demo"]:
        recipe = re.search(r"^demo:.*\n\t(.*)$", (ROOT / "Makefile").read_text(), flags=re.M)[1]
        argv = shlex.split(recipe.replace("$(VENV)/bin/", ""))
    assert argv[0] == "pvvjax", f"a ```sh block runs pvvjax or make, not {line!r}"
    if any(a == "--format" and b in ("c", "fmu") for a, b in zip(argv, argv[1:])):
        from pvvjax.realtime import c_compiler

        if c_compiler() is None:  # CI has one; tests/test_celement.py skips with the reason
            return
    code = main(argv[1:])
    out = capsys.readouterr()
    assert code == 0, f"{line}\n{out.out}\n{out.err}"


def test_every_sh_block_is_run():
    blocks = {p.name: sh_blocks(p) for p in DOCS if sh_blocks(p)}
    assert set(blocks) == {"README.md", "networks.md", "realtime.md"}, blocks


BLOCKS = [(p.name, i) for p in DOCS for i, _ in enumerate(sh_blocks(p))]


@pytest.mark.check
@pytest.mark.heavy
@pytest.mark.parametrize("doc, block", BLOCKS, ids=[f"{d}-{i}" for d, i in BLOCKS])
def test_each_block_of_the_docs_commands_runs_with_micro_settings(doc, block, workdir, capsys):
    for line in sh_blocks(next(p for p in DOCS if p.name == doc))[block]:
        _run_line(line, capsys)


@pytest.mark.check
@pytest.mark.parametrize("doc", ["README.md", "networks.md", "realtime.md"])
def test_the_docs_commands_run_verbatim(doc, workdir, capsys):
    path = next(p for p in DOCS if p.name == doc)
    for block in sh_blocks(path):
        for line in block:
            _run_line(line, capsys)
