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
# # pvvjax quickstart
#
# From a flight-test campaign to the paper's training databases in a few calls: load the
# embedded synthetic UH-60A campaign, analyse the 4/rev vibration of the pull-up 11022,
# and build databases 1-3.

# %%
import matplotlib.pyplot as plt
import numpy as np

import pvvjax
from pvvjax.synth import SynthConfig, cached_campaign

# %% tags=["parameters"]
campaign_config = SynthConfig()  # the embedded campaign; set `counts`, `seed`, ... for another

# %%
folder = cached_campaign(campaign_config)  # generated once (a few seconds), then cached
campaign = pvvjax.load_campaign(folder)
print(len(campaign), "counters;", len(campaign.conditions()), "conditions")
campaign.counters.head()

# %% [markdown]
# ## Harmonic analysis of one counter
# Windows of 8 rotor revolutions, 4/rev amplitude (PVV) and the flight state averaged over
# each window. The window length is continuous: try 6.5 revolutions.

# %%
batch = pvvjax.to_batch(campaign, ["pitch_rate_dps", "airspeed_kt"], counters=["11022"])
fig, ax = plt.subplots(figsize=(7, 3))
for L in (8.0, 6.5):
    w = pvvjax.analyze(batch, window_revs=L)
    valid = np.asarray(w.valid[0])
    ax.step(np.asarray(w.time[0])[valid], np.asarray(w.amplitude[0])[valid], where="mid", label=f"L = {L} revs")
ax.set_xlabel("time, s")
ax.set_ylabel("4P PVV, g")
ax.set_title("Pull-up 11022")
ax.legend()
print("peak PVV (8 revs):", float(np.max(np.asarray(pvvjax.analyze(batch, 8.0).amplitude))))

# %% [markdown]
# ## The maneuver load factor of the paper's worked example

# %%
mu = 0.27
v_kt = float(mu * 255 * 2 * np.pi / 60 * pvvjax.UH60A.rotor_radius_ft / (6076.12 / 3600))
print(f"airspeed {v_kt:.1f} kt, MLF = {float(pvvjax.maneuver_load_factor(0.0, 9.6, v_kt)):.3f}")

# %% [markdown]
# ## Databases 1-3
# Peak PVV per flight condition, with every input taken at the peak window.

# %%
dbs = pvvjax.build_databases(campaign)
print({k: v.shape for k, v in dbs.items()})
dbs["db1"].set_index("condition").loc[
    ["T1-level-135", "T1-descent-160", "T1-climb-62", "T1-turn45-145", "11022", "AR60"]]
