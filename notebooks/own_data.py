# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Bringing your own flight-test data
#
# pvvjax reads a campaign folder in one documented format (`docs/data-contract.md`):
# `counters.csv` (one row per counter: maneuver, condition, constants such as weight) and
# one time series per counter in `timeseries/`. Real data rarely arrive with pvvjax's column
# names and units; a column mapping in the experiment config renames and converts them,
# and validation names every problem (file, column, first bad row) instead of failing deep
# inside the pipeline.
#
# To have something to work on, this notebook writes three counters of the embedded
# synthetic campaign in a *foreign* layout: other column names, SI units, the sticks as
# fractions, the acceleration in m/s², and one bad sample.

# %%
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

import pvvjax
from pvvjax.config import ColumnMap, load_config
from pvvjax.synth import SynthConfig, generate

counters, records, _ = generate(SynthConfig(conditions=("11022", "T1-level-135", "T1-climb-62")))
foreign = Path(tempfile.mkdtemp()) / "my-campaign"
(foreign / "timeseries").mkdir(parents=True)
rename = {"time_s": "t", "az_g": "acc_z", "rotor_rpm": "nr", "airspeed_kt": "tas", "pitch_rate_dps": "q",
          "roll_angle_deg": "phi", "climb_rate_fpm": "vz", "collective_pct": "coll", "lateral_pct": "lat",
          "longitudinal_pct": "lon"}
for name, df in records.items():
    out = pd.DataFrame({
        "t": df.time_s, "acc_z": df.az_g * 9.80665, "nr": df.rotor_rpm, "tas": df.airspeed_kt * 1852 / 3600,
        "q": np.deg2rad(df.pitch_rate_dps), "phi": df.roll_angle_deg, "vz": df.climb_rate_fpm * 0.3048 / 60,
        "coll": df.collective_pct / 100, "lat": df.lateral_pct / 100, "lon": df.longitudinal_pct / 100,
    })
    out.to_csv(foreign / "timeseries" / f"{name}.csv", index=False)
table = counters.rename(columns={"gross_weight_lb": "mass_kg"})
table["mass_kg"] = table.mass_kg * 0.45359237
table.to_csv(foreign / "counters.csv", index=False)
pd.read_csv(foreign / "timeseries" / "11022.csv").head(3)

# %% [markdown]
# ## 1. Validation names every problem
#
# Without a mapping, every canonical column is missing; the report lists them all at once.

# %%
problems = pvvjax.validate_campaign(foreign)
print(f"{len(problems)} problems, for example:")
for p in problems[:4]:
    print(" ", p)

# %% [markdown]
# ## 2. The column mapping
#
# In a config file it reads
#
# ```toml
# [campaign]
# path = "my-campaign"
# [campaign.columns.tas]
# to = "airspeed_kt"
# unit = "m/s"
# [campaign.columns.coll]
# to = "collective_pct"
# unit = "fraction"
# ```
#
# and so on for each column; `unit` converts to the canonical unit of the target, `scale`
# and `offset` handle anything else.

# %%
units = {"t": "s", "acc_z": "m/s^2", "nr": "rpm", "tas": "m/s", "q": "rad/s", "phi": "deg", "vz": "m/s",
         "coll": "fraction", "lat": "fraction", "lon": "fraction", "mass_kg": "kg"}
targets = {**{v: k for k, v in rename.items()}, "mass_kg": "gross_weight_lb"}
lines = ["[campaign]", f'path = "{foreign.as_posix()}"']
for col, unit in units.items():
    lines += [f"[campaign.columns.{col}]", f'to = "{targets[col]}"', f'unit = "{unit}"']
cfg_path = foreign.parent / "my-experiment.toml"
cfg_path.write_text("\n".join(lines) + "\n")
cfg = load_config(cfg_path)
print(cfg.campaign.columns["tas"], "->", ColumnMap("airspeed_kt", "m/s").factor(), "kt per m/s")

# %%
campaign = pvvjax.load_campaign(foreign, cfg.campaign.columns)
rec = campaign.records["11022"]
np.testing.assert_allclose(rec.airspeed_kt, records["11022"].airspeed_kt, rtol=1e-5)
np.testing.assert_allclose(rec.collective_pct, records["11022"].collective_pct, rtol=1e-5)
rec[["time_s", "az_g", "airspeed_kt", "pitch_rate_dps", "collective_pct"]].head(3)

# %% [markdown]
# ## 3. One bad sample
#
# A sensor drop-out (a NaN in the middle of a record) is reported with its file, column and
# first bad row, not carried silently into the harmonic analysis.

# %%
bad = pd.read_csv(foreign / "timeseries" / "T1-climb-62.csv")
bad.loc[1234, "tas"] = np.nan
bad.to_csv(foreign / "timeseries" / "T1-climb-62.csv", index=False)
for p in pvvjax.validate_campaign(foreign, cfg.campaign.columns):
    print(p)
bad.loc[1234, "tas"] = bad.loc[1233, "tas"]  # repaired (here: the previous sample)
bad.to_csv(foreign / "timeseries" / "T1-climb-62.csv", index=False)
assert not pvvjax.validate_campaign(foreign, cfg.campaign.columns)

# %% [markdown]
# ## 4. Your data through the pipeline
#
# From here on the campaign is like any other: harmonic analysis, peak PVV per condition,
# databases 1–3, and everything after them.

# %%
dbs = pvvjax.build_databases(pvvjax.load_campaign(foreign, cfg.campaign.columns))
dbs["db1"]
