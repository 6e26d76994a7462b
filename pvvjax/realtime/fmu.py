"""The real-time element as an FMI 2.0 co-simulation unit (FMU), built from its C source.

FMI 2.0 rather than 3.0: the element needs nothing 3.0 adds (clocks, arrays, intermediate
updates), and 2.0 co-simulation is what simulators and tools import most widely today (Simulink,
Dymola, OpenModelica, FMPy, most flight-simulation frameworks). The unit is `c_sources` plus
`csrc/fmi2_pvv_element.c`, compiled with the machine's C compiler into
`binaries/<platform>/pvv_element.<so|dylib|dll>`, with the sources in `sources/` so that a host
on another platform can build it. Each `fmi2DoStep(t, h)` is one element frame at time t.
"""

from __future__ import annotations

import hashlib
import math
import platform
import shutil
import tempfile
import uuid
import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

from .cexport import _CSRC, CSourceLimits, _fill, c_sources, compile_shared
from .element import AIRCRAFT_DEFAULTS, CHANNELS, input_source

__all__ = ["FMU_INPUTS", "build_fmu", "fmu_channels", "fmu_platform", "model_description"]

MODEL_IDENTIFIER = "pvv_element"

# (unit, description) of the frame channels; the unit table below says what each unit is in SI.
FMU_INPUTS = {
    "airspeed_kt": ("kt", "true airspeed"),
    "gross_weight_lb": ("lb", "gross weight"),
    "rotor_rpm": ("rpm", "main-rotor speed (integrated for the azimuth when azimuth_input is false)"),
    "density_ratio": ("1", "air density over sea-level standard"),
    "pitch_rate_dps": ("deg/s", "body pitch rate"),
    "roll_angle_deg": ("deg", "roll attitude"),
    "climb_rate_fpm": ("ft/min", "rate of climb"),
    "collective_pct": ("%", "collective stick, percent of travel"),
    "lateral_pct": ("%", "lateral cyclic stick, percent of travel"),
    "longitudinal_pct": ("%", "longitudinal cyclic stick, percent of travel"),
}
# unit -> (SI base-unit exponents, factor): value_SI = factor * value.
_UNITS = {
    "kt": (dict(m=1, s=-1), 1852.0 / 3600.0), "lb": (dict(kg=1), 0.45359237), "rpm": (dict(rad=1, s=-1), math.pi / 30),
    "1": ({}, 1.0), "deg/s": (dict(rad=1, s=-1), math.pi / 180), "deg": (dict(rad=1), math.pi / 180),
    "ft/min": (dict(m=1, s=-1), 0.3048 / 60), "%": ({}, 0.01), "g": (dict(m=1, s=-2), 9.80665), "s": (dict(s=1), 1.0),
    "rev": (dict(rad=1), 2 * math.pi),
}
# The channels each derived input is computed from.
_NEEDS = {"advance_ratio": ("airspeed_kt", "rotor_rpm"), "mlf": ("airspeed_kt", "pitch_rate_dps", "roll_angle_deg")}


def fmu_platform() -> str:
    """FMI's name of this machine's platform (linux64, darwin64, win64, or machine-system)."""
    system, machine = platform.system(), platform.machine().lower()
    if machine in ("x86_64", "amd64"):
        return {"Linux": "linux64", "Darwin": "darwin64", "Windows": "win64"}.get(system, f"x86_64-{system.lower()}")
    if system == "Darwin":
        return "darwin64"
    return f"{machine}-{system.lower()}"


def fmu_channels(inputs) -> list[str]:
    """The frame channels a database's inputs (features or their rates) need, in `CHANNELS`
    order (the rotor speed always: it drives the azimuth when no azimuth is given)."""
    need = {"rotor_rpm"}
    for k in inputs:
        f, _ = input_source(k)
        need.update(_NEEDS.get(f, (f,)))
    return [c for c in CHANNELS if c in need]


# The seat axes of the outputs shake_x_g, shake_y_g, shake_z_g (data contract: ax_g, ay_g, az_g).
SEAT_AXES = (("x", "longitudinal, positive forward"), ("y", "lateral, positive right"), ("z", "vertical"))


def _var(name, vr, kind, causality, variability, description, unit=None, start=None, initial=None, lo=None, hi=None):
    attrs = f'name="{name}" valueReference="{vr}" description={quoteattr(description)} causality="{causality}" ' \
            f'variability="{variability}"' + (f' initial="{initial}"' if initial else "")
    typed = (f' unit="{unit}"' if unit else "") + (f' start="{start}"' if start is not None else "") \
        + (f' min="{lo!r}"' if lo is not None else "") + (f' max="{hi!r}"' if hi is not None else "")
    return f"    <ScalarVariable {attrs}>\n      <{kind}{typed}/>\n    </ScalarVariable>\n"


def _bool(v) -> str:
    return "true" if v else "false"


def model_description(spec: dict, limits: CSourceLimits, guid: str, source: str = "") -> str:
    """`modelDescription.xml` of the element's FMU (FMI 2.0 co-simulation).

    Args:
        spec: the element's settings (element.json). limits: as `c_sources`.
        guid: the FMU's GUID (also compiled into the binary).
        source: a line naming the nets, in the description.
    """
    variables, outputs = [], []

    def add(text, is_output=False):
        variables.append(text)
        if is_output:
            outputs.append(len(variables))

    ac = {**AIRCRAFT_DEFAULTS, **spec.get("aircraft", {})}
    starts = dict(density_ratio=1.0, rotor_rpm=ac["nominal_rpm"])
    for name in fmu_channels(spec["inputs"]):
        unit, text = FMU_INPUTS[name]
        add(_var(name, CHANNELS.index(name), "Real", "input", "continuous", text, unit, repr(starts.get(name, 0.0))))
    add(_var("azimuth_deg", 10, "Real", "input", "continuous", "reference-blade azimuth", "deg", "0.0"))
    blades = int(ac["blades"])
    for vr, name, unit, text in (
            (20, "pvv_g", "g", f"peak {blades}/rev pilot-floor vertical vibration of the latest window"),
            (21, "shake_g", "g", f"seat-shake acceleration: amplitude x cos({blades} psi + phase) + harmonics"),
            (22, "amplitude_g", "g", "seat-shake amplitude, ramped over one hop"),
            (23, "window_time_s", "s", "centre time of the window pvv_g belongs to (NaN before the first)"),
            *((24 + i, f"pvv_{a}_g", "g", f"{blades}/rev amplitude of the latest window, seat axis {a} ({word}; 0 "
               "where the element does not predict it)") for i, (a, word) in enumerate(SEAT_AXES)),
            *((27 + i, f"shake_{a}_g", "g", f"seat-shake acceleration along {a} ({word}): {blades}/rev at its "
               "amplitude and phase, plus the 1/rev of track and balance") for i, (a, word) in enumerate(SEAT_AXES))):
        add(_var(name, vr, "Real", "output", "continuous", text, unit), True)
    for vr, name, text in ((30, "ready", "a window has been predicted"),
                           (31, "out_of_envelope", "an input of the latest window lay outside the training envelope"),
                           (32, "rejected", "the last frame was ignored (non-finite value or time not advancing)"),
                           (33, "overflow", "frames came faster than the buffers were sized for")):
        add(_var(name, vr, "Boolean", "output", "discrete", text), True)
    wlo, whi = limits.window_revs
    for vr, name, unit, text, start, lo, hi in (
            (40, "offset_s", "s", "input-to-vibration offset", spec["offset_s"], -limits.max_offset_s,
             limits.max_offset_s),
            (41, "stick_offset_s", "s", "the sticks' extra offset (stick lag)", spec["stick_offset_s"],
             -limits.max_stick_offset_s, limits.max_stick_offset_s),
            (42, "window_revs", "rev", "window length", spec["window_revs"], wlo, whi),
            (43, "hop_revs", "rev", "window spacing (update interval), at most the window", spec["hop_revs"], 1e-3,
             whi)):
        add(_var(name, vr, "Real", "parameter", "fixed", text, unit, repr(float(start)), "exact", float(lo), float(hi)))
    add(_var("azimuth_input", 44, "Boolean", "parameter", "fixed",
             "true: the azimuth_deg input gives the rotor azimuth; false: rotor_rpm is integrated", None,
             _bool(True), "exact"))
    add(_var("clip", 45, "Boolean", "parameter", "fixed", "clip inputs to the training envelope (always flagged)",
             None, _bool(True), "exact"))
    units = "".join(
        f'    <Unit name="{name}">\n      <BaseUnit' + "".join(f' {k}="{v}"' for k, v in base.items())
        + (f' factor="{factor!r}"' if factor != 1.0 else "") + "/>\n    </Unit>\n"
        for name, (base, factor) in _UNITS.items())
    unknowns = "".join(f'      <Unknown index="{i}"/>\n' for i in outputs)
    initial = "".join(f'      <Unknown index="{i}" dependencies=""/>\n' for i in outputs)
    description = f"pvvjax real-time PVV element ({', '.join(spec['inputs'])}){': ' + source if source else ''}"
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<fmiModelDescription fmiVersion="2.0" modelName="{MODEL_IDENTIFIER}" guid="{guid}" '
        f'description={quoteattr(description)} generationTool="pvvjax" variableNamingConvention="flat" '
        'numberOfEventIndicators="0">\n'
        f'  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canHandleVariableCommunicationStepSize="true" '
        'canInterpolateInputs="false" canBeInstantiatedOnlyOncePerProcess="false" '
        'canNotUseMemoryManagementFunctions="false" canGetAndSetFMUstate="false" canSerializeFMUstate="false">\n'
        '    <SourceFiles>\n      <File name="pvv_element.c"/>\n      <File name="fmi2_pvv_element.c"/>\n'
        '    </SourceFiles>\n  </CoSimulation>\n'
        f'  <UnitDefinitions>\n{units}  </UnitDefinitions>\n'
        f'  <ModelVariables>\n{"".join(variables)}  </ModelVariables>\n'
        f'  <ModelStructure>\n    <Outputs>\n{unknowns}    </Outputs>\n'
        f'    <InitialUnknowns>\n{initial}    </InitialUnknowns>\n  </ModelStructure>\n'
        '</fmiModelDescription>\n')


def build_fmu(out, spec: dict, nets: list, limits: CSourceLimits = CSourceLimits(), source: str = "") -> Path:
    """Build `out` (a `.fmu` file): C sources, binary for this platform, model description.

    Args:
        out: the FMU's path. spec, nets, limits, source: as `cexport.c_sources`.

    Returns:
        The FMU's path. Raises RuntimeError where no C compiler is found or it fails.
    """
    files = c_sources(spec, nets, limits, source)
    wrapper_template = (_CSRC / "fmi2_pvv_element.c").read_text()
    digest = hashlib.sha256("".join(files.values()).encode() + wrapper_template.encode()).hexdigest()
    guid = "{" + str(uuid.uuid5(uuid.NAMESPACE_URL, "pvvjax-element:" + digest)) + "}"
    files["fmi2_pvv_element.c"] = _fill(wrapper_template, dict(GUID=guid))
    ext = {"Darwin": ".dylib", "Windows": ".dll"}.get(platform.system(), ".so")
    out = Path(out)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for name, text in files.items():
            (root / "sources").mkdir(exist_ok=True)
            (root / "sources" / name).write_text(text)
        binary = root / "binaries" / fmu_platform() / (MODEL_IDENTIFIER + ext)
        compile_shared([root / "sources" / "pvv_element.c", root / "sources" / "fmi2_pvv_element.c"], binary)
        (root / "modelDescription.xml").write_text(model_description(spec, limits, guid, source))
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp_zip = out.with_name(out.name + ".tmp")
        with zipfile.ZipFile(tmp_zip, "w", zipfile.ZIP_DEFLATED) as z:
            for path in sorted(root.rglob("*")):
                if path.is_file():
                    z.write(path, path.relative_to(root).as_posix())
        shutil.move(tmp_zip, out)
    return out
