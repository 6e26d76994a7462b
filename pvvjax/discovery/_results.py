"""Discovery's outcome as typed records: a trial's confirmation, a named effect and a round
(the discovery itself, `Discovery`, is built from them in `_workflow`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

from .candidates import Candidate

__all__ = ["Confirmation", "Effect", "Predicted", "Round"]


class Predicted(NamedTuple):
    """A model's held-out predictions (seeds, n) on its replay windows (`_Windows`): what two
    trials are compared on, window by window."""

    pred: np.ndarray
    win: Any


@dataclass(frozen=True)
class Confirmation:
    """A trial model tested against the current one (`_confirm._confirm`).

    Attributes:
        confirmed: the trial's effect confirms. why: why not ("" when it does).
        pred: (seeds, n) the trial's held-out predictions, g, on `win`, its replay windows.
        metrics: the trial's `metrics`.
        shrink: relative drop of the ensemble's held-out RMS over all windows.
        local: the same where the effect acts (`judged_in`, maneuver kinds joined by ", ").
        region: where the effect acts and the RMS there before and after (`where`,
            `before_rms_g`, `after_rms_g`).
        ensemble: the ensemble's held-out RMS over all windows, before and after, g.
    """

    confirmed: bool
    why: str
    pred: np.ndarray | None
    win: Any
    metrics: dict
    shrink: float
    local: float
    region: dict
    judged_in: str
    ensemble: tuple[float, float]

    @classmethod
    def not_run(cls) -> "Confirmation":
        """The record of a test that did not run (its shrinks NaN)."""
        return cls(False, "not run", None, None, {}, math.nan, math.nan, {}, "", (math.nan, math.nan))


@dataclass(frozen=True)
class Effect:
    """A confirmed effect, in the order named.

    Attributes:
        rank: 1 for the first named. round: the round that named it (0: the lag test).
        name: in words. operator: the candidate's operator (`effects.OPERATORS`, or "lag").
        channels: the campaign channels it is built from (a lag: the model's inputs).
        parameters: its fitted parameters (knee, centre, τ, coefficient, ...).
        explained_fraction: of the residual, by the selection (or the retraining that
            tested it). p_value: the selection's (or the retraining's) p-value.
        region: where it acts and the held-out RMS there before and after (`where`,
            `before_rms_g`, `after_rms_g`).
        key: the candidate's key. candidate: the candidate as added.
        found_in: the maneuver kind it was found in, or "all".
    """

    rank: int
    round: int
    name: str
    operator: str
    channels: tuple[str, ...]
    parameters: dict
    explained_fraction: float
    p_value: float
    region: dict
    key: str
    candidate: Candidate
    found_in: str

    def summary(self) -> dict:
        """Its entry in `discovery.json` (data-contract §3)."""
        r = lambda v: round(v, 6) if isinstance(v, float) else v  # noqa: E731
        return dict(rank=self.rank, name=self.name, operator=self.operator, channels=list(self.channels),
                    parameters={k: r(v) for k, v in self.parameters.items()},
                    explained_fraction=round(float(self.explained_fraction), 4), p_value=round(float(self.p_value), 4),
                    region={k: r(v) for k, v in self.region.items()})


@dataclass(frozen=True)
class Round:
    """One round of discovery: every try of it and the effect it named.

    Attributes:
        number: 0 for the lag test, then 1, 2, ...
        tries: its rows of `Discovery.tries` (one per proposal and way it was added).
        named: the effect it named, or None (the round that named nothing ends discovery).
    """

    number: int
    tries: pd.DataFrame
    named: Effect | None
