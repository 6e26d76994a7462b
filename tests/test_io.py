"""Result tables: Parquet and CSV with their config, and Markdown for reports."""

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pvvjax.config import ExperimentConfig
from pvvjax.io import markdown_table, read_table, write_table


def test_tables_round_trip_with_their_config(tmp_path):
    df = pd.DataFrame({"a": [1.5, 2.0], "b": ["x", "y"]})
    parquet, csv = write_table(df, tmp_path / "t", ExperimentConfig(name="io"))
    pd.testing.assert_frame_equal(pd.read_csv(csv), df)
    back, cfg = read_table(parquet)
    pd.testing.assert_frame_equal(back, df)
    assert cfg["name"] == "io"


def test_markdown_table_formats_floats_and_nan():
    df = pd.DataFrame({"name": ["a", "b"], "g": [0.12345, np.nan], "n": [3, 4], "f32": np.float32([1.5, 2.25])})
    assert markdown_table(df).splitlines() == [
        "| name | g | n | f32 |", "|---|---|---|---|", "| a | 0.123 | 3 | 1.500 |", "| b | nan | 4 | 2.250 |"]
    assert markdown_table(df, "{:.3g}", nan="").splitlines()[3] == "| b |  | 4 | 2.25 |"


@pytest.mark.check
def test_compiled_programs_are_cached_for_the_user_outside_any_checkout(tmp_path):
    """The CLI's persistent compilation cache is the user's (shared by every clone, so a new
    clone starts warm), or under $PVVJAX_CACHE, and it is bounded in size."""
    import subprocess
    import sys

    probe = ("import jax; from pvvjax.experiment import enable_compilation_cache; enable_compilation_cache(); "
             "print(jax.config.jax_compilation_cache_dir)")
    env = {k: v for k, v in os.environ.items() if k not in ("JAX_COMPILATION_CACHE_DIR", "PVVJAX_CACHE",
                                                              "XDG_CACHE_HOME")}
    home = subprocess.run([sys.executable, "-c", probe], env={**env, "HOME": str(tmp_path)}, cwd=tmp_path,
                          capture_output=True, text=True, check=True).stdout.split()
    assert home == [str(tmp_path / ".cache" / "pvvjax" / "jax")]
    assert Path(__file__).parents[1] not in Path(home[0]).parents
    own = subprocess.run([sys.executable, "-c", probe], env={**env, "PVVJAX_CACHE": str(tmp_path / "c")},
                         capture_output=True, text=True, check=True).stdout.split()
    assert own[0] == str(tmp_path / "c" / "jax")


def test_the_compile_cache_is_pruned_least_recently_used_first(tmp_path):
    from pvvjax._cache import prune_compile_cache

    for i in range(5):  # entries of 100 bytes, used at times 10, 20, ..., 50
        p = tmp_path / f"e{i}-cache"
        p.write_bytes(b"x" * 100)
        os.utime(p, (10.0 * (i + 1), 10.0 * (i + 1)))
    os.utime(tmp_path / "e0-cache", (60.0, 60.0))  # the oldest entry read last
    assert prune_compile_cache(tmp_path, max_bytes=250) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e0-cache", "e4-cache"]
    assert prune_compile_cache(tmp_path, max_bytes=250) == 0 and prune_compile_cache(tmp_path / "none") == 0
