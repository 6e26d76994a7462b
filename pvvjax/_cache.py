"""Where pvvjax keeps what it can recompute.

Generated campaigns and campaign fingerprints go to `cache_dir()`: `$PVVJAX_CACHE`, else
`.cache/` of a source checkout (their keys name the generator's version, which a checkout
may change without a new release), else `~/.cache/pvvjax`. Compiled XLA programs go to
`compile_cache_dir()`, outside any checkout: JAX keys each program by its computation,
compiler and devices, never by the path of the code, so every clone and installed copy on a
machine shares them, and a fresh clone starts warm.
"""

from __future__ import annotations

import os
from pathlib import Path

COMPILE_CACHE_BYTES = 2 << 30  # the compiled-program cache is pruned (least recently used first) above 2 GiB


def cache_dir() -> Path:
    """pvvjax's cache folder for campaigns and fingerprints (not created here)."""
    env = os.environ.get("PVVJAX_CACHE")
    if env:
        return Path(env)
    root = Path(__file__).resolve().parents[1]
    return root / ".cache" if (root / "pyproject.toml").exists() else user_cache_dir()


def user_cache_dir() -> Path:
    """`$XDG_CACHE_HOME/pvvjax`, else `~/.cache/pvvjax`."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "pvvjax"


def compile_cache_dir() -> Path:
    """The persistent compilation cache: `$PVVJAX_CACHE/jax`, else `~/.cache/pvvjax/jax`
    (the user's, shared by every checkout)."""
    env = os.environ.get("PVVJAX_CACHE")
    return (Path(env) if env else user_cache_dir()) / "jax"


def prune_compile_cache(folder: Path | None = None, max_bytes: int = COMPILE_CACHE_BYTES) -> int:
    """Delete the least recently used entries of the compiled-program cache until it holds
    at most `max_bytes`; the number deleted.

    One scan of the folder, run once as a process enables the cache: JAX's own bound
    (`jax_compilation_cache_max_size`) rescans the whole folder at every write, which costs
    more than the compilations it saves once the folder holds thousands of small programs.
    """
    folder = compile_cache_dir() if folder is None else Path(folder)
    try:
        entries = [(max(st.st_atime, st.st_mtime), st.st_size, p) for p in folder.iterdir()
                   if p.is_file() and (st := p.stat())]
    except OSError:  # no cache yet, or another process is pruning it
        return 0
    total, removed = sum(size for _, size, _ in entries), 0
    for _, size, path in sorted(entries, key=lambda e: e[0]):
        if total <= max_bytes:
            break
        try:
            path.unlink()
        except OSError:
            continue
        total -= size
        removed += 1
    return removed
