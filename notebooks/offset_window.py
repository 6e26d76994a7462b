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
# # The input-to-vibration offset and the window length, by gradient
#
# The paper replayed the pull-up 11022 through its networks with the flight state averaged
# over 8-revolution windows, saw the predicted peak about a second late, shifted the inputs
# by half a window by hand, and asked for a systematic optimisation of that offset (and a
# study of the window length). Here both are fitted by gradient.
#
# To run in about a minute this notebook trains small RBF networks (5-fold cross-validation
# by condition) instead of the paper's back-propagation nets; `experiments/replay_study.py`
# does the same with the paper networks.

# %%
import tempfile

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

import pvvjax
from pvvjax import plots
from pvvjax.config import ExperimentConfig, SweepConfig
from pvvjax.replay.calibration import calibrate, cost_grid, group_members
from pvvjax.replay.quasistatic import make_settings, replay, replay_cost
from pvvjax.replay.tables import load_replay_set, peak_summary, replay_windows
from pvvjax.synth import SynthConfig, cached_campaign

# %% tags=["parameters"]
campaign_config = SynthConfig()  # the embedded campaign; set `counts`, `seed`, ... for another

# %%
campaign = pvvjax.load_campaign(cached_campaign(campaign_config))
dbs = pvvjax.build_databases(campaign)
sweep_dir = tempfile.mkdtemp()
cfg = ExperimentConfig(sweep=SweepConfig(databases=("db1", "db3"), family="rbf", centers=(24,), seeds=2))
results = pvvjax.run_sweep(cfg, dbs, sweep_dir, log=lambda *a: None)
results.groupby("database").test_rms_g.median()

# %% [markdown]
# ## Replay the maneuvers
# Every pull-up, pushover and roll counter (add "autorotation" and "flare" for the whole
# campaign), each through the nets that held its condition out.

# %%
kinds = ["pullup", "pushover", "roll"]
counters = list(campaign.counters[campaign.counters.maneuver.isin(kinds)].index)
info, batch, recs, models = load_replay_set(campaign, counters, sweep_dir, ["db1", "db3"])
i = counters.index("11022")
rpm = campaign.records["11022"].rotor_rpm.mean()
half = 4 / (rpm / 60)  # half an 8-rev segment, s
settings8 = make_settings(batch, min_window_revs=8.0, max_window_revs=8.0, offset_bounds=(0.0, 1.5))
one = info.loc[["11022"]]
take = lambda tree: jax.tree.map(lambda a: a[np.array([i])], tree)  # noqa: E731
series = {}
for tau in (0.0, half):
    w = replay_windows(one, take(recs), {"db1": take(models["db1"])}, (tau, 8.0, 0.0), settings8)
    series[f"db1, offset {tau:.2f} s"] = w
plots.replay(series, "pull-up 11022: zero and half-segment offset (paper Figs 13a, 14a)")
peak_summary(w)[["database", "measured_peak_g", "predicted_peak_g", "phase_error_s"]]

# %% [markdown]
# ## The cost and its gradient
# Peak error (g), phase error (time of the peak, s) and RMS, each scaled (0.02 g and 1 s cost
# 1) and summed. The peak and its time are soft maxima, so the cost is differentiable in the
# offset and in the window length; windows integrate the linear interpolant of the samples,
# so the gradient has no jumps at whole-sample offsets.

# %%
settings = make_settings(batch, min_window_revs=4.0, max_window_revs=16.0, hop_revs=2.0, offset_bounds=(-1.0, 3.0))
m1, r1 = jax.tree.map(lambda a: a[i], (models["db1"], recs))


# The nets and the record are arguments, not constants closed over: the compiled cost and
# gradient then serve every counter of the set (its records share one padded length).
def pullup_cost(tau, L, model, rec):
    return replay_cost(replay(model, rec, tau, L, settings=settings))


cost = jax.jit(pullup_cost)
grad = jax.jit(jax.grad(pullup_cost, argnums=(0, 1)))
for tau in (0.0, 0.5, 1.0):
    g = grad(tau, 8.0, m1, r1)
    print(f"offset {tau:.1f} s: cost {float(cost(tau, 8.0, m1, r1)):7.2f}, d/d offset {float(g[0]):7.2f}, "
          f"d/d L {float(g[1]):6.2f}")

# %% [markdown]
# ## One offset and window length for all maneuvers
# Levenberg-Marquardt from the best point of a coarse grid, vmapped over the
# two databases; a brute-force grid checks it.

# %%
members, mask = group_members(np.zeros(len(counters), int))
coarse = np.stack(np.meshgrid(np.arange(-1, 3.01, 0.5), [6.0, 10.0, 14.0], indexing="ij"), -1).reshape(-1, 2)
stacked = jax.tree.map(lambda *a: jnp.stack(a), models["db1"], models["db3"])
cal = jax.vmap(lambda m: calibrate(m, recs, members, mask, jnp.array([0.0, 8.0, 0.0]), coarse,
                                   free=("offset_s", "window_revs"), settings=settings))(stacked)
for d, db in enumerate(["db1", "db3"]):
    print(f"{db}: offset {float(cal.theta[d, 0, 0]):.2f} s, window {float(cal.theta[d, 0, 1]):.1f} revs, "
          f"cost {float(cal.start_cost[d, 0]):.1f} -> {float(cal.cost[d, 0]):.1f} in {int(cal.steps[d, 0])} steps")

offsets, lengths = np.arange(-1, 3.01, 0.5), np.arange(4, 16.01, 2.0)
grid = np.asarray(cost_grid(models["db1"], recs, members, mask, offsets, lengths, settings=settings))[0]
fig, ax = plt.subplots(figsize=(5.5, 4))
im = ax.pcolormesh(offsets, lengths, grid, shading="nearest")
fig.colorbar(im, label="mean cost")
ax.plot(float(cal.theta[0, 0, 0]), float(cal.theta[0, 0, 1]), "rx", ms=10, mew=2, label="gradient optimum")
ax.set_xlabel("offset, s")
ax.set_ylabel("window length, revs")
ax.legend()
ax.set_title("db1: replay cost over all maneuvers")

# %% [markdown]
# ## One offset per maneuver kind
# The same solve with one group per kind (vmapped over the groups).

# %%
kind_ids = {k: n for n, k in enumerate(dict.fromkeys(info.maneuver))}
members, mask = group_members([kind_ids[k] for k in info.maneuver])
per_kind = calibrate(models["db1"], recs, members, mask, jnp.array([0.0, 8.0, 0.0]),
                     np.arange(-1, 3.01, 0.5)[:, None], settings=settings)
{k: round(float(per_kind.theta[n, 0]), 2) for k, n in kind_ids.items()}
