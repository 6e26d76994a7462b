"""Vibration through time: the dynamic part of a PVV model (a delay and a unit-gain
second-order response) as pure, jit-able and differentiable functions of window sequences."""

from .response import delayed, second_order

__all__ = ["delayed", "second_order"]
