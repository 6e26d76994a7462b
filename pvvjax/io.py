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

__all__ = ["OWNER_FILE", "ResultsFolderError", "claim_folder", "folder_kind", "listed", "markdown_table", "new_file",
           "own_folder", "read_table", "refuse_in_campaign", "write_config", "write_table"]

_META_KEY = b"pvvjax.config"
OWNER_FILE = "owner.json"


class ResultsFolderError(ValueError):
    """A results folder that holds the results of other settings or another campaign."""


def _flat(tree, prefix=""):
    if isinstance(tree, dict):
        out = {}
        for k, v in tree.items():
            out.update(_flat(v, f"{prefix}{k}."))
        return out
    return {prefix[:-1]: tree}



def listed(items, most: int = 5, sep: str = ", ") -> str:
    """At most `most` items joined by `sep`, then how many more there are: a message names
    the files, records or conditions at fault without listing hundreds."""
    items = [str(i) for i in items]
    return sep.join(items[:most]) + (f"{sep}and {len(items) - most} more" if len(items) > most else "")


def refuse_in_campaign(path: str | Path, itself: bool = True) -> None:
    """Refuse a path in a campaign folder (one holding `counters.csv` and `timeseries/`): a
    command never writes among a campaign's files, where a result could pass for data.

    Args:
        path: the output.
        itself: whether `path` being a campaign folder counts (not for a campaign's writer).

    Raises:
        ResultsFolderError: naming the path and the campaign folder.
    """
    path = Path(path)
    for p in (path.resolve(), *path.resolve().parents)[0 if itself else 1:]:
        if (p / "counters.csv").is_file() and (p / "timeseries").is_dir():
            where = "is the campaign folder" if p == path.resolve() else f"lies inside the campaign folder {p}"
            raise ResultsFolderError(f"{path}: {where}; give an output outside the campaign")


def own_folder(out: str | Path, command: str) -> Path:
    """Make `out` a folder of `command`'s outputs (figures, an exported net or element), or
    refuse: a new or empty folder is claimed (`owner.json` names the command); one the same
    command wrote before is written again (its files replaced); anything else (a user's
    files, another command's results, a campaign) is refused by name, so that a command
    never writes over a file it did not write.

    Args:
        out: the folder (created if missing).
        command: what writes there, e.g. "pvvjax export"; recorded and compared.

    Raises:
        ResultsFolderError: as above.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ResultsFolderError(f"{out}: is a file, not a folder; give a folder for the output")
    refuse_in_campaign(out)
    record = {"written_by": command}
    old = _owner_record(out)
    if old is not None:
        if old != record:
            what = f"the output of {old['written_by']}" if "written_by" in old else "results of pvvjax's other commands"
            raise ResultsFolderError(f"{out}: holds {what}, not of {command}; give another output folder")
    elif out.exists() and any(out.iterdir()):
        raise ResultsFolderError(f"{out}: is not empty and was not written by {command}; give a new or empty folder")
    out.mkdir(parents=True, exist_ok=True)
    (out / OWNER_FILE).write_text(json.dumps(record))
    return out


def _owner_record(out: Path) -> dict | None:
    """The folder's owner record (`owner.json`; {} if unreadable), or None if it has none."""
    owner = out / OWNER_FILE
    if not owner.exists():
        return None
    try:
        return json.loads(owner.read_text())
    except ValueError:
        return {}


def new_file(path: str | Path, flag: str = "--out") -> Path:
    """Check that `path` is a new file outside any campaign folder, for a command that
    writes one file (its parent folder is created). An existing file is never replaced.

    Raises:
        ResultsFolderError: naming `flag` and the path.
    """
    path = Path(path)
    if path.exists():
        raise ResultsFolderError(f"{flag} {path}: exists; give a new file name (a command never writes over a file)")
    refuse_in_campaign(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def claim_folder(out: str | Path, settings: dict, campaign: str, log=print, kind: str = "") -> Path:
    """Make `out` the results folder of these settings and campaign, or refuse.

    A folder belongs to the command and settings that first wrote into it (recorded in
    `owner.json`, the tool's own marker): the same settings and campaign again resume or
    rerun there; anything else is refused, naming what differs, so that the rows of two
    configs never mix in one table. A folder holding only results folders (each with its own
    record, as `pvvjax sweep` leaves `OUT_DIR/NAME/sweep` for the main job) is claimed as it
    is: each keeps its own record, checked when its stage resumes it. A non-empty folder
    without the marker is not the tool's, whatever files it holds: it is refused, never
    moved or written into.

    Args:
        out: the results folder (created if missing).
        settings: the config sections that decide its results (`to_dict` form).
        campaign: the campaign's content fingerprint.
        log: unused; kept for callers that pass it.
        kind: the command whose results these are ("sweep", "dynamic", "run", ...),
            recorded so that a reader of the folder knows what it holds (`folder_kind`).

    Raises:
        ResultsFolderError: `out` is a file, holds other settings' or another command's
            results, lies inside another results folder, or is not empty and not the tool's.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ResultsFolderError(f"{out}: is a file, not a folder; give a folder for the results")
    refuse_in_campaign(out)
    record = json.loads(json.dumps({"settings": settings, "campaign": campaign, **({"kind": kind} if kind else {})},
                                   sort_keys=True, default=str))
    owner = out / OWNER_FILE
    old = _owner_record(out)
    if old is not None:
        if old == record:
            return out
        if "written_by" in old:
            raise ResultsFolderError(f"{out}: holds the output of {old['written_by']}; give another output folder")
        if kind and old.get("kind", kind) != kind:
            raise ResultsFolderError(f"{out}: holds the results of `pvvjax {old['kind']}`, not of `pvvjax {kind}`; "
                                     "give another output folder")
        if {k: v for k, v in old.items() if k != "kind"} == {k: v for k, v in record.items() if k != "kind"}:
            owner.write_text(json.dumps(record, indent=1, sort_keys=True))  # a record from before kinds: add it
            return out
        was, now = _flat(old.get("settings", {})), _flat(record["settings"])
        diffs = [f"{k}: {was.get(k, '(unset)')!r} there, {now.get(k, '(unset)')!r} now"
                 for k in sorted(set(was) | set(now)) if was.get(k) != now.get(k)]
        if old.get("campaign") != campaign:
            diffs.append(f"campaign content: fingerprint {old.get('campaign')} there, {campaign} now")
        shown = listed(diffs, sep="; ")
        raise ResultsFolderError(f"{out}: holds the results of other settings ({shown}); give another output "
                                 "folder")
    parent = next((p for p in out.resolve().parents if (p / OWNER_FILE).exists()), None)
    if out.exists() and any(out.iterdir()) and parent is not None:
        raise ResultsFolderError(f"{out}: is part of the results folder {parent}, written there with its settings; "
                                 "give another output folder")
    # Only results folders of its stages (`pvvjax sweep` into OUT_DIR/NAME/sweep): a job resumes them.
    stages = out.exists() and all((p / OWNER_FILE).exists() for p in out.iterdir())
    if out.exists() and any(out.iterdir()) and not stages:
        raise ResultsFolderError(f"{out}: is not empty and has no {OWNER_FILE} (the marker pvvjax writes into its "
                                 "results folders), so it is not pvvjax's to write into; give a new or empty output "
                                 "folder")
    out.mkdir(parents=True, exist_ok=True)
    owner.write_text(json.dumps(record, indent=1, sort_keys=True))
    return out


def folder_kind(folder: str | Path) -> str | None:
    """The command whose results a folder holds, from its `owner.json` ("sweep", "dynamic",
    ...; "" for a record without a kind), or None if the folder has no record."""
    old = _owner_record(Path(folder))
    if old is None:
        return None
    settings = old.get("settings")
    return old.get("kind") or (settings.get("command", "") if isinstance(settings, dict) else "")


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
