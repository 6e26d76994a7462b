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
# # Discovery: from a residual map to a closed gap
#
# A static map from flight state to peak vibration misses physics. Here a synthetic campaign
# hides one effect from the db1 model, and the discovery workflow has to find it from the
# data alone: where the held-out replays miss, which candidate explains the miss beyond any
# function of the map's own inputs (one test, at 5 % family-wise), and whether adding it to
# the model and retraining closes the gap.
#
# The world is the default physics without the terms db1's inputs cannot carry (the
# measured load factor, the pitch- and roll-rate transients, the base's lag, the rotor-speed
# resonance), with about half the random conditions of a benchmark world (129 counters),
# plus a hidden sideslip effect. The settings are light (3 seeds) so that the notebook runs
# in about a minute. The generator's ground truth stays in a variable that the workflow never
# sees; it is opened at the end. The test suite runs this notebook, and its last cells assert
# what the benchmark asks of a hidden effect.

# %%
import json
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt

from pvvjax import plots
from pvvjax.analysis import DB_INPUTS
from pvvjax.config import DiscoveryConfig, EnsembleConfig, ExperimentConfig, OffsetConfig, TrainConfig, from_dict
from pvvjax.data.campaign import campaign_from_frames
from pvvjax.discovery import discover, gcm_test, summary
from pvvjax.synth import SynthConfig, generate

# %% tags=["parameters"]
counts = dict(level=40, climb=10, descent=13, turn=8, roll=6, pushover=4, pullup=6, flare=3)  # random conditions
seeds, max_steps = 3, 2000  # light settings (below)

# %%
base = dict(seed=41, maneuvers=["level", "climb", "descent", "turn", "roll", "pushover", "pullup", "flare"],
            counts=counts, load_factor="kinematic",
            effects={"roll_rate": {"enabled": False}, "pitch_rate": {"enabled": False},
                     "rotor_resonance": {"enabled": False}, "dynamic_lag": {"enabled": False}})
hidden = {"sideslip": {"enabled": True, "scale": 6.0}}  # the hidden effect
world = from_dict(SynthConfig, {**base, "name": "notebook-world", "effects": {**base["effects"], **hidden}})
counters, records, truth = generate(world)
campaign = campaign_from_frames(counters, records, source="notebook-world")
len(campaign), len(campaign.conditions())

# %% [markdown]
# ## Run the workflow
#
# db1 nets, 5-fold by condition over 3 seeds; every counter is replayed by the nets that
# held its condition out, at a fitted offset. Where that held-out residual is predictable
# from db1's own inputs, the misfit is named first by the forms of the inputs that carry it
# (knees, bands) and taken off. Then every candidate (channels, their magnitudes, rates,
# spreads, knees, bands and products, and lags of the model's own prediction) is tested for
# what it explains of what is left beyond any function of db1's inputs, with conditions as
# the units and Holm's step-down over the candidates; what passes is named, its parameters
# fitted, and the model retrained once with everything named.

# %%
# Light settings for a notebook: 3 seeds, a coarser offset grid, and at most 2000 training
# steps.
fast = dict(ensemble=EnsembleConfig(seeds=seeds), offset=OffsetConfig(step_s=0.25))
cfg = ExperimentConfig(train=TrainConfig(max_steps=max_steps), discovery=DiscoveryConfig(**fast))
res = discover(campaign, cfg, name="notebook-world")

# %% [markdown]
# ## 1. Localize: where the baseline misses

# %%
fig = plots.residual_map(res.localized, "held-out residual of the db1 baseline")
res.localized["maneuver"].round(4)

# %% [markdown]
# ## 2. Explain: what the test named
#
# Each round's smallest p-values (`left`: the share of a candidate's variance left once db1's
# inputs are partialled out; a candidate with nothing left cannot be named as missing).

# %%
res.tries.sort_values("p_value").head(10)

# %% [markdown]
# The files a run writes (`pvvjax discover` writes the same): `discovery.json` in the format of
# the data contract, `report.md` with its figures, and the tables behind them.

# %%
from pvvjax.discovery.report import write_discovery  # noqa: E402

report = write_discovery(res, Path(tempfile.mkdtemp()) / "discovery", cfg)
print(report.read_text()[:1500])
print(json.dumps(summary(res), indent=2))

# %% [markdown]
# ## 3. The effect's partial dependence and the closed gap
#
# The baseline residual, binned against the first missing effect's value per window, and
# what the augmented model changed there.

# %%
w = res.windows[res.windows.weight >= 0.999]
missing = [e for e in res.effects if e.kind == "missing"]
if missing:
    e = missing[0]
    fig = plots.partial_dependence(w[f"effect_{e.rank}"], w.measured_g - w.predicted_before_g,
                                   w.predicted_after_g - w.predicted_before_g, e.name, e.name)

# %%
worst = (w.assign(r2=(w.measured_g - w.predicted_before_g) ** 2).groupby("counter").r2.mean()
         .sort_values(ascending=False).index[0])
g = w[w.counter == worst]
fig = plots.replay({"baseline": g.assign(predicted_g=g.predicted_before_g),
                    "augmented": g.assign(predicted_g=g.predicted_after_g)}, f"counter {worst}: before and after")

# %% [markdown]
# ## 4. How much of the gap was the hidden effect's?
#
# The same world generated without the effect (same seed) gives the baseline error the
# model would have had anyway (its floor); the attributable shrink is the share of the gap
# the effect opened that adding it closed: (before − after) / (before − before without it).

# %%
plain = from_dict(SynthConfig, {**base, "name": "notebook-world-without"})
c2, r2, _ = generate(plain)
without = discover(campaign_from_frames(c2, r2, source="without"),
                   cfg.with_(discovery=DiscoveryConfig(max_effects=0, **fast)), log=lambda m: None)
attributable = (res.before["rms_g"] - res.after["rms_g"]) / (res.before["rms_g"] - without.before["rms_g"])
print(f"held-out RMS: without the effect {without.before['rms_g']:.4f} g; with it {res.before['rms_g']:.4f} g "
      f"before discovery, {res.after['rms_g']:.4f} g after; attributable shrink {attributable:.0%}")

# %% [markdown]
# Could the test have seen the truth? The true per-window effect (the measured PVV with the
# effect minus the same window without it) tested the same way, told the answer: the
# oracle. Where the oracle does not detect it either, no search on this residual could.

# %%
both = res.windows[["counter", "window", "measured_g"]].merge(
    without.windows[["counter", "window", "measured_g"]], on=["counter", "window"], how="left", suffixes=("", "_0"))
full = (res.windows.weight >= 0.999).to_numpy() & both.measured_g_0.notna().to_numpy()
true_effect = (both.measured_g - both.measured_g_0).to_numpy()[full]
held = res.windows[full]
oracle = gcm_test((held.measured_g - held.predicted_before_g).to_numpy(), true_effect, held.condition.to_numpy(),
                  held[list(DB_INPUTS["db1"])].to_numpy())
print(f"the oracle: t = {oracle.statistic:.2f}, p = {oracle.p_value:.2g}")

# %% [markdown]
# ## 5. Open the ground truth

# %%
print("hidden:", truth["hidden"])
print("named: ", [e.name for e in res.effects])
plt.close("all")

# %% tags=["checks"]
first = next(e for e in summary(res)["effects"] if e["kind"] == "missing")
assert "sideslip_deg" in first["channels"] or any("sideslip" in k for k in first["tied"]), first
assert attributable >= 0.5, attributable
