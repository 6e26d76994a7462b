"""The Python API reference, generated from the package (`experiments/reference_docs.py`)."""

from __future__ import annotations

import importlib
import inspect
import re

# Pipeline order: data, analysis, networks, replay, discovery, real time, the generator, the shell.
# A package is listed where it holds names of private modules (nets, discovery, synth).
MODULES = [
    "data.campaign",
    "data.checks",
    "data.plausibility",
    "data.fingerprint",
    "data.units",
    "data.batch",
    "data.constants",
    "data.features",
    "analysis.harmonics",
    "analysis.axes",
    "analysis.databases",
    "nets",
    "nets.networks",
    "nets.train",
    "nets.batched",
    "nets.sweep",
    "nets.evaluation",
    "replay.quasistatic",
    "replay.calibration",
    "replay.tables",
    "replay.studies",
    "discovery",
    "discovery.residuals",
    "discovery.candidates",
    "discovery.effects",
    "discovery.report",
    "dynamics.response",
    "dynamics.checks",
    "dynamics.sequences",
    "dynamics.models",
    "dynamics.compare",
    "dynamics.scores",
    "dynamics.study",
    "dynamics.reporting",
    "seat.study",
    "seat.report",
    "realtime.element",
    "realtime.npnet",
    "realtime.jax_element",
    "realtime.export",
    "realtime.cexport",
    "realtime.fmu",
    "realtime.jsbsim",
    "synth",
    "paper.comparison",
    "config",
    "io",
    "plots",
    "experiment",
    "interrupts",
    "cli",
]


def _signature(name: str, obj) -> str:
    try:
        sig = str(inspect.signature(obj))
    except (TypeError, ValueError):
        return name
    sig = re.sub(r" at 0x[0-9a-f]+", "", sig)  # reprs of default callables carry addresses
    sig = re.sub(r"<PjitFunction of (<function [\w.]+>)>", r"\1", sig)  # a jitted default: its function
    return f"{name}{sig}"


def _first_paragraph(doc: str | None) -> str:
    return (doc or "").strip().split("\n\n")[0].replace("\n", " ")


def _entry(modname: str, name: str, obj) -> list[str]:
    top = f"; also `pvvjax.{name}`" if name in _top_level() and getattr(_pvvjax(), name) is obj else ""
    if inspect.isclass(obj) or callable(obj):
        kind = "class" if inspect.isclass(obj) else "function"
        lines = [f"### `{modname}.{name}` ({kind}{top})", "", "```python", _signature(name, obj), "```", ""]
        doc = inspect.getdoc(obj) if (inspect.isclass(obj) and obj.__doc__) or not inspect.isclass(obj) else ""
        if doc and not doc.startswith(f"{name}("):  # dataclasses' generated docstrings repeat the signature
            lines += [doc, ""]
        return lines
    return [f"### `{modname}.{name}` (constant, `{type(obj).__name__}`{top})", ""]


def _pvvjax():
    import pvvjax

    return pvvjax


def _top_level() -> dict:
    return getattr(_pvvjax(), "_WHERE")


def api_reference() -> str:
    """docs/api.md: every public module in pipeline order, each with its docstring and every
    name in its `__all__` (signature and docstring)."""
    lines = ["# Python API", "",
             "Generated from the package itself (`python experiments/reference_docs.py --docs`); a test keeps it "
             "current. The names most scripts need are importable from `pvvjax` directly (marked below); the rest "
             "from their modules. Numerical functions are pure (JAX arrays and PyTrees in, out); files, plots and "
             "the CLI are at the edges. See [concepts](concepts.md) for the pipeline and [the CLI](cli.md) for "
             "the commands.", "", "## Modules", "", "| module | what it holds |", "|---|---|"]
    mods = {m: importlib.import_module(f"pvvjax.{m}") for m in MODULES}
    listed = {mod.__name__ for mod in mods.values()}
    for m, mod in mods.items():
        anchor = "pvvjax" + m.replace("_", "").replace(".", "")
        lines.append(f"| [`pvvjax.{m}`](#{anchor}) | {_first_paragraph(mod.__doc__)} |")
    lines.append("")
    for m, mod in mods.items():
        lines += [f"## pvvjax.{m}", "", (inspect.getdoc(mod) or "").strip(), ""]
        for name in getattr(mod, "__all__", []):
            obj = getattr(mod, name)
            home = getattr(obj, "__module__", None)
            if home != mod.__name__ and home in listed:  # documented in its own module
                continue
            lines += _entry(m, name, obj)
    return "\n".join(lines).rstrip() + "\n"
