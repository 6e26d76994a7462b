"""Explain: the candidate matrix beside the floor covariates, the selection's proposals, the
neighbouring resonance cell and the resonance probe."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from . import _rules
from ._confirm import _SIGN_FLIPS, _explained, _paired_errors, _sign_flip_p, _train_model
from ._lag import _lag_candidates
from ._model import Model, _Ctx, _determined, _selection_column, _Windows, source_channels
from .candidates import Candidate, library, values
from .selection import Selected as _Selected
from .selection import forward_select, gains
from .selection import gain as _selection_gain


def _floor_basis(win: _Windows, yhat, rows, floor, knots=(0.25, 0.5, 0.75)) -> np.ndarray:
    """Covariates for the error floor: the prediction, and each floor feature with hinges at
    interior quantiles (a piecewise-linear map of the model's own inputs; interior knots, so
    that a held-out condition at the edge of the data is not extrapolated by a steep hinge)."""
    cols = [yhat[rows]]
    for f in floor:
        x = win.cands[f"x:{f}"].to_numpy()[rows]
        cols.append(x)
        cols += [np.maximum(x - k, 0.0) for k in np.unique(np.quantile(x, knots)) if np.ptp(np.maximum(x - k, 0)) > 0]
    return np.column_stack(cols)


def knn_floor(features, residual, groups, k: int = 30, chunk: int = 1024) -> np.ndarray:
    """The residual a static map of these features leaves near each window: the mean
    residual of its `k` nearest windows (standardised features) among *other* conditions.

    A misfit that is a function of the model's own inputs (the map's error floor: too few
    peaks there, an extrapolation) reappears at the same inputs in other conditions, so this
    covariate absorbs it; a missing effect does not, unless it follows the inputs.

    Args:
        features: (n, d) the model's inputs per window. residual: (n,). groups: (n,) condition.

    Returns:
        (n,) the floor estimate.
    """
    X = np.asarray(features, float)
    sd = X.std(axis=0)
    X = (X - X.mean(axis=0)) / np.where(sd > 0, sd, 1.0)
    g = pd.factorize(np.asarray(groups))[0]
    out = np.empty(len(X))
    sq = np.sum(X * X, axis=1)
    for a in range(0, len(X), chunk):
        d2 = sq[a:a + chunk, None] + sq[None, :] - 2.0 * X[a:a + chunk] @ X.T
        d2[g[a:a + chunk, None] == g[None, :]] = np.inf
        kk = min(k, d2.shape[1] - 1)
        idx = np.argpartition(d2, kk, axis=1)[:, :kk]
        out[a:a + chunk] = residual[idx].mean(axis=1)
    return out


# Operators tried at `candidate_offsets_s` besides the model's offset: no fitted parameter.
_ALIGNED = ("input", "rate", "abs_rate", "window")


def _unaligned_key(c: Candidate) -> str:
    """A candidate's key without its alignment: one effect, whatever offset it was tried at."""
    return replace(c, parameters={k: v for k, v in c.parameters.items() if k != "offset_s"}).key


def _candidate_matrix(ctx: _Ctx, model: Model, win: _Windows, yhat, used_keys,
                      lags: bool = True) -> tuple[list[Candidate], np.ndarray, list[Candidate], np.ndarray]:
    """The round's candidates and their selection columns: the library at the model's offset
    and, for those without a fitted parameter, at `candidate_offsets_s`; without the effects
    named already (`used_keys`) and, unless `lags` and the model has none, the lags of the
    prediction. Static refinements of the model's own inputs (their knees and products, at
    its offset) are returned apart: the floor's business (`_propose`), not discoveries.

    Returns:
        (candidates, columns, own refinements, their columns); non-finite, constant and
        duplicate columns dropped.
    """
    own = _determined(model.inputs)
    taken = tuple(model.inputs) + tuple(c.channels[0] for c in model.extra if c.operator == "input")
    # Candidates take the model's offset, recorded as their alignment: a term keeps it if a
    # later round moves the model's offset (`_Windows.values`). Those without a fitted
    # parameter are also tried at `candidate_offsets_s` (a transient's faster response).
    lib, cols, flib, fcols = [], [], [], []
    extra = sorted({round(float(o), 6) for o in _rules.CANDIDATE_OFFSETS_S} - {round(float(model.offset_s), 6)})
    win.prefetch([model.offset_s, *extra])
    for off in [model.offset_s, *extra]:
        table = win.at(off)  # `win.cands` at the model's own offset (`win` is its replay)
        for c in library(table, model_inputs=taken, knee_quantiles=_rules.KNEE_QUANTILES):
            if off != model.offset_s and c.operator not in _ALIGNED:
                continue
            c = replace(c, parameters={**c.parameters, "offset_s": off})
            if c.operator in ("input", "threshold", "product") and set(c.channels) <= set(own):
                if c.operator != "input":
                    flib.append(c)
                    fcols.append(values(c, table))
                continue
            if _unaligned_key(c) in used_keys:
                continue
            lib.append(c)
            cols.append(_selection_column(c, values(c, table), yhat))
    C = np.column_stack(cols)
    if lags and model.lag_tau_s <= 0:
        lc, LC = _lag_candidates(yhat, win, _rules.LAG_TAUS)
        lib, C = lib + lc, np.column_stack([C, LC])
    # Drop non-finite, constant and duplicate columns (e.g. |x| of a channel that is never negative).
    usable = lambda M: np.all(np.isfinite(M), axis=0) & (np.ptp(M, axis=0) > 0)  # noqa: E731
    ok = usable(C)
    _, first = np.unique(np.round(C[:, ok], 12), axis=1, return_index=True)
    keep = np.flatnonzero(ok)[np.sort(first)]
    F = np.column_stack(fcols) if fcols else np.empty((len(C), 0))
    fok = np.flatnonzero(usable(F))
    return [lib[j] for j in keep], C[:, keep], [flib[j] for j in fok], F[:, fok]


def _floor(win: _Windows, yhat, resid, rows, own, groups, min_conditions: int = 40) -> np.ndarray:
    """The floor covariates of a selection: the prediction and the nearest-neighbour floor;
    with enough conditions also the piecewise-linear basis of the model's own inputs (in a
    maneuver kind of a dozen conditions its ~30 columns would fit the held-out folds'
    noise, not the floor)."""
    knn = knn_floor(win.cands.loc[rows, [f"x:{f}" for f in own]].to_numpy(), resid[rows], groups[rows])
    if len(set(groups[rows])) >= min_conditions:
        return np.column_stack([_floor_basis(win, yhat, rows, own), knn])
    return np.column_stack([yhat[rows], knn])


def _try_order(same) -> list:
    """The order in which to retrain the candidates a selection cannot tell apart ((column,
    gain), simplest first): the simplest (the one it names), then the one that explains
    most (a gain on the prediction, a resonance, can be a whole mode while simpler channels
    share its shadow; the retraining decides between them), then the others."""
    best = max(range(len(same)), key=lambda i: same[i][1])
    return [same[i] for i in [0] + ([best] if best else []) + [i for i in range(1, len(same)) if i != best]]


def _neighbour_cells(proposals, lib: list[Candidate], M, designs, resid, groups, d, seed: int) -> list:
    """The proposals with, after each resonance, the band of the adjacent grid cell (same
    channel and alignment) that the proposal's design credits with the larger held-out gain,
    if it gains `min_gain` and is not proposed already. A mode between two grid centres is
    shared by both cells, and which of the two the selection ranks first depends on how few
    windows reach the band; the retraining decides (measured: a mode at 273 rpm, the band at
    267.5 ranked first, gain 0.084, but −0.5 % retrained; the one at 270.7, gain 0.071, −22 % RMS).

    Args:
        proposals: `_propose`'s list of (where, column, `Selected`). lib: the candidate of each
            column of `M`. designs: `_propose`'s {where: (rows, floor covariates)}.

    Returns:
        The proposals, neighbours inserted (not counted against `d.selection.proposals`).
    """
    taken = {j for _, j, _ in proposals}
    out = []
    for where, j, s in proposals:
        out.append((where, j, s))
        c = lib[j]
        if c.operator != "resonance":
            continue
        same = lambda o: (o.operator == c.operator and o.channels == c.channels  # noqa: E731
                          and o.parameters.get("offset_s") == c.parameters.get("offset_s"))
        near = [k for k, o in enumerate(lib) if k not in taken and same(o)
                and 0 < abs(o.parameters["center"] - c.parameters["center"]) <= 1.01 * c.parameters["width"]]
        if not near:
            continue
        rows, floor = designs[where]
        g = gains(resid[rows], M[:, near][rows], groups[rows], base=floor, folds=d.ensemble.folds, seed=seed)
        top = int(np.argmax(g))
        if g[top] >= _rules.MIN_GAIN:
            taken.add(near[top])
            out.append((where, near[top], s._replace(index=near[top], gain=float(g[top]))))
    return out


def _probe_gains(ctx: _Ctx, model: Model, bands) -> np.ndarray:
    """The gains of nets trained with a learned gain on every band at once (`gain_apply`),
    median over folds and seeds: (len(bands),). The nets learn the response, the gains how
    much each band magnifies it; a mode is the band of the largest."""
    params = _train_model(ctx, model._replace(gains=model.gains + tuple(bands)))
    g = np.asarray(params["gain"])[..., len(model.gains):]
    return np.median(g.reshape(-1, len(bands)), axis=0)


def _resonance_probe(ctx: _Ctx, model: Model, proposals, lib: list[Candidate], M, designs, resid, groups, d,
                     seed: int, log) -> list:
    """`proposals` and, if none is a resonance, the rotor-speed band of the largest
    `_probe_gains` (the model's offset; a band not named already), for nets trained on the
    peaks (none for window nets, `Model.through_lag`). Its
    `Selected` carries the band's held-out gain as a column of the selection (usually ~0:
    what it explains is not proportional to the prediction) and no p-value: the retraining's
    confirmation decides."""
    if any(lib[j].operator == "resonance" for _, j, _ in proposals):
        return proposals
    if model.through_lag:
        # The probe is for peak nets: nets trained on the windows under-predict the lowest
        # rotor speed, where the fewest conditions are, and a gain there corrects them out of
        # sample although the campaign has no mode.
        log("resonance probe: skipped, the nets train on the windows (the probe is calibrated on peak nets)")
        return proposals
    bands = [(j, c) for j, c in enumerate(lib)
             if c.operator == "resonance" and c.parameters.get("offset_s") == model.offset_s]
    if not bands:
        return proposals
    g = _probe_gains(ctx, model, [c for _, c in bands])
    j = bands[int(np.argmax(g))][0]
    rows, floor = designs["all"]
    gain = _selection_gain(resid[rows], M[rows, j], groups[rows], base=floor, folds=d.ensemble.folds, seed=seed)
    log("resonance probe: gains by band centre " + ", ".join(
        f"{c.parameters['center']:.1f} {v:+.2f}" for (_, c), v in zip(bands, g)) + f": proposes {lib[j].name}")
    return list(proposals) + [("all", j, _Selected(j, gain, float("nan"), float("nan"), source="probe"))]


def hidden_sources(inputs) -> frozenset[str]:
    """The campaign channels that a model's derived inputs are computed from but that it does
    not take, nor determine exactly: for db1, the load factor's roll angle and pitch rate."""
    return source_channels(inputs) - set(_determined(inputs))


def _source_tries(proposals, lib: list[Candidate], M, designs, resid, groups, inputs, d, seed: int, log) -> list:
    """`proposals` and the `d.selection.source_tries` candidates of the best held-out gain (above 0, one
    alignment each, none proposed already) built only from `hidden_sources`. The nets learn
    part of such an effect through the derived input, so the residual under-ranks the rest:
    the selection alone does not propose it. Their `Selected` carries the gain and no p-value
    (`_source_test` gives its retraining's): the confirmation and the floor control decide."""
    if not d.selection.source_tries:
        return proposals
    hidden = hidden_sources(inputs)
    proposed = {_unaligned_key(lib[j]) for _, j, _ in proposals}
    cols = [j for j, c in enumerate(lib)
            if c.channels and set(c.channels) <= hidden and _unaligned_key(c) not in proposed]
    if not cols:
        return proposals
    rows, floor = designs["all"]
    g = gains(resid[rows], M[rows][:, cols], groups[rows], base=floor, folds=d.ensemble.folds, seed=seed)
    out, seen = list(proposals), set()
    for k in np.argsort(-g, kind="stable"):
        key = _unaligned_key(lib[cols[k]])
        if g[k] <= 0 or len(seen) == d.selection.source_tries:
            break
        if key not in seen:
            seen.add(key)
            out.append(("all", cols[k], _Selected(cols[k], float(g[k]), float("nan"), float("nan"), source="source")))
    if seen:
        log("source tries (" + ", ".join(sorted(hidden)) + "): " + "; ".join(
            f"{lib[j].name} ({s.gain:.3f})" for _, j, s in out[len(proposals):]))
    return out


def _source_test(conf, current, seed: int) -> tuple[float, float]:
    """The p-value and explained fraction of a source try (`_source_tries`), which the
    selection gives none, from its retraining: p that the retrained ensemble predicts better
    than the current one by condition where it acts (`judged_in`), one-sided sign flips.
    Reported, not required: the confirmation and the floor control decide.

    Returns:
        (p, 1 − the trial's squared error / the current model's over all windows).
    """
    both = _paired_errors(current, conf)
    where = both[both.maneuver.isin(conf.judged_in.split(", "))]
    return _sign_flip_p(where if len(where) else both, _SIGN_FLIPS, seed), _explained(both)


def _probe_test(conf, current, c: Candidate, seed: int, alpha: float) -> tuple[float, float, str]:
    """The p-value and explained fraction of a probe's band (`_resonance_probe`), which the
    selection gives none, from its retraining. p: that the retrained ensemble predicts better
    than the current one by condition where the band acts (its value ≥ 0.5: a mode magnifies
    the conditions at its rotor speeds), one-sided sign flips. Required at `probe_alpha`, a
    looser level than `alpha`: a real mode acts on few conditions, so its p-value by condition
    stays above `alpha`, while a band without a mode scores far above either.

    Args:
        conf: `_confirm`'s `Confirmation` (the trial's predictions and windows). current: the
            current model's (`Predicted`). c: the band. seed: of the flips.
        alpha: the level p must reach (`probe_alpha`).

    Returns:
        (p, 1 − the trial's squared error / the current model's over all windows, why the band
        is not confirmed: "" if p ≤ alpha).
    """
    both = _paired_errors(current, conf).merge(
        conf.win.table[["counter", "window"]].assign(band=conf.win.values(c)), on=["counter", "window"])
    p = _sign_flip_p(both[both.band >= 0.5], _SIGN_FLIPS, seed)
    why = "" if p <= alpha else f"its retraining's p = {p:.3f} by condition where it acts, above probe_alpha {alpha:g}"
    return p, _explained(both), why


def _propose(win: _Windows, yhat, resid, C, rows, own, floor_all, d, seed: int, complexity, keys,
             is_floor=None) -> tuple[list, list, dict]:
    """Significant candidates over all windows (`where` "all"): the permutations grow so that
    the level `alpha` can be reached. `floor_all`: the floor covariates of the rows
    (`_floor`). `complexity` (one per column of C) is for the selection's parsimony rule; `keys`
    (one per column) names the effect of each, so that one effect at two alignments is
    proposed once (at the better).

    `is_floor` marks the columns that refine the model's own inputs (`_candidate_matrix`): before
    any candidate is asked, the one with the largest held-out gain joins the floor
    covariates, while it gains `MIN_GAIN`, at most `FLOOR_REFINEMENTS` of them. A knee of the
    map's own inputs that ~200 peaks did not teach the nets is the map's floor, not a
    missing effect; left out, a channel that follows it (a stick, the shaft power) is named
    in its place. Never tested, never proposed: covariates (their permutations in the test's
    null would only inflate it).

    Returns:
        (proposals, absorbed, designs). proposals: list of (where, candidate column,
        `Selected`), most residual² explained first and, inside a selection, the candidates it
        cannot tell apart (`_try_order`); at most `d.selection.proposals`, one per candidate. absorbed:
        list of (where, column, gain) of the floor columns that joined the floor. designs:
        {where: (rows, floor covariates with the absorbed columns)} of each selection.
    """
    groups = win.table.condition.to_numpy()
    is_floor = np.zeros(C.shape[1], bool) if is_floor is None else np.asarray(is_floor, bool)
    alpha = d.selection.alpha
    perms = max(d.selection.permutations, int(np.ceil(1.0 / alpha)) - 1)
    found, absorbed, designs = [], [], {}
    for where, sub in [("all", rows)]:
        Cs = C[sub]
        keep = np.flatnonzero(np.ptp(Cs, axis=0) > 0)
        floor = floor_all
        # The floor first: the static map of the model's own inputs is the null model, so
        # its refinements (the one with the largest held-out gain, while it gains `min_gain`)
        # join the floor covariates before any candidate is asked (never tested: covariates).
        for _ in range(_rules.FLOOR_REFINEMENTS):
            own_cols = keep[is_floor[keep]]
            if not len(own_cols):
                break
            g = gains(resid[sub], Cs[:, own_cols], groups[sub], base=floor, folds=d.ensemble.folds, seed=seed)
            top = int(np.argmax(g))
            if g[top] < _rules.MIN_GAIN:
                break
            absorbed.append((where, int(own_cols[top]), float(g[top])))
            floor = np.column_stack([floor, Cs[:, own_cols[top]]])
            keep = keep[keep != own_cols[top]]
        keep = keep[~is_floor[keep]]
        designs[where] = (sub, floor)
        for s in forward_select(resid[sub], Cs[:, keep], groups[sub], base=floor, folds=d.ensemble.folds, max_effects=1,
                                min_gain=_rules.MIN_GAIN, alpha=alpha, permutations=perms, seed=seed,
                                complexity=complexity[keep], parsimony=_rules.PARSIMONY):
            amount = s.gain * float(np.sum(resid[sub] ** 2))
            s = s._replace(index=int(keep[s.index]),  # global columns
                           alternatives=tuple((int(keep[a]), g) for a, g in s.alternatives),
                           equivalents=tuple((int(keep[a]), g) for a, g in s.equivalents))
            found.append((amount, where, s))
    out, seen = [], set()
    for _, where, s in sorted(found, key=lambda f: -f[0]):
        for j, g in _try_order(s.equivalents or ((s.index, s.gain),)):
            if keys[j] not in seen:
                seen.add(keys[j])
                out.append((where, j, s._replace(index=j, gain=g)))
    return out[: d.selection.proposals], absorbed, designs
