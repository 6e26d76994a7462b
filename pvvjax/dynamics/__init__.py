"""Vibration through time: window sequences of every record (`window_sequences`) and the
dynamic part of a PVV model (a delay and a unit-gain second-order response) as pure,
jit-able and differentiable functions of them."""

from .response import delayed, second_order
from .sequences import Sequences, window_sequences

__all__ = ["Sequences", "delayed", "second_order", "window_sequences"]
