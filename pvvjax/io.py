"""Result tables on disk: Parquet and CSV side by side, with the config that made them; and
as Markdown for reports."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ._strict import to_dict

__all__ = ["markdown_table", "read_table", "write_config", "write_table"]

_META_KEY = b"pvvjax.config"


def write_table(df: pd.DataFrame, stem: str | Path, config=None) -> tuple[Path, Path]:
    """Write `df` to `stem.parquet` and `stem.csv`; the config (a dataclass) is stored in the
    Parquet schema metadata. Files are written under a temporary name and renamed, so a
    killed write never leaves a half file under the final name.

    Returns:
        The two paths.
    """
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    table = pa.Table.from_pandas(df, preserve_index=False)
    if config is not None:
        meta = dict(table.schema.metadata or {})
        meta[_META_KEY] = json.dumps(to_dict(config), sort_keys=True, default=str).encode()
        table = table.replace_schema_metadata(meta)
    pq_path, csv_path = stem.with_suffix(".parquet"), stem.with_suffix(".csv")
    tmp = pq_path.with_name(pq_path.name + ".tmp")
    pq.write_table(table, tmp)
    tmp.replace(pq_path)
    tmp = csv_path.with_name(csv_path.name + ".tmp")
    df.to_csv(tmp, index=False)
    tmp.replace(csv_path)
    return pq_path, csv_path


def read_table(path: str | Path) -> tuple[pd.DataFrame, dict | None]:
    """Read a Parquet result table and the config stored with it (or None)."""
    table = pq.read_table(path)
    meta = (table.schema.metadata or {}).get(_META_KEY)
    return table.to_pandas(), (json.loads(meta) if meta else None)


def write_config(cfg, path: str | Path) -> Path:
    """Write a config dataclass as TOML (the exact settings a result came from)."""
    import tomli_w

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(tomli_w.dumps(to_dict(cfg)))
    return path


def markdown_table(df: pd.DataFrame, fmt: str = "{:.3f}", nan: str | None = None) -> str:
    """A table as Markdown: floats through `fmt`, NaN as `nan` (default: through `fmt`),
    everything else as `str`."""
    def cell(v):
        if isinstance(v, (float, np.floating)):
            return nan if nan is not None and np.isnan(v) else fmt.format(v)
        return str(v)

    lines = ["| " + " | ".join(str(c) for c in df.columns) + " |", "|" + "---|" * len(df.columns)]
    lines += ["| " + " | ".join(cell(v) for v in r) + " |" for r in df.itertuples(index=False)]
    return "\n".join(lines)
