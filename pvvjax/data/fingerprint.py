"""A campaign's content fingerprint: what results record, so that a changed campaign is
never taken for the one a result came from.

The fingerprint hashes the bytes of every file of the campaign (`campaign.toml`,
`counters.csv`, `timeseries/*`), not their names' folder: a campaign moved elsewhere keeps
its fingerprint, one regenerated in place gets a new one. Hashing a large campaign takes a
while, so file sizes and modification times are the quick key: while they are unchanged
the hash computed last time is reused (kept in the pvvjax cache folder).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import pandas as pd

from .._cache import cache_dir

__all__ = ["campaign_files", "campaign_fingerprint", "frames_fingerprint", "tables_fingerprint"]


def campaign_files(folder) -> list[Path]:
    """The files that make up a campaign folder, in a fixed order."""
    folder = Path(folder)
    files = [folder / n for n in ("campaign.toml", "counters.csv") if (folder / n).is_file()]
    ts = folder / "timeseries"
    if ts.is_dir():
        files += sorted(p for p in ts.iterdir() if p.suffix in (".csv", ".parquet") and p.is_file())
    return files


def _cache_file() -> Path:
    return cache_dir() / "fingerprints.json"


def campaign_fingerprint(folder) -> str:
    """Content hash (16 hex digits) of a campaign folder's files; sizes and mtimes as a quick key."""
    folder = Path(folder).resolve()
    files = campaign_files(folder)
    stats = [(str(p.relative_to(folder)), p.stat().st_size, p.stat().st_mtime_ns) for p in files]
    quick = hashlib.sha256(json.dumps([str(folder), stats]).encode()).hexdigest()
    cache = _cache_file()
    try:
        known = json.loads(cache.read_text())
    except (OSError, ValueError):
        known = {}
    if quick in known:
        return known[quick]
    h = hashlib.sha256()
    for p in files:
        h.update(str(p.relative_to(folder)).encode() + b"\0")
        with open(p, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    digest = h.hexdigest()[:16]
    known[quick] = digest
    try:  # a cache that cannot be written only costs the next hash
        cache.parent.mkdir(parents=True, exist_ok=True)
        tmp = cache.with_name(f"{cache.name}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(known))
        tmp.replace(cache)
    except OSError:
        pass
    return digest


def tables_fingerprint(tables) -> str:
    """Content hash (16 hex digits) of named tables (`name -> DataFrame`, in their order):
    names, columns and values."""
    h = hashlib.sha256()
    for name, df in tables.items():
        h.update(f"{name}\0{','.join(map(str, df.columns))}\0".encode())
        h.update(pd.util.hash_pandas_object(df, index=False).to_numpy().tobytes())
    return h.hexdigest()[:16]


def frames_fingerprint(counters: pd.DataFrame, records) -> str:
    """Content hash (16 hex digits) of in-memory campaign tables (counter order and values)."""
    return tables_fingerprint({"counters.csv": counters, **{f"timeseries/{k}": v for k, v in records.items()}})
