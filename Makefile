# Two commands set up a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: venv demo test check bench clean

# Reinstall only when the package metadata changes (the install is editable). uv (from PyPI,
# into the venv) resolves and installs the same packages as pip in about a quarter of the time
# (11 s against 45 s on 2 cores); where uv cannot be had, pip does it.
INSTALL = $(PY) -m uv pip install --quiet --python $(PY)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet uv && $(INSTALL) -e '.[test,sim]' || $(PY) -m pip install --quiet -e '.[test,sim]'
	touch $(STAMP)

venv: $(STAMP)

demo: venv
	$(VENV)/bin/pvvjax run experiments/paper.toml

# The suite starts many Python processes (workers, notebook kernels, CLI and export
# subprocesses): each compiles the sources of jax, pandas and pvvjax again (2 s of 3.6 s per
# import on 2 cores) where PYTHONDONTWRITEBYTECODE is set. Their bytecode goes to one tree
# inside the venv instead, never beside the sources.
PYTEST = PYTHONDONTWRITEBYTECODE= PYTHONPYCACHEPREFIX=$(abspath $(VENV))/pycache $(PY) -m pytest -q -n 2 --dist worksteal

# The newcomer's lane: unit, property and integration tests of every module and command, in
# process on micro inputs. The tests over the 15 s budget are listed at the end, never failed.
test: venv
	$(PYTEST) -m "not check" --durations=25

# The check lane: whatever runs a whole command, notebook, README block, example or
# multi-process job end to end (on micro campaigns), and the research runs on full-size ones.
check: venv
	$(PYTEST) -m check --durations=0

# pip, not uv, for the bench extra: pip finds torch's CPU build on these machines' disk.
bench: venv
	$(PY) -m pip install --quiet -e '.[test,sim,bench]'
	$(PY) benchmarks/bench_harmonics.py
	$(PY) benchmarks/bench_synth.py
	$(PY) benchmarks/bench_sweep.py

clean:
	rm -rf $(VENV) runs .pytest_cache
