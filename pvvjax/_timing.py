"""Wall time per named stage of a long computation, from one helper."""

from __future__ import annotations

import contextlib
import time

__all__ = ["Stopwatch"]


class Stopwatch:
    """Seconds per stage, summed over the times a stage runs: `with clock("explain"): ...`.

    `seconds` is the dict of stages in the order they first ran; a stage nested in another
    counts in both.
    """

    def __init__(self):
        self.seconds: dict[str, float] = {}

    @contextlib.contextmanager
    def __call__(self, stage: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[stage] = self.seconds.get(stage, 0.0) + time.perf_counter() - t0
