"""The real-time vibration element a simulator embeds: one frame of state in, PVV and a
seat-shake signal out.

`element` (`VibrationElement`) and `npnet` (`NumpyNet`) import NumPy only, so a simulator
host needs no JAX; `cexport` writes the same element as C99 source (`<math.h>` only) and `fmu`
builds it into an FMI 2.0 co-simulation unit (both import no JAX either); `jax_element` is the
same element as a pure JAX step and scan, and `export` writes an element folder from trained
nets (both import JAX).
"""

from .cexport import CElement, CSourceLimits, c_compiler, c_sources, compile_shared, write_c_element
from .element import CHANNELS, ElementOutput, VibrationElement
from .fmu import build_fmu, model_description
from .npnet import NumpyNet, read_npz

__all__ = [
    "CElement",
    "CHANNELS",
    "CSourceLimits",
    "ElementOutput",
    "NumpyNet",
    "VibrationElement",
    "build_fmu",
    "c_compiler",
    "c_sources",
    "compile_shared",
    "model_description",
    "read_npz",
    "write_c_element",
]
