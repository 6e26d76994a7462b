"""Which inputs each pilot-floor axis needs, judged as a simulator is qualified.

For each database's inputs, nets of one output per axis (`analysis.axes_database`: every
condition's peak window of every axis, each row carrying every axis's N/rev there) are
trained k-fold by condition and seed, all in one vmapped program (`dynamics.fit_peak_map`).
Each axis is then judged on its own peaks of held-out conditions: RMS error, FAA Part 60
test 3.f.1 pass share against that axis's nominal cruise level, and Kendall's τ. An axis
needs the first database whose pass share reaches `[axes] pass_share`; one that no
database serves needs more of the flight state than the databases hold (the lateral axis,
with sideslip, as Kottapalli found on the UH-60A), which `pvvjax discover` on that axis
names.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import jax
import numpy as np
import pandas as pd
from scipy.stats import kendalltau

from ..analysis.databases import DB_INPUTS, axes_database, campaign_axes
from ..dynamics.compare import condition_split, fit_peak_map, heldout
from ..dynamics.scores import faa_pass, nominal_cruise
from ..nets.networks import mlp_apply
from ..realtime.npnet import read_npz, write_npz

__all__ = ["AxesStudy", "axis_needs", "axis_scores", "fit_axes", "run_axes", "study_nets"]

AXIS_WORDS = {"az_g": "vertical", "ax_g": "longitudinal", "ay_g": "lateral"}
# An axis whose measured peaks all lie below this (the data contract's vibration floor, g)
# carries no vibration: it is said so, never scored as failing test 3.f.1.
NO_VIBRATION_G = 1e-3


class AxesStudy(NamedTuple):
    """A study's results.

    Attributes:
        table: one row per (axis, database): rms_g, faa_pass_share, kendall_tau,
            nominal_cruise_g, fails (held-out FAA failures by maneuver kind), n_conditions,
            status ("no vibration", or "").
        needs: one row per axis: the database it needs ("" where none suffices), its pass
            share, and a sentence saying so.
        predictions: the axes database with each database's held-out predictions
            (`pred_<db>_<axis>`).
    """

    table: pd.DataFrame
    needs: pd.DataFrame
    predictions: pd.DataFrame


def fit_axes(rows: pd.DataFrame, database: str, axes, split, seeds: int, hidden, train_cfg):
    """Nets of one output per axis on `database`'s inputs (`dynamics.Trained`: params
    stacked (folds, seeds, ...), pred (F, S, R, 1, A))."""
    x = rows[list(DB_INPUTS[database])].to_numpy(np.float32)
    y = rows[list(axes)].to_numpy(np.float32)
    return fit_peak_map(x, y, split, seeds, hidden, train_cfg)


def axis_scores(rows: pd.DataFrame, pred: np.ndarray, axes, band) -> list[dict]:
    """Each axis judged on its own peaks: the rows whose `peak_axis` is it, its column of
    `pred` ((R, A) held-out predictions, g) against its measured peak.

    Returns:
        One dict per axis: rms_g, faa_pass_share, kendall_tau, nominal_cruise_g, fails
        ("kind failed/total, ..." for the kinds with a failure), n_conditions and status:
        "no vibration" for an axis whose measured peaks all lie below `NO_VIBRATION_G`
        (its FAA share and τ are NaN: nothing to match), else "".
    """
    out = []
    for a, axis in enumerate(axes):
        sel = (rows.peak_axis == axis).to_numpy()
        measured, p = rows[axis].to_numpy(float)[sel], pred[sel, a]
        kinds = rows.maneuver.to_numpy()[sel]
        rms = float(np.sqrt(np.mean((p - measured) ** 2)))
        if not (measured >= NO_VIBRATION_G).any():
            out.append(dict(axis=axis, rms_g=rms, faa_pass_share=float("nan"), kendall_tau=float("nan"),
                            nominal_cruise_g=float("nan"), fails="", n_conditions=int(sel.sum()),
                            status="no vibration"))
            continue
        nominal = nominal_cruise(measured, kinds, rows.advance_ratio.to_numpy()[sel], band,
                                 key="axes.cruise_advance_ratio")
        ok = faa_pass(p, measured, nominal)
        per_kind = pd.Series(~ok).groupby(kinds).agg(["sum", "size"])
        fails = ", ".join(f"{k} {int(r['sum'])}/{int(r['size'])}" for k, r in
                          per_kind[per_kind["sum"] > 0].sort_values("sum", ascending=False).iterrows())
        out.append(dict(axis=axis, rms_g=rms, faa_pass_share=float(ok.mean()),
                        kendall_tau=float(kendalltau(p, measured).statistic), nominal_cruise_g=nominal, fails=fails,
                        n_conditions=int(sel.sum()), status=""))
    return out


def axis_needs(table: pd.DataFrame, databases, pass_share: float) -> pd.DataFrame:
    """Per axis, the first of `databases` whose held-out FAA pass share reaches
    `pass_share`, and a sentence: which inputs suffice, or that none does and where it fails."""
    rows = []
    for axis, t in table.groupby("axis", sort=False):
        t = t.set_index("database").loc[list(databases)]
        good = t[t.faa_pass_share >= pass_share]
        word = AXIS_WORDS.get(axis, axis)
        if "status" in t and (t.status == "no vibration").all():
            rows.append(dict(axis=axis, database="", faa_pass_share=float("nan"),
                             text=f"{axis} ({word}): carries no vibration (every measured peak below "
                                  f"{NO_VIBRATION_G:g} g): nothing to predict, no input needed"))
            continue
        if len(good):
            db = good.index[0]
            text = (f"{axis} ({word}): {db}'s inputs suffice ({', '.join(DB_INPUTS[db])}): FAA 3.f.1 passes on "
                    f"{good.faa_pass_share.iloc[0]:.0%} of held-out conditions")
            rows.append(dict(axis=axis, database=db, faa_pass_share=float(good.faa_pass_share.iloc[0]), text=text))
            continue
        best = t.faa_pass_share.idxmax()
        text = (f"{axis} ({word}): no database suffices; the best, {best}, passes FAA 3.f.1 on "
                f"{t.faa_pass_share.max():.0%} of held-out conditions and fails in {t.fails[best] or '-'}. It needs "
                f"more of the flight state than {', '.join(databases)} hold: run the discovery on it "
                f"([analysis] axis = \"{axis}\").")
        rows.append(dict(axis=axis, database="", faa_pass_share=float(t.faa_pass_share.max()), text=text))
    return pd.DataFrame(rows)


def _part(out: Path, db: str) -> Path:
    return out / "parts" / f"{db}.params.npz"


def run_axes(campaign, cfg, out, log=print) -> AxesStudy:
    """The study on a campaign into folder `out` (`cfg`: an `ExperimentConfig`; its `[axes]`,
    `[analysis]`, `[train]` and seed): each database's nets (resumable: saved to
    `parts/<db>.params.npz` as they finish), the table, the needs and the predictions."""
    ac = cfg.axes
    axes = campaign_axes(campaign)
    rows = axes_database(campaign, cfg.analysis)
    split = condition_split(rows.condition.to_numpy(), ac.folds, cfg.seed, key="axes.folds")
    predictions, table = rows.copy(), []
    for db in ac.databases:
        part = _part(Path(out), db)
        if part.exists():
            params, _ = read_npz(part)
            log(f"axes: {db}: saved part {part}")
            pred = _predict(params, rows, db)
        else:
            log(f"axes: {db}: training {ac.folds} folds x {ac.seeds} seeds, {len(axes)} outputs ({', '.join(axes)})")
            trained = fit_axes(rows, db, axes, split, ac.seeds, ac.hidden, cfg.train)
            params, pred = trained.params, trained.pred[:, :, :, 0, :]
            part.parent.mkdir(parents=True, exist_ok=True)
            write_npz(part, params, dict(database=db, inputs=list(DB_INPUTS[db]), outputs=list(axes)))
        held = heldout(pred, split)  # (R, A)
        for a, axis in enumerate(axes):
            predictions[f"pred_{db}_{axis}"] = held[:, a]
        table += [dict(database=db, **s) for s in axis_scores(rows, held, axes, ac.cruise_advance_ratio)]
    table = pd.DataFrame(table)[["axis", "database", "rms_g", "faa_pass_share", "kendall_tau", "nominal_cruise_g",
                                 "fails", "n_conditions", "status"]]
    table = table.sort_values("axis", key=lambda s: s.map(list(axes).index), kind="stable").reset_index(drop=True)
    return AxesStudy(table, axis_needs(table, ac.databases, ac.pass_share), predictions)


def _predict(params: dict, rows: pd.DataFrame, db: str) -> np.ndarray:
    """(F, S, R, A) every saved net's prediction of every row."""
    x = rows[list(DB_INPUTS[db])].to_numpy(np.float32)
    per_fold = jax.vmap(jax.vmap(mlp_apply, in_axes=(0, None)), in_axes=(0, None))
    return np.asarray(per_fold(params, x))


def study_nets(folder, database: str) -> list[tuple[dict, dict]]:
    """Every (fold, seed) net of `database` in a study folder, as (parameters, metadata)
    pairs for the element (its outputs: the axes, in order)."""
    part = _part(Path(folder), database)
    if not part.exists():
        raise FileNotFoundError(f"{part}: the study has no nets of {database}")
    stacked, meta = read_npz(part)
    folds, seeds = np.shape(stacked["y_scale"])[:2]
    return [(jax.tree.map(lambda a, f=f, s=s: np.asarray(a)[f, s], stacked), meta)
            for f in range(folds) for s in range(seeds)]
