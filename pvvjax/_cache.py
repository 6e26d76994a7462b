"""The one folder where pvvjax keeps what it can recompute (generated campaigns, campaign
fingerprints): `$PVVJAX_CACHE`, else `.cache/` of a source checkout, else `~/.cache/pvvjax`."""

from __future__ import annotations

import os
from pathlib import Path


def cache_dir() -> Path:
    """pvvjax's cache folder (not created here)."""
    env = os.environ.get("PVVJAX_CACHE")
    if env:
        return Path(env)
    root = Path(__file__).resolve().parents[1]
    return root / ".cache" if (root / "pyproject.toml").exists() else Path.home() / ".cache" / "pvvjax"
