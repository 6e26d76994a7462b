"""A rotor-speed band added to a benchmark world's baseline in each way discovery can add it:
a gain on the nets' output (learned in steps of 1 / `gain_unit`), an extra network input,
an additive term; the nets retrained each time, the held-out ensemble RMS before and after.

Each job is SEED_OFFSET:SCENARIO of the benchmark config. `--bands top` tries the band of
the grid at the top rotor speed (where the benchmark's mode acts), `all` every band of the
grid (on a null world: what a band could gain by chance). The numbers in docs/discovery-studies.md
("A band as a network input"):

    python experiments/resonance_modes_probe.py 11:rotor-resonance,14:rotor-resonance \\
        --modes gain1,gain10,input,additive
    python experiments/resonance_modes_probe.py 1:null-51 --modes input --bands all

Mode `truth` is the model told the world's own mode: nets trained on the peaks divided by
the magnification the generator applied, their predictions multiplied by it (a ceiling of
sorts for any band; it reads the generator's settings, which discovery never does).
`--net-seeds 0,100,...` repeats the baseline and every mode with the nets initialised from
the config's seed plus each shift, and `--null` adds the same seed's null world's baseline,
so that a mode's attributable shrink is read on the mean over seed sets: one set of four nets
per fold moves the ensemble RMS by ~7 % by itself ("What the true mode would close"):

    python experiments/resonance_modes_probe.py 16:rotor-resonance --modes gain10,truth \\
        --net-seeds 0,100,200,300 --null
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from discovery_benchmark import _campaign, scenario_configs  # noqa: E402
from term_backfit_probe import CONFIG, baseline, world, world_config  # noqa: E402

from pvvjax.analysis.databases import DB_INPUTS, OUTPUT  # noqa: E402
from pvvjax.data.constants import UH60A  # noqa: E402
from pvvjax.discovery._confirm import _augment, _train_model  # noqa: E402
from pvvjax.discovery._model import _predict, fit_ensemble, metrics, predictions  # noqa: E402
from pvvjax.discovery.candidates import Candidate, library, values  # noqa: E402
from pvvjax.synth import EFFECTS  # noqa: E402


def magnification(synth, rpm) -> np.ndarray:
    """The rotor-speed magnification a world's generator applied at these rotor speeds (1
    where its `rotor_resonance` is off): the truth, for the probe's `truth` mode only."""
    on, scale, params = synth.effect_settings()["rotor_resonance"]
    rpm = np.asarray(rpm, float)
    if not on:
        return np.ones_like(rpm)
    return 1.0 + scale * (EFFECTS["rotor_resonance"].fn({"f4": UH60A.blades * rpm / 60.0}, **params) - 1.0)


def _truth_ensemble(ctx, synth, offset: float, win) -> np.ndarray:
    """(S, n) held-out predictions of nets trained on the peaks divided by the world's own
    magnification, times it on each window."""
    rpm = Candidate("input", ("rotor_rpm",), {"offset_s": offset})
    d = ctx.cfg.discovery
    peaks = magnification(synth, values(rpm, ctx.train_table))
    params = fit_ensemble(ctx.x_db, ctx.db[OUTPUT].to_numpy(np.float64) / peaks, ctx.folds, k=d.folds,
                          seeds=d.seeds, hidden=d.hidden, train_cfg=ctx.cfg.train, seed=ctx.cfg.seed)
    x = win.table[list(DB_INPUTS[d.database])].to_numpy(np.float64)
    return _predict(params, ctx.counter_fold[win.table.i.to_numpy()], x) * magnification(synth, win.values(rpm))[None]


def _null_job(job: str) -> str | None:
    """The null scenario of the same seed as SEED_OFFSET:SCENARIO (None if it has none)."""
    offset, name = job.split(":")
    scs, _ = scenario_configs(CONFIG, int(offset))
    seed = next(s["seed"] for s in scs if s["name"] == name)
    null = next((s["name"] for s in scs if s["truth"] is None and s["seed"] == seed), None)
    return None if null is None else f"{offset}:{null}"


def _reseeded_baselines(ctx0, base0, shifts):
    """(context, baseline) per net-seed shift: the baseline's nets initialised from the
    config's seed plus the shift and retrained (the campaign, folds, offset and replay
    calibration unchanged; shift 0 is the workflow's own baseline)."""
    for shift in shifts:
        if not shift:
            yield ctx0, base0
            continue
        ctx = dataclasses.replace(ctx0, cfg=dataclasses.replace(ctx0.cfg, seed=ctx0.cfg.seed + shift))
        yield ctx, base0._replace(params=_train_model(ctx, base0))


def shrinks(job: str, modes, which: str = "top", shifts=(0,)) -> tuple[np.ndarray, list]:
    """The baseline's ensemble RMS per net-seed shift and, per band and mode, the ensemble RMS
    after, per shift: ([S], [(centre, mode, [S])])."""
    sc, cfg = world_config(job)
    campaign = _campaign(sc["synth"])
    ctx0, base0, win = baseline(campaign, cfg)
    bands = [c for c in library(win.at(base0.offset_s), model_inputs=base0.inputs) if c.operator == "resonance"]
    if which == "top":
        bands = bands[-1:]
    before, out = [], {}
    for ctx, base in _reseeded_baselines(ctx0, base0, shifts):
        before.append(metrics(predictions(ctx, base, win), win)["ensemble_rms_g"])
        if "truth" in modes:
            truth = _truth_ensemble(ctx, sc["synth"], base.offset_s, win)
            out.setdefault((None, "truth"), []).append(metrics(truth, win)["ensemble_rms_g"])
        for band in bands:
            band = replace(band, parameters={**band.parameters, "offset_s": base.offset_s})
            for mode in (m for m in modes if m != "truth"):
                how, unit = ("gain", float(mode[4:] or 1)) if mode.startswith("gain") else (mode, None)
                c = band if unit is None else replace(band, parameters={**band.parameters, "gain_unit": unit})
                after = metrics(predictions(ctx, _augment(ctx, base, c, how), win), win)["ensemble_rms_g"]
                out.setdefault((band.parameters["center"], mode), []).append(after)
    return np.array(before), [(c, m, np.array(v)) for (c, m), v in out.items()]


def null_baseline(job: str, shifts=(0,)) -> np.ndarray:
    """The ensemble RMS of a world's baseline per net-seed shift."""
    campaign, cfg = world(job)
    ctx0, base0, win = baseline(campaign, cfg)
    return np.array([metrics(predictions(ctx, base, win), win)["ensemble_rms_g"]
                     for ctx, base in _reseeded_baselines(ctx0, base0, shifts)])


def _where(center) -> str:
    """A row's band centre, "" for the `truth` mode (the world's own mode, not a band)."""
    return "" if center is None else f"{center:.1f} "


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("jobs", help="comma-separated SEED_OFFSET:SCENARIO")
    ap.add_argument("--modes", default="gain1,gain10,input",
                    help="gainU (a gain in steps of 1/U), input, additive, truth (the world's own mode)")
    ap.add_argument("--bands", choices=("top", "all"), default="top")
    ap.add_argument("--net-seeds", default="0", help="comma-separated shifts of the nets' seed (default 0)")
    ap.add_argument("--null", action="store_true", help="also the same seed's null world's baseline")
    args = ap.parse_args()
    shifts = [int(s) for s in args.net_seeds.split(",")]
    for job in args.jobs.split(","):
        t0 = time.perf_counter()
        before, rows = shrinks(job, args.modes.split(","), args.bands, shifts)
        if len(shifts) == 1:
            print(f"{job}: ensemble RMS {before[0]:.4f} g; " + "; ".join(f"{_where(c)}{m} {1 - s[0] / before[0]:+.1%}"
                                                                         for c, m, s in rows)
                  + f" ({time.perf_counter() - t0:.0f} s)", flush=True)
            continue
        null_job = _null_job(job) if args.null else None
        null = null_baseline(null_job, shifts) if null_job else None
        show = lambda v: " ".join(f"{x:.4f}" for x in v) + f" (mean {v.mean():.4f})"  # noqa: E731
        lines = [f"{job}, net seeds + {args.net_seeds}: baseline {show(before)}"]
        if null is not None:
            lines.append(f"  null baseline {show(null)}; gap {before.mean() - null.mean():.4f} g")
        for c, m, s in rows:
            diff = s - before
            att = ("" if null is None or before.mean() <= null.mean()
                   else f"; attributable {(before.mean() - s.mean()) / (before.mean() - null.mean()):.2f}")
            lines.append(f"  {_where(c)}{m}: {show(s)}; paired shrink {-diff.mean() / before.mean():+.1%} "
                         f"(sd {diff.std(ddof=1) / before.mean():.1%}){att}")
        print("\n".join(lines) + f" ({time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
