"""The real-time vibration element a simulator embeds: one frame of state in, PVV and a
seat-shake signal out.

`element` (`VibrationElement`) and `npnet` (`NumpyNet`) import NumPy only, so a simulator
host needs no JAX; `cexport` writes the same element as C99 source (`<math.h>` only) and `fmu`
builds it into an FMI 2.0 co-simulation unit, `jsbsim` maps a JSBSim frame to the element's
channels (these import no JAX either; jsbsim only when used); `jax_element` is the
same element as a pure JAX step and scan, and `export` writes an element folder from trained
nets (both import JAX).
"""

from .cexport import CElement, CSourceLimits, c_compiler, c_sources, compile_shared, write_c_element
from .element import CHANNELS, ElementOutput, VibrationElement, stream
from .fmu import build_fmu, model_description
from .jsbsim import JSBSIM_CHANNELS, frame_channels, jsbsim_aircraft, quiet_stdout
from .npnet import NumpyNet, read_npz

__all__ = [
    "CElement",
    "CHANNELS",
    "CSourceLimits",
    "ElementOutput",
    "JSBSIM_CHANNELS",
    "NumpyNet",
    "VibrationElement",
    "build_fmu",
    "c_compiler",
    "c_sources",
    "compile_shared",
    "frame_channels",
    "jsbsim_aircraft",
    "model_description",
    "quiet_stdout",
    "read_npz",
    "stream",
    "write_c_element",
]
