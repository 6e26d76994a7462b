"""One round of step 4: every proposal retrained in each way it can be added, confirmed
against the current model (and its floor control), compared, and one of them named."""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from . import _rules
from ._confirm import (
    _SIGN_FLIPS,
    _augment,
    _choose,
    _confirm,
    _control_refinements,
    _encompassed,
    _floor_control,
    _paired_sign_flip,
    _rival,
    _rival_encompasses,
    _tied,
    _ties,
)
from ._fits import _fit_offset, _keep_better, _refine
from ._model import Model, _Ctx, _gain_unit, _Windows, metrics, predictions, source_channels
from ._propose import _probe_test, _source_test, _unaligned_key
from ._results import Confirmation, Predicted
from .candidates import Candidate
from .selection import Selected


class _Confirmed(NamedTuple):
    """A try of a round: what `_choose` compares and what naming it takes (`_way` may
    name a term that did not confirm alone in place of its proposal's input)."""

    shrink: float  # of the ensemble's RMS over all windows
    row: int  # in the rounds table
    where: str
    selected: Selected  # the selection's (p-value and explained fraction as confirmed)
    candidate: Candidate  # as tried (fitted parameters added)
    trial: Model
    conf: Confirmation
    proposal: str  # the key of the proposal it tries (its term and input share it)
    control_shrink: float  # on top of its floor control, over all windows; NaN without one


def _modes(operator: str, d) -> tuple[str, ...]:
    """The ways a proposal of `operator` is added and retrained (`_confirm._augment`): a lag
    refitted in the replay, a band as a gain on the nets' output (and, with
    `resonance.as_input`, as an extra input too), any other candidate both as an additive
    term and as an extra input (the confirmation keeps one)."""
    if operator == "lag":
        return ("lag",)
    if operator == "resonance":
        return ("gain", "input") if d.resonance.as_input else ("gain",)
    return ("additive", "input")


def _kept_on_top(ctx: _Ctx, first: Model, term: tuple) -> float:
    """The share of an additive term's own coefficient (`term`: its candidate as added and its
    coefficients per fold, fitted alone) that it keeps when added on top of `first` (the
    model with another term), retrained: about none where the other term explains it."""
    c, alone = term
    m = _augment(ctx, first, c, "additive")
    return float(np.median(m.terms[-1][1][:, 1]) / np.median(alone[:, 1]))


# The columns of a try's row (`Discovery.tries`): a campaign where nothing is proposed still
# gets its (empty) table with them.
TRY_COLUMNS = ("round", "where", "candidate", "parameters", "proposal", "source", "name", "operator", "channels",
               "augment", "p_value", "cv_gain", "runners_up", "explained_fraction", "rms_before_g", "rms_after_g",
               "ensemble_rms_before_g", "ensemble_rms_after_g", "floor_terms", "shrink", "judged_in",
               "region_shrink", "control_shrink", "control_region_shrink", "over_control_shrink",
               "over_control_region_shrink", "control_terms", "confirmed", "why_not", "p_best_better",
               "p_input_better", "chosen")


class _Round:
    """The tries of one round on the current model.

    Args:
        ctx: the workflow's context. rnd: the round's index (0-based).
        current, pred, cur_metrics: the current model, its predictions on `win` (seeds ×
            windows) and their `metrics`.
        win, yhat, resid: the current model's windows, median prediction and residual.
        lib, designs: the candidates the proposals index, and each selection's (rows, floor).
        refinements: the floor's refinements over all windows, the floor control's inputs.
            floor_terms: what the floor took, in words.
        used: the proposals' keys of every round so far (updated). rounds: the rounds table's
            rows (appended to). log: progress messages.
    """

    def __init__(self, ctx: _Ctx, rnd: int, current: Model, pred, cur_metrics: dict, win: _Windows, yhat, resid,
                 lib: list, designs: dict, refinements: list, floor_terms: str, used: set, rounds: list, log):
        self.ctx, self.d, self.rnd, self.seed = ctx, ctx.cfg.discovery, rnd, ctx.cfg.seed + rnd
        self.current, self.pred, self.cur_metrics = current, pred, cur_metrics
        self.win, self.yhat, self.resid, self.lib, self.designs = win, yhat, resid, lib, designs
        self.refinements, self.floor_terms, self.used, self.rounds, self.log = (
            refinements, floor_terms, used, rounds, log)
        self.controls = {}  # the floor controls of this round, by the keys of the refinements they hold
        self.confirmed, self.tried, self.ways = [], set(), {}  # ways: every try, confirmed or not, by (proposal, way)

    def _control_for(self, c: Candidate):
        """The floor control a try of `c` is judged on top of, and the refinements it holds."""
        kept = _control_refinements(self.refinements, c)
        key = tuple(r.key for r in kept)
        if kept and key not in self.controls:
            control = self.controls[key] = _floor_control(self.ctx, self.current, kept)
            rms = metrics(predictions(self.ctx, control, self.win), self.win)["ensemble_rms_g"]
            self.log(f"round {self.rnd + 1}: floor control ({'; '.join(r.name for r in kept)} as inputs): "
                     f"ensemble's RMS {self.cur_metrics['ensemble_rms_g']:.4f} -> {rms:.4f} g")
        return self.controls.get(key), kept

    def try_proposal(self, where: str, j: int, s: Selected):
        """Retrain the proposal (column `j` of `lib`, found in `where`, `s` its `Selected`) in
        each way it can be added; its rows go to `rounds`, its confirmed tries to `confirmed`."""
        ctx, d, win, yhat, resid, lib = self.ctx, self.d, self.win, self.yhat, self.resid, self.lib
        rows, fl = self.designs[where]
        refined = _keep_better(lib[j], _refine(lib[j], resid[rows], win.at(
            lib[j].parameters.get("offset_s", win.offset))[rows], yhat[rows], base=fl), win, yhat, resid,
            rows, fl, d.ensemble.folds, self.seed, self.log)
        self.used.add(_unaligned_key(lib[j]))
        if refined.key in self.tried:  # two grid knees refined to the same one: retrained already
            self.log(f"  {lib[j].name}: refined to {refined.name}, tried already")
            return
        self.tried.add(refined.key)
        alts = "; ".join(f"{lib[a].name} ({g:.3f})" for a, g in s.alternatives)
        for mode in _modes(refined.operator, d):
            c, trial, added = self._trial(refined, mode, s)
            conf = _confirm(ctx, self.current, trial, c, where, d)
            ok, p_value, explained = conf.confirmed, s.p_value, s.explained_fraction
            if s.source == "probe":  # no selection p: its retraining's, by condition
                p_value, explained, why = _probe_test(conf, Predicted(self.pred, win), c, self.seed,
                                                      _rules.PROBE_ALPHA)
                if ok and why:
                    ok, conf = False, replace(conf, confirmed=False, why=why)
            elif s.source == "source":  # no selection p either: its retraining's, reported
                p_value, explained = _source_test(conf, Predicted(self.pred, win), self.seed)
            unset = Confirmation.not_run()
            on_control, over_control, control, kept = unset, unset, None, ()
            if ok and self.refinements and mode != "lag":
                control, kept = self._control_for(added)
            if control is not None:  # the same try on top of the floor control
                on_control = _confirm(ctx, control, _augment(ctx, control, added, mode), added, where, d,
                                      slack=_rules.SHRINK_NOISE)
                ok = on_control.confirmed
                # Or the try alone beats the control (`_floor_control`), where the control predicts
                # at least as well as the current model: beating a worse one, the try has shown
                # nothing its first confirmation had not.
                control_worse = on_control.ensemble[0] > conf.ensemble[0]
                if not ok and not control_worse:
                    over_control = _confirm(ctx, control, trial, added, where, d, slack=_rules.SHRINK_NOISE)
                    ok = over_control.confirmed
                if not ok:
                    alone = ("the control predicts worse than the current model (ensemble's RMS "
                             f"{on_control.ensemble[0]:.4f} against {conf.ensemble[0]:.4f} g)" if control_worse
                             else f"nor better than it alone ({over_control.shrink:+.1%}, {over_control.local:+.1%})")
                    conf = replace(conf, confirmed=False, why=(
                        f"not confirmed on top of the floor control: {on_control.why} (shrink "
                        f"{on_control.shrink:+.1%} (all), {on_control.local:+.1%} ({on_control.judged_in})), {alone}"))
                elif over_control is not unset:
                    self.log(f"  {c.name} ({mode}): not confirmed on top of the floor control (shrink "
                             f"{on_control.shrink:+.1%} (all), {on_control.local:+.1%}), but better than it "
                             f"alone ({over_control.shrink:+.1%} (all), {over_control.local:+.1%} "
                             f"({over_control.judged_in}))")
            m = self.cur_metrics
            self.rounds.append(dict(
                round=self.rnd + 1, where=where, candidate=c.key, parameters=c.parameters_json, proposal=refined.key,
                source=s.source, name=c.name, operator=c.operator, channels=",".join(c.channels), augment=mode,
                p_value=p_value, cv_gain=s.gain, runners_up=alts, explained_fraction=explained,
                rms_before_g=m["rms_g"], rms_after_g=conf.metrics["rms_g"],
                ensemble_rms_before_g=conf.ensemble[0], ensemble_rms_after_g=conf.ensemble[1],
                floor_terms=self.floor_terms, shrink=conf.shrink, judged_in=conf.judged_in,
                region_shrink=conf.local, control_shrink=on_control.shrink,
                control_region_shrink=on_control.local, over_control_shrink=over_control.shrink,
                over_control_region_shrink=over_control.local,
                control_terms="; ".join(r.name for r in kept) if control is not None else "",
                confirmed=ok, why_not=conf.why, p_best_better=np.nan, p_input_better=np.nan, chosen=False))
            self.log(f"  {c.name} ({mode}): held-out RMS {m['rms_g']:.4f} -> {conf.metrics['rms_g']:.4f} "
                     f"g (median over seeds); ensemble's {conf.ensemble[0]:.4f} -> {conf.ensemble[1]:.4f} g, "
                     f"shrink {conf.shrink:+.1%} (all), {conf.local:+.1%} ({conf.judged_in}): "
                     f"{'confirmed' if ok else 'not confirmed (' + conf.why + ')'}")
            done = _Confirmed(conf.shrink, len(self.rounds) - 1, where,
                              s._replace(p_value=p_value, explained_fraction=explained), c, trial, conf,
                              refined.key, on_control.shrink)
            self.ways[(refined.key, mode)] = done
            if ok:  # both ways are tried; `_choose`, then `_way`, keeps one
                self.confirmed.append(done)

    def _trial(self, c: Candidate, mode: str, s: Selected) -> tuple[Candidate, Model, Candidate]:
        """The current model with `c` added in `mode`, retrained: (the candidate with its fitted
        parameters, the model, the candidate as added, which a floor control adds again)."""
        if mode == "lag":
            trial = _fit_offset(self.ctx, self.current, with_lag=True)
            c = replace(c, parameters={"tau_s": trial.lag_tau_s})
            return c, trial, c
        if mode == "gain" and s.source != "probe":  # a tested band: its gain in steps of gain_unit
            c = replace(c, parameters={**c.parameters, "gain_unit": _rules.GAIN_UNIT})
        added = c
        trial = _augment(self.ctx, self.current, c, mode)
        if trial.terms and trial.terms[-1][0] is c:
            c = replace(c, parameters={**c.parameters, "coefficient": float(np.median(trial.terms[-1][1][:, 1]))})
        if mode == "gain":
            gain = _gain_unit(c) * np.median(trial.params["gain"][..., -1])
            c = replace(c, parameters={**c.parameters, "gain": float(gain)})
        return c, trial, added

    def _choose(self) -> tuple[list, int]:
        """The confirmed tries as `_choose` compares them, and the index of the one named."""
        top = max(self.confirmed, key=lambda t: t.shrink).conf
        ps = [1.0 if t.conf is top else _paired_sign_flip(t.conf, top, _SIGN_FLIPS, self.seed)[0]
              for t in self.confirmed]
        for t, p in zip(self.confirmed, ps):
            self.rounds[t.row]["p_best_better"] = p
        tries = [(t.shrink, np.nan if t.selected.source == "probe" else t.selected.gain, p, t.proposal,
                  t.control_shrink) for t, p in zip(self.confirmed, ps)]
        d = self.d
        return tries, _choose(tries, _rules.SHRINK_NOISE, d.selection.alpha, d.min_shrink, _rules.TIE_SHARE)

    def name(self, proposals: list) -> _Confirmed | None:
        """Try every proposal (`(where, j, Selected)`) and name one of the confirmed tries:
        `_choose`'s, or a weak name's runner-up on other channels (`_rival`), or a tied rival
        its term encompasses (`_encompass`); then its proposal's term in place of a tied input
        (`_way`), and a named term refitted on window nets (`_refit_named`). None where nothing
        confirms. The named try's row is marked `chosen`."""
        for where, j, s in proposals:
            self.try_proposal(where, j, s)
        if not self.confirmed:
            return None
        tries, k = self._choose()
        lib = self.lib
        taken = set().union(*(source_channels(lib[j].channels) for _, j, _ in proposals))
        named = self.confirmed[k]
        rival = _rival(k, tries, named.selected.alternatives, [c.channels for c in lib], taken,
                       self.d.min_shrink, _rules.MIN_GAIN)
        if rival is not None:  # a weak name: its runner-up on other channels retrained beside it
            a, g = rival
            self.log(f"round {self.rnd + 1}: {named.candidate.name} gains less than min_shrink on top of its floor "
                     f"control; its runner-up on other channels, {lib[a].name} (gain {g:.3f}), is tried as well")
            self.try_proposal(named.where, a, named.selected._replace(index=a, gain=g, explained_fraction=g,
                                                                      alternatives=(), equivalents=(), source="rival"))
            tries, k = self._choose()
        k = self._encompass(k, tries)
        self._input_ties()
        named = self._refit_named(self._way(self.confirmed[k]))
        self.rounds[named.row]["chosen"] = True
        return named

    def _encompass(self, k: int, tries) -> int:
        """The named try's index after comparing its proposal's term with
        each tied proposal's on other source channels (both confirmed as additive terms; lags
        and bands aside), in turn: the rival is named, in its way of the largest shrink, where
        its term keeps a larger share of its own coefficient on top of the named's model
        (`_kept_on_top`) than the named's term keeps on top of its own, by more than
        `ENCOMPASSING_MARGIN`. Each rival's term row logs what it kept on top (`kept_on_top`),
        what the named kept on top of it (`named_kept_on_top`) and the named's proposal
        (`kept_against`: a rival after a change of name is measured against the new one)."""
        d, ways, conf = self.d, self.ways, self.confirmed

        def term(i: int):  # its proposal's additive try, where that confirmed
            w = ways.get((conf[i].proposal, "additive"))
            ok = w is not None and conf[i].candidate.operator not in ("lag", "resonance") and any(
                w is c for c in conf)
            return w if ok else None

        def measure(k: int, i: int):
            named, t = conf[k], conf[i]
            a, b = term(k), term(i)
            kept_b = _kept_on_top(self.ctx, a.trial, b.trial.terms[-1])
            kept_a = _kept_on_top(self.ctx, b.trial, a.trial.terms[-1])
            self.rounds[b.row].update(kept_on_top=kept_b, named_kept_on_top=kept_a, kept_against=named.proposal)
            won = _rival_encompasses((kept_b, kept_a), _rules.ENCOMPASSING_MARGIN)
            self.log(f"round {self.rnd + 1}: encompassing: {t.candidate.name} keeps {kept_b:.2f} of its coefficient "
                     f"on top of {named.candidate.name}, which keeps {kept_a:.2f} on top of it (margin "
                     f"{_rules.ENCOMPASSING_MARGIN:.2f}): {t.candidate.name if won else named.candidate.name} named")
            return kept_b, kept_a

        return _encompassed(k, _ties(tries, _rules.SHRINK_NOISE, d.selection.alpha, d.min_shrink, _rules.TIE_SHARE),
                            [c.proposal for c in conf], lambda i: term(i) is not None,
                            lambda i: source_channels(conf[i].candidate.channels), measure, _rules.ENCOMPASSING_MARGIN,
                            lambda j: conf[j].shrink)

    def _input_ties(self):
        """Log on the term row of every proposal whose input confirmed the p that the input
        predicts better (`p_input_better`): what `_way` decides by, for whichever input is
        named."""
        for t in self.confirmed:
            term = self.ways.get((t.proposal, "additive"))
            if self.rounds[t.row]["augment"] == "input" and term is not None:
                self.rounds[term.row]["p_input_better"] = _paired_sign_flip(term.conf, t.conf, _SIGN_FLIPS,
                                                                            self.seed)[0]

    def _way(self, named: _Confirmed) -> _Confirmed:
        """A named input's proposal as its additive term where the two tie (`p_input_better`,
        logged by `_input_ties`)."""
        term = self.ways.get((named.proposal, "additive"))
        if self.rounds[named.row]["augment"] != "input" or term is None:
            return named
        # The proposal is confirmed; which way adds it is a choice between fits: a term is two
        # numbers per fold, an input is learned anew by each training; tied, the smaller model.
        d = self.d
        p = self.rounds[term.row]["p_input_better"]
        if not _tied(term.shrink, named.shrink, p, _rules.SHRINK_NOISE, d.selection.alpha, _rules.TIE_SHARE):
            return named
        self.log(f"round {self.rnd + 1}: {named.candidate.name} added as a term, not an input: its shrink "
                 f"{term.shrink:+.1%} ties with the input's {named.shrink:+.1%} (p = {p:.3f} that the input "
                 "predicts better)")
        return term

    def _refit_named(self, named: _Confirmed) -> _Confirmed:
        """A named additive term refitted on window nets, kept where that confirms too."""
        d, row, c, conf = self.d, named.row, named.candidate, named.conf
        if self.rounds[row]["augment"] != "additive" or self.current.through_lag:
            return named
        # The tries were refitted on the peak nets, whose residual holds a term short; the
        # named one alone is refitted on window nets, so floor structure that no try
        # confirmed on the peaks cannot be named through it.
        term = named.trial.terms[-1][0]
        w_trial = _augment(self.ctx, self.current, term, "additive", refit="windows")
        w_conf = _confirm(self.ctx, self.current, w_trial, term, named.where, d)
        kept = w_conf.confirmed
        coefficient = float(np.median(w_trial.terms[-1][1][:, 1]))
        self.rounds[row].update(window_refit_coefficient=coefficient, window_refit_kept=kept,
                                window_refit_ensemble_rms_g=w_conf.ensemble[1])
        self.log(f"round {self.rnd + 1}: {c.name} refitted on window nets: coefficient "
                 f"{c.parameters['coefficient']:.4g} -> {coefficient:.4g}, ensemble's RMS "
                 f"{conf.ensemble[1]:.4f} -> {w_conf.ensemble[1]:.4f} g, shrink {w_conf.shrink:+.1%} "
                 f"(all), {w_conf.local:+.1%} ({w_conf.judged_in}): "
                 + ("kept" if kept else f"not confirmed ({w_conf.why}), the peaks' refit kept"))
        if not kept:
            return named
        c = replace(c, parameters={**c.parameters, "coefficient": coefficient})
        return named._replace(candidate=c, trial=w_trial, conf=w_conf)
