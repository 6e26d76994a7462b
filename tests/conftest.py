"""Shared fixtures: a tiny hand-made campaign for bad-input tests, and the embedded
synthetic campaign (generated once into the cache, loaded once per test process)."""

from __future__ import annotations

import os
from pathlib import Path

# Every test process (two xdist workers, the notebooks' kernels, CLI subprocesses) shares the
# user's persistent compilation cache (the one the CLI uses, outside the checkout, so a second
# clone starts warm), and keeps every program, small ones too: on a cold cache (CI) much of
# the workers' CPU time is XLA compiling, programs which the processes compile alike. Set
# before JAX is imported (it reads these at import; children inherit them).
from pvvjax._cache import compile_cache_dir, user_cache_dir  # noqa: E402  (imports no JAX)

os.environ.setdefault("JAX_COMPILATION_CACHE_DIR", str(compile_cache_dir()))
# What the tests generate once (the campaigns, keyed by their config and generator version; the
# small sweep and the small `pvvjax dynamic` run, keyed by the package's source) goes to the
# user's cache too, so that a second clone of the same code makes none of it again. Set after
# the compilation cache, which stays where it is.
os.environ.setdefault("PVVJAX_CACHE", str(user_cache_dir() / "tests"))
# hypothesis keeps its caches (the examples database is off: tests/test_fuzz.py) beside the
# campaign cache, not in the working directory.
os.environ.setdefault("HYPOTHESIS_STORAGE_DIRECTORY", str(compile_cache_dir().parent / "hypothesis"))
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
# The two test processes share the two cores: scikit-learn's trees (the cross-fitted tests'
# nuisance learner) each take one OpenMP thread, not one per core (three times slower when
# they oversubscribe).
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
from _budget import (  # noqa: E402, F401  (the time budget's hooks, registered by being here)
    pytest_addoption,
    pytest_runtest_logreport,
    pytest_runtest_makereport,
    pytest_terminal_summary,
    start_counting,
)

_COMPILE_EVENTS = ("/jax/core/compile/jaxpr_trace_duration", "/jax/core/compile/jaxpr_to_mlir_module_duration",
                   "/jax/core/compile/backend_compile_duration")
_compile_seconds: dict = {}
_current_test = ["(outside a test)"]


def _compile_site() -> str:
    """The innermost frame of pvvjax or the tests that asked for a program (file:line)."""
    import traceback

    for frame in reversed(traceback.extract_stack()[:-3]):
        if "/pvvjax/" in frame.filename or "/tests/" in frame.filename:
            return f"{Path(frame.filename).parent.name}/{Path(frame.filename).name}:{frame.lineno}"
    return "?"


def _record_compile(event, duration, **kw):
    if event in _COMPILE_EVENTS:
        name = kw.get("fun_name", "?")
        if os.environ.get("PVVJAX_COMPILE_SITES") and event == _COMPILE_EVENTS[1]:
            name = f"{name} @ {_compile_site()}"
        row = _compile_seconds.setdefault(_current_test[0], {}).setdefault(name, [0, 0.0, 0.0, 0.0])
        i = _COMPILE_EVENTS.index(event)
        row[0] += i == 1  # programs lowered
        row[1 + i] += duration  # seconds tracing, lowering, compiling (or reading the persistent cache)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    _current_test[0] = item.nodeid  # the compile report's key: programs by the test that lowered them
    yield
    _current_test[0] = "(outside a test)"


def pytest_unconfigure(config):
    """With PVVJAX_COMPILE_REPORT=PREFIX, each test process writes PREFIX.<worker>.json: per
    test and function name, the programs it lowered and the seconds spent tracing, lowering
    and compiling them (where a cold suite's time goes; subprocesses are not counted). With
    PVVJAX_COMPILE_SITES=1 too, the programs lowered are counted by function name and the
    line of pvvjax or the tests that asked for them."""
    prefix = os.environ.get("PVVJAX_COMPILE_REPORT")
    if prefix:
        import json

        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        Path(f"{prefix}.{worker}.json").write_text(json.dumps(_compile_seconds, indent=0))


def pytest_configure(config):
    start_counting()
    if not hasattr(config, "workerinput"):  # the controller, once per run: the cache's bound
        from pvvjax._cache import prune_compile_cache

        prune_compile_cache(Path(os.environ["JAX_COMPILATION_CACHE_DIR"]))
    if os.environ.get("PVVJAX_COMPILE_REPORT"):
        import jax

        jax.monitoring.register_event_duration_secs_listener(_record_compile)
    # xdist hands tests out one at a time (two pending per worker), so that the heavy tests,
    # collected first, spread over the workers and the light ones fill the gaps: in chunks
    # of consecutive tests one worker would take most heavy tests (a minute or more at the end).
    if hasattr(config.option, "maxschedchunk") and config.option.maxschedchunk is None:
        config.option.maxschedchunk = 1


def pytest_collection_modifyitems(config, items):
    items.sort(key=lambda item: item.get_closest_marker("heavy") is None)  # stable: heavy first


def tiny_records(n_counters=2, seconds=12.0, spr=64, rpm=257.8, seed=0):
    """Counters table and records of a small valid campaign (constant rotor speed)."""
    rng = np.random.default_rng(seed)
    fs = spr * rpm / 60.0
    t = np.arange(0.0, seconds, 1.0 / fs)
    rows, recs = [], {}
    for i in range(n_counters):
        name = f"C{i + 1}"
        psi = 2 * np.pi * rpm / 60.0 * t
        az = 1.0 + 0.1 * (i + 1) * np.cos(4 * psi + 0.4) + 0.01 * rng.standard_normal(t.size)
        recs[name] = pd.DataFrame({
            "time_s": t, "az_g": az, "rotor_rpm": rpm, "airspeed_kt": 100.0 + i, "pitch_rate_dps": 0.0,
            "roll_angle_deg": 0.0, "climb_rate_fpm": 0.0, "collective_pct": 50.0, "lateral_pct": 50.0,
            "longitudinal_pct": 55.0,
        })
        rows.append(dict(counter=name, maneuver="level", gross_weight_lb=16000.0, density_ratio=1.0))
    return pd.DataFrame(rows), recs


def lag_loop(u, table, tau):
    """The exact first-order lag of a held input, window by window along each counter (`table.i`)
    in window order (`table.k`), from rest at its first window (float64): the reference of
    the discovery's lag of window series."""
    out = np.empty_like(u, dtype=float)
    for _, rows in table.groupby("i").groups.items():
        rows = np.asarray(rows)[np.argsort(table.k.to_numpy()[rows])]
        t = table.time_s.to_numpy()[rows]
        y = u[..., rows[0]].astype(float)
        out[..., rows[0]] = y
        for j in range(1, len(rows)):
            a = np.exp(-(t[j] - t[j - 1]) / tau)
            y = a * y + (1.0 - a) * u[..., rows[j]]
            out[..., rows[j]] = y
    return out


def write_tiny(folder, counters=None, recs=None, fmt="csv"):
    """Write a tiny campaign folder (optionally from modified tables)."""
    from pvvjax.data.campaign import write_campaign

    c0, r0 = tiny_records()
    return write_campaign(folder, c0 if counters is None else counters, r0 if recs is None else recs, fmt=fmt)


@pytest.fixture
def tiny(tmp_path):
    return tiny_records()


@pytest.fixture(scope="session")
def default_campaign_dir():
    from pvvjax.synth import cached_campaign

    return cached_campaign()


@pytest.fixture(scope="session")
def default_campaign(default_campaign_dir):
    from pvvjax.data.campaign import load_campaign

    return load_campaign(default_campaign_dir)


@pytest.fixture(scope="session")
def default_dbs(default_campaign):
    from pvvjax.analysis.databases import build_databases

    return build_databases(default_campaign)


@pytest.fixture(scope="session")
def default_dbs_axes(default_campaign):
    """The embedded campaign's N/rev peak table of every axis (`axis_peak_tables`), by axis."""
    from pvvjax.analysis import axis_peak_tables

    n = default_campaign.aircraft.blades
    return {axis: t for (axis, k), t in axis_peak_tables(default_campaign, harmonics=(n,)).items()}


SMALL_COUNTS = dict(level=10, climb=3, descent=3, turn=3, roll=3, pushover=2, pullup=3, autorotation=1, flare=2)


@pytest.fixture(scope="session")
def small_campaign_dir():
    """A small synthetic campaign (named conditions, the level sweep and a few of each kind)."""
    from pvvjax.synth import SynthConfig, cached_campaign

    return cached_campaign(SynthConfig(name="small", counts=SMALL_COUNTS))


@pytest.fixture(scope="session")
def small_dbs(small_campaign_dir):
    from pvvjax.analysis.databases import build_databases
    from pvvjax.data.campaign import load_campaign

    return build_databases(load_campaign(small_campaign_dir))


def rbf_nets(dbs, database: str, n: int = 3, centers: int = 16):
    """`n` RBF nets (seeds 0..n-1, NumPy parameters) fitted to all rows of a database, and
    its input envelope (min, max): quick stand-ins for trained nets in element tests."""
    import jax

    from pvvjax.analysis.databases import DB_INPUTS
    from pvvjax.nets.networks import rbf_fit
    from pvvjax.nets.sweep import stack_data

    x, y, in_mask, _ = stack_data(dbs, [database], 5, 0)[database]
    params = [jax.tree.map(np.asarray, rbf_fit(jax.random.key(s), x, y, centers, in_mask=in_mask)) for s in range(n)]
    db = dbs[database][list(DB_INPUTS[database])]
    return params, (db.min().to_numpy(), db.max().to_numpy())


def experiment(name: str):
    """The module of experiments/NAME.py (a script, not a package), with the experiments
    folder importable as its own imports expect."""
    import importlib.util
    import sys

    folder = Path(__file__).parents[1] / "experiments"
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
    spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


def research(name: str):
    """The module of research/NAME.py (a script of the lab, not a package)."""
    import importlib.util
    import sys

    spec = importlib.util.spec_from_file_location(name, Path(__file__).parents[1] / "research" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # its dataclasses' annotations resolve in their module
    spec.loader.exec_module(mod)
    return mod


class LinearLearner:
    """Least squares with an intercept, a nuisance learner for tests of the cross-fitted tests
    over many simulated draws (their nuisances are linear; scikit-learn's own costs more in
    checks than in fitting)."""

    def fit(self, Z, y):
        self.coef = np.linalg.lstsq(np.c_[np.ones(len(Z)), Z], y, rcond=None)[0]
        return self

    def predict(self, Z):
        return np.c_[np.ones(len(Z)), Z] @ self.coef


_SECTION_OF = {"hidden": ("ensemble", "hidden"), "seeds": ("ensemble", "seeds"), "folds": ("ensemble", "folds"),
               "split_seed": ("ensemble", "split_seed"), "offset_step_s": ("offset", "step_s"),
               "calibrate_offset": ("offset", "calibrate"), "offset_s": ("offset", "fixed_s")}


def discovery_config(**settings):
    """A `DiscoveryConfig` from flat keyword settings (`seeds=1, folds=3, offset_step_s=0.5`),
    each put in its section: the tests' short form of the nested config."""
    from pvvjax.config import DiscoveryConfig, from_dict

    data: dict = {}
    for key, value in settings.items():
        if key in _SECTION_OF:
            section, name = _SECTION_OF[key]
            data.setdefault(section, {})[name] = value
        else:
            data[key] = value
    return from_dict(DiscoveryConfig, data)


class Lowerings:
    """Counts the programs JAX lowers for compilation, by function name, while active
    (`with Lowerings() as n: ...; n["_segment"]`). A lowering happens for every program
    compiled, whether or not the persistent cache then holds its binary, so the count is a
    cache-independent measure of how many programs a piece of code needs. `fresh=True` clears
    JAX's in-memory caches on entering, so that a count of programs compiled once does not
    depend on the tests that ran before in the same worker."""

    EVENT = "/jax/core/compile/jaxpr_to_mlir_module_duration"

    def __init__(self, fresh: bool = False):
        from collections import Counter

        self.counts = Counter()
        self.fresh = fresh

    def _listener(self, event, duration, **kw):
        if event == self.EVENT:
            name = kw.get("fun_name", "?")
            self.counts[name[4:-1] if name.startswith("jit(") else name] += 1

    def __enter__(self):
        import jax

        if self.fresh:  # programs traced by earlier tests in this worker would not be lowered again
            jax.clear_caches()
        jax.monitoring.register_event_duration_secs_listener(self._listener)
        return self.counts

    def __exit__(self, *exc):
        import jax

        jax.monitoring.unregister_event_duration_listener(self._listener)


# The small trained sweep several tests export, replay or resume: MLP nets of db1 and db3 on
# the small campaign, every fold. A test copies it to its own folder and runs `pvvjax sweep`
# with `small_sweep_config` there: the folder is claimed for these settings, so the sweep
# resumes with nothing to train, and any axis subset (one database, some folds) resumes too.
SMALL_SWEEP = '''name = "{name}"\nout_dir = "{out}"\n[campaign]\npath = "{campaign}"
[sweep]\ndatabases = {databases}\nhidden = [[4]]\nseeds = 1\nfolds = 3\ntest_folds = {test_folds}\ncpu_devices = 1
[train]\nmax_steps = 300\nlearning_rate = 0.01\n'''


def small_sweep_config(path, out, campaign, name="s", databases=("db1", "db3"), test_folds=()) -> Path:
    """Write the shared small sweep's config (some of its axes) to `path`; its sweep folder
    is `out/name/sweep`."""
    path = Path(path)
    path.write_text(SMALL_SWEEP.format(name=name, out=Path(out).as_posix(), campaign=Path(campaign).as_posix(),
                                       databases=list(databases), test_folds=list(test_folds)).replace("'", '"'))
    return path


def small_job_config(folder, campaign, small_sweep, replay_databases=("db1", "db3"), run: str = "") -> Path:
    """The main job's config on the small campaign with the shared small sweep's settings,
    written to `folder/p.toml`; the sweep is copied into its folder (`folder/p/sweep`, as
    `pvvjax sweep` of the same config leaves it), so a command on the config claims the
    folder and resumes the sweep with nothing to train. `run`: a `[run]` table to add."""
    import json
    import shutil

    folder = Path(folder)
    shutil.copytree(small_sweep, folder / "p" / "sweep")
    cfg = folder / "p.toml"
    cfg.write_text(f'''name = "p"\nout_dir = "{folder.as_posix()}"
[campaign]\npath = "{Path(campaign).as_posix()}"
{run}[sweep]\ndatabases = ["db1", "db3"]\nhidden = [[4]]\nseeds = 1\nfolds = 3\ncpu_devices = 1
[train]\nmax_steps = 300\nlearning_rate = 0.01
[replay]\ndatabases = {json.dumps(list(replay_databases))}
[calibration]\ngrid_offset_step_s = 0.5\ngrid_window_step_revs = 2.0\n''')
    return cfg


def _code_key() -> str:
    """Hash of the package's source: a cached sweep is trained again whenever the code changes."""
    import hashlib

    h = hashlib.sha256()
    for p in sorted((Path(__file__).parents[1] / "pvvjax").rglob("*.py")):
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def cached_folder(kind: str, marker: str, make) -> Path:
    """A results folder made once per code version and cached beside the campaigns
    (read-only: copy it), under a lock so that the workers make it once. `make(tmp)` writes it
    into the new folder `tmp`; `marker` is the file whose presence says it is complete."""
    import fcntl
    import shutil
    import tempfile

    from pvvjax._cache import cache_dir

    root = cache_dir() / kind
    final = root / f"small-{_code_key()}"
    if (final / marker).exists():
        return final
    root.mkdir(parents=True, exist_ok=True)
    with open(root / f"{final.name}.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if not (final / marker).exists():
            tmp = Path(tempfile.mkdtemp(dir=root, prefix=".tmp-"))
            try:
                os.rename(make(tmp), final)
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
            _keep_newest(root, final, KEEP_VERSIONS)
    return final


KEEP_VERSIONS = 4  # code versions whose cached folders are kept (the user's cache is shared by every clone)


def _keep_newest(root: Path, final: Path, keep: int):
    """Delete all but the `keep` newest cached folders of `root` (one per code version), never
    `final`; their lock files go with them. A folder another process is still making is a
    `.tmp-*` folder, which this leaves alone."""
    import shutil

    folders = sorted((p for p in root.glob("small-*") if p.is_dir() and p != final), key=lambda p: p.stat().st_mtime)
    for old in folders[:max(0, len(folders) - (keep - 1))]:
        shutil.rmtree(old, ignore_errors=True)
        (root / f"{old.name}.lock").unlink(missing_ok=True)


@pytest.fixture(scope="session")
def small_sweep(small_campaign_dir) -> Path:
    """The shared small sweep's folder (read-only: copy it), trained once per code version."""
    from pvvjax.cli import main

    def make(tmp):
        cfg = small_sweep_config(tmp / "s.toml", tmp, small_campaign_dir)
        assert main(["sweep", str(cfg), "--out", str(tmp / "sweep")]) == 0
        return tmp / "sweep"

    return cached_folder("sweeps", "results.parquet", make)


