"""Result tables: Parquet and CSV with their config, and Markdown for reports."""

import numpy as np
import pandas as pd

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
