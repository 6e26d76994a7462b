"""The test suite as a newcomer meets it: `make test` on a clean clone, timed.

Clones the repository's HEAD into a new folder and runs `make test` there with a new, empty
HOME (a new machine: no pip or uv cache, no compiled programs, no generated campaigns), then
again in a second clone with that HOME (the programs and campaigns the first made are there),
and a third time with a CPU hog beside it (one busy process per core, at normal priority). For
each run: the wall time of the whole command (venv and install included), pytest's own
seconds, the tests passed and failed, the tests the suite listed over its 15 s budget, and
the programs in the compilation cache after it (after the first run: those a new machine compiles).
Nothing in the checkout is touched; the folders are kept under --work, each clone with its
`make-test.log` and `junit.xml` (every test's seconds).

    python benchmarks/bench_suite.py [--work DIR] [--runs new,second,loaded] [--target test]

Results go to --work/suite.json and are printed as a Markdown table for docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _hog(stop_at: float):
    """A busy loop until `stop_at` (time.time())."""
    x = 0
    while time.time() < stop_at:
        for _ in range(100_000):
            x += 1


def summarise(output: str) -> dict:
    """pytest's closing counts and seconds, and the tests it listed over the budget."""
    last = [ln for ln in output.splitlines() if re.search(r"\d+ (passed|failed)", ln) and " in " in ln]
    counts = {k: int(v) for v, k in re.findall(r"(\d+) (passed|failed|skipped|error)", last[-1])} if last else {}
    seconds = float(re.search(r" in ([\d.]+)s", last[-1])[1]) if last else float("nan")
    over = re.findall(r"^\s+([\d.]+) s\s+(tests/\S+)$", output.split("tests over the")[-1], flags=re.M) \
        if "tests over the" in output else []
    return dict(counts=counts, pytest_s=seconds, over_budget=[(n, float(s)) for s, n in over])


def machine_speed() -> float:
    """Seconds of one core for a fixed pure-Python loop (the sum of 10**7 squares), best of 3:
    the same VM type runs from fast to 2-3x slower by the hour, so each table carries it."""
    best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        sum(i * i for i in range(10**7))
        best = min(best, time.perf_counter() - t0)
    return round(best, 2)


def run(clone: Path, home: Path, target: str, hog: bool) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PVVJAX_", "JAX_", "XDG_", "PYTEST_"))}
    env["HOME"] = str(home)
    env["PYTEST_ADDOPTS"] = f"--junitxml={clone / 'junit.xml'}"  # every test's seconds, for where the time goes
    procs = []
    if hog:
        stop = time.time() + 3600
        procs = [multiprocessing.Process(target=_hog, args=(stop,), daemon=True) for _ in range(os.cpu_count() or 2)]
        for p in procs:
            p.start()
    t0 = time.perf_counter()
    # Ctrl-C as a terminal gives it (a benchmark started in the background inherits it ignored).
    out = subprocess.run(["make", target], cwd=clone, env=env, capture_output=True, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    wall = time.perf_counter() - t0
    for p in procs:
        p.terminate()
    (clone / f"make-{target}.log").write_text(out.stdout + out.stderr)
    cache = home / ".cache" / "pvvjax" / "jax"  # one entry per program compiled (by every process)
    programs = sum(1 for p in cache.iterdir() if p.is_file()) if cache.is_dir() else 0
    return dict(returncode=out.returncode, wall_s=round(wall, 1), programs_cached=programs, **summarise(out.stdout))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, default=None, help="folder for the clones and the HOME (default: a new one)")
    ap.add_argument("--runs", default="new,second,loaded", help="which runs, in order: new, second, loaded")
    ap.add_argument("--target", default="test", help="the make target (default: test)")
    args = ap.parse_args(argv)
    work = args.work or Path(tempfile.mkdtemp(prefix="pvvjax-suite-"))
    work.mkdir(parents=True, exist_ok=True)
    home = work / "home"
    home.mkdir(exist_ok=True)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    results = []
    for i, kind in enumerate(args.runs.split(",")):
        clone = work / f"clone-{i}-{kind}"
        subprocess.run(["git", "clone", "--quiet", str(ROOT), str(clone)], check=True)
        print(f"{kind}: make {args.target} in {clone} (HOME={home}) ...", flush=True)
        speed = machine_speed()
        res = dict(run=kind, commit=commit, python_loop_s=speed, **run(clone, home, args.target, hog=kind == "loaded"))
        print(json.dumps(res), flush=True)
        results.append(res)
    (work / "suite.json").write_text(json.dumps(results, indent=1))
    print(f"\n| run | commit | make {args.target} (m:s) | pytest (s) | passed | failed | over 15 s | programs cached "
          "| 10**7 squares (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in results:
        m, s = divmod(r["wall_s"], 60)
        c = r["counts"]
        print(f"| {r['run']} | {r['commit']} | {int(m)}:{s:04.1f} | {r['pytest_s']:.0f} | {c.get('passed', 0)} "
              f"| {c.get('failed', 0)} | {len(r['over_budget'])} | {r['programs_cached']} "
              f"| {r['python_loop_s']} |")
    return 0 if all(r["returncode"] == 0 for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
