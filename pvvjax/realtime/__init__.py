"""The real-time vibration element a simulator embeds: one frame of state in, PVV and a
seat-shake signal out.

`element` (`VibrationElement`) and `npnet` (`NumpyNet`) import NumPy only, so a simulator
host needs no JAX; `jax_element` is the same element as a pure JAX step and scan, and
`export` writes an element folder from trained nets (both import JAX).
"""

from .element import CHANNELS, ElementOutput, VibrationElement
from .npnet import NumpyNet, read_npz

__all__ = [
    "CHANNELS",
    "ElementOutput",
    "NumpyNet",
    "VibrationElement",
    "read_npz",
]
