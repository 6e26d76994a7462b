"""Discovery's outcome as typed records: a named effect and a round (the discovery itself,
`Discovery`, is built from them in `_workflow`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import pandas as pd

from .candidates import Candidate

__all__ = ["Effect", "Round"]


@dataclass(frozen=True)
class Effect:
    """A named effect, in the order named.

    Attributes:
        rank: 1 for the first named. round: the test's round that named it (the misfit's
            forms are named first, then the history's, then the missing effects).
        name: in words. operator: the candidate's operator (`effects.OPERATORS`, or "lag").
        channels: the campaign channels it is built from (a lag: the model's inputs).
        parameters: its fitted parameters (knee, centre and width, τ, ...).
        explained_fraction: the share of the residual's variance (partialled out of the
            model's inputs) it explains in its round. p_value: its Holm-adjusted p-value.
        region: where the model with the named effects changed the prediction and the
            held-out RMS there before and after (`where`, `before_rms_g`, `after_rms_g`).
        key: the candidate's key. candidate: the candidate as added.
        found_in: the windows it was tested on ("all").
        kind: "misfit" (a function of the model's inputs that it did not learn), "history"
            (a form of the inputs' history: a rate, a spread inside the window, a lag of the
            prediction) or "missing" (a channel, or its history, beyond both).
        statistic: its test's t on conditions.
        intervals: per fitted parameter, its (low, high) over a bootstrap of conditions.
        tied: the keys of the candidates the data cannot tell from it.
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
    kind: str = "missing"
    statistic: float = math.nan
    intervals: dict = field(default_factory=dict)
    tied: tuple[str, ...] = ()

    def summary(self) -> dict:
        """Its entry in `discovery.json` (data-contract §3)."""
        r = lambda v: round(v, 6) if isinstance(v, float) else v  # noqa: E731
        return dict(rank=self.rank, name=self.name, operator=self.operator, channels=list(self.channels),
                    parameters={k: r(v) for k, v in self.parameters.items()},
                    explained_fraction=round(float(self.explained_fraction), 4), p_value=round(float(self.p_value), 4),
                    region={k: r(v) for k, v in self.region.items()}, kind=self.kind,
                    statistic=round(float(self.statistic), 4), adjusted_p=round(float(self.p_value), 6),
                    intervals={k: [r(float(v)) for v in iv] for k, iv in self.intervals.items()},
                    tied=list(self.tied))


@dataclass(frozen=True)
class Round:
    """One round of discovery's test: every candidate tested in it and the effect it named.

    Attributes:
        number: 1, 2, ... (the misfit's rounds first, then the missing candidates').
        tries: its rows of `Discovery.tries` (one per candidate).
        named: the effect it named, or None (the round that named nothing ends discovery).
    """

    number: int
    tries: pd.DataFrame
    named: Effect | None
