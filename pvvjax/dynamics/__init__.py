"""Vibration through time: window sequences of every record (`window_sequences`), the
dynamic part of a PVV model (a delay and a unit-gain second-order response) as pure,
jit-able and differentiable functions of them, and the physics-shaped model (a static map
followed by them), trained by `nets.train.fit` like a static net."""

from .models import Response, dynamic_apply, dynamic_init, identified
from .response import delayed, second_order
from .sequences import Sequences, window_sequences

__all__ = ["Response", "Sequences", "delayed", "dynamic_apply", "dynamic_init", "identified", "second_order",
           "window_sequences"]
