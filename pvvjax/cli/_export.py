"""`pvvjax export`: a trained net, or the real-time element (NumPy, C or FMU) of a sweep, a
`pvvjax dynamic` comparison or a `pvvjax axes` study."""

from __future__ import annotations

from pathlib import Path

from ..experiment import resolve_campaign
from ..io import own_folder

# The flags a folder's export can take, their defaults, and what each kind of export honours.
_FLAGS = {"model": "--model", "net": "--net", "database": "--database", "architecture": "--architecture",
          "offset": "--offset", "stick_offset": "--stick-offset", "window": "--window", "hop": "--hop",
          "max_rate": "--max-rate"}
_DEFAULTS = dict(offset=0.0, stick_offset=0.0, window=8.0, hop=1.0, max_rate=1000.0)
_WINDOWS = {"offset", "stick_offset", "window", "hop"}
_HONOURED = {
    "dynamic": ({"model", "database"}, "a model of a `pvvjax dynamic` comparison (its windows, hop and offset are "
                                       "the comparison's)"),
    "axes": ({"database"} | _WINDOWS, "the nets of a `pvvjax axes` study"),
    "element": ({"net", "database", "architecture"} | _WINDOWS, "a sweep's element"),
    "net": ({"net", "database"}, "one net of a sweep (add --element for the element's settings)"),
}


def _settle_flags(args, kind: str) -> None:
    """Refuse, by name, every flag the export of `kind` would not honour and the flags that
    contradict each other; then fill the defaults of those left unset."""
    honoured, what = _HONOURED[kind]
    if args.element and args.format != "numpy":
        honoured = honoured | {"max_rate"}
    bad = [flag for key, flag in _FLAGS.items() if getattr(args, key) is not None and key not in honoured]
    if bad == ["--max-rate"]:
        raise ValueError("--max-rate: sizes the buffers of the C and FMU element; give it with --element and --format "
                         "c or fmu")
    if bad:
        it = "it" if len(bad) == 1 else "them"
        raise ValueError(f"{', '.join(bad)}: not used when exporting {what}; leave {it} out")
    if args.net is not None:
        both = [flag for key, flag in (("database", "--database"), ("architecture", "--architecture"))
                if getattr(args, key) is not None]
        if both:
            raise ValueError(f"--net {args.net} and {' and '.join(both)}: the net names its own database and "
                             "architecture; give one or the other")
    for key, value in _DEFAULTS.items():
        if getattr(args, key) is None:
            setattr(args, key, value)
    if kind != "dynamic" and args.database is None:
        args.database = "db1"


def _check_element_settings(args) -> None:
    """An element's offsets and window within the calibration's bounds (a NaN or a negative
    window would make every frame NaN)."""
    import math

    from ..replay.calibration import Bounds

    b = Bounds()
    for flag, value, (lo, hi) in (("--offset", args.offset, b.offset_s), ("--stick-offset", args.stick_offset,
                                  b.stick_offset_s), ("--window", args.window, b.window_revs)):
        if not (math.isfinite(value) and lo <= value <= hi):
            raise ValueError(f"{flag} {value:g}: must be a number within {lo:g} to {hi:g}")
    if not (math.isfinite(args.hop) and 0 < args.hop <= args.window):
        raise ValueError(f"--hop {args.hop:g}: must be above 0 and at most the window ({args.window:g} revs)")


def _export_element(args, res, sweep: Path) -> int:
    """Every net of one database (all seeds and folds: their median) with the replay
    settings and the training envelope, as a NumPy real-time element."""
    from ..analysis.databases import DB_INPUTS, peak_table
    from ..config import load_config
    from ..nets.sweep import load_nets
    from ..realtime.export import element_spec

    database, arch = args.database, args.architecture
    if args.net:
        row = res[res.net_id == args.net]
        if row.empty:
            raise KeyError(f"{sweep / 'results.parquet'}: no net {args.net!r}")
        database, arch = row.database.iloc[0], row.architecture.iloc[0]
    sel = res[res.database == database]
    if sel.empty:
        raise KeyError(f"{sweep / 'results.parquet'}: no net for database {database!r}")
    archs = sorted(set(sel.architecture))
    if arch is None:  # the architecture whose nets hold out best (median over seeds and folds)
        arch = sel.groupby("architecture").test_rms_g.median().idxmin()
    if arch not in archs:
        raise KeyError(f"--architecture {arch!r}: {database} of {sweep} has {', '.join(archs)}")
    sel = sel[sel.architecture == arch]
    ids = list(sel.sort_values(["test_fold", "seed"]).net_id)
    cfg = load_config(sweep / "config.toml")
    campaign, _ = resolve_campaign(cfg)
    inputs = list(DB_INPUTS[database])
    db = peak_table(campaign, cfg.analysis)[0][inputs]
    spec = element_spec([f"net_{i}.npz" for i in ids], inputs, (db.min(), db.max()), campaign,
                        cfg.analysis.window_revs, window_revs=args.window, hop_revs=args.hop, offset_s=args.offset,
                        stick_offset_s=args.stick_offset)
    source = f"{len(ids)} {arch} nets ({database}) of {sweep}"
    out = _write_element_format(args, spec, load_nets(sweep, ids, res), source)
    print(f"exported a real-time element ({args.format}): {len(ids)} {arch} nets ({database}), window "
          f"{args.window:g} revs, hop {args.hop:g} revs, offset {args.offset:g} s, to {out}")
    return 0


def _export_dynamic_element(args, folder: Path) -> int:
    """A model of a `pvvjax dynamic` comparison as a real-time element (`dynamics.study.
    element_model`), its input envelope the windows it was judged on."""
    import pandas as pd

    from ..config import load_config
    from ..dynamics import window_sequences
    from ..dynamics.study import element_model
    from ..realtime.element import input_source
    from ..realtime.export import element_spec

    cfg = load_config(folder / "config.toml")
    em = element_model(folder, cfg, args.model, args.database)
    campaign, _ = resolve_campaign(cfg)
    counters = sorted(set(pd.read_parquet(folder / "predictions.parquet", columns=["counter"]).counter))
    inputs = em.nets[0][1]["inputs"]
    plain = [n for n in inputs if not input_source(n)[1]]  # the features whose rates the nets take too
    seq = window_sequences(campaign, plain, window_revs=em.window_revs, hop_revs=em.hop_revs, counters=counters,
                           rates=len(plain) < len(inputs), chain=True)
    x = seq.inputs[seq.mask]
    spec = element_spec([f"net_{i}.npz" for i in range(len(em.nets))], em.nets[0][1]["inputs"],
                        (x.min(axis=0), x.max(axis=0)), campaign, cfg.analysis.window_revs,
                        window_revs=em.window_revs, hop_revs=em.hop_revs, offset_s=em.offset_s, stick_offset_s=0.0)
    if em.response is not None:
        spec["response"] = em.response
    source = f"{len(em.nets)} {em.model} nets ({em.database}) of {folder}"
    out = _write_element_format(args, spec, em.nets, source)
    print(f"exported a real-time element ({args.format}): {source}, window {em.window_revs:g} revs, hop "
          f"{em.hop_revs:g} revs" + (f", response {em.response}" if em.response else "") + f", to {out}")
    return 0


def _export_axes_element(args, folder: Path) -> int:
    """The nets of one database of a `pvvjax axes` study (every fold and seed: their median)
    as a three-axis real-time element: each axis's N/rev phase and 1/rev of track and balance
    from the campaign, the envelope of the rows the nets trained on."""
    from ..analysis.databases import DB_INPUTS, axes_database
    from ..config import load_config
    from ..realtime.export import element_spec
    from ..seat import study_nets

    cfg = load_config(folder / "config.toml")
    campaign, _ = resolve_campaign(cfg)
    nets = study_nets(folder, args.database)
    outputs = list(nets[0][1]["outputs"])
    inputs = list(DB_INPUTS[args.database])
    rows = axes_database(campaign, cfg.analysis)[inputs]
    spec = element_spec([f"net_{i}.npz" for i in range(len(nets))], inputs, (rows.min(), rows.max()), campaign,
                        cfg.analysis.window_revs, window_revs=args.window, hop_revs=args.hop, offset_s=args.offset,
                        stick_offset_s=args.stick_offset, outputs=outputs)
    source = f"{len(nets)} nets of {len(outputs)} outputs ({args.database}: {', '.join(outputs)}) of {folder}"
    out = _write_element_format(args, spec, nets, source)
    print(f"exported a three-axis real-time element ({args.format}): {source}, window {args.window:g} revs, hop "
          f"{args.hop:g} revs, offset {args.offset:g} s, to {out}")
    return 0


def _write_element_format(args, spec: dict, nets: list, source: str) -> Path:
    """The element in the format asked for: the NumPy folder, the C source, or the FMU."""
    import json

    from ..realtime.cexport import CSourceLimits, write_c_element
    from ..realtime.export import write_element
    from ..realtime.fmu import build_fmu
    from ..realtime.npnet import NumpyNet

    if args.format == "numpy":
        return write_element(args.out, nets, spec)
    nets = [NumpyNet(params, meta) for params, meta in nets]
    lo, hi = CSourceLimits().window_revs
    limits = CSourceLimits(max_rate_hz=args.max_rate, window_revs=(min(lo, spec["window_revs"]), hi))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "settings.json").write_text(json.dumps({**spec, "nets": source}, indent=2))  # what was built in
    if args.format == "c":
        return write_c_element(out, spec, nets, limits, source)
    return build_fmu(out / "pvv_element.fmu", spec, nets, limits, source)


def cmd_export(args) -> int:
    """Copy a trained net and the NumPy evaluator into a folder a simulator host can use."""
    import shutil

    from ..nets.sweep import finished_sweep, load_nets
    from ..realtime import npnet

    sweep = Path(args.sweep)
    if (sweep / "comparison.parquet").is_file():  # the folder of `pvvjax dynamic`
        if not args.element:
            raise ValueError(f"{sweep}: a comparison of `pvvjax dynamic`; export its models with --element")
        _settle_flags(args, "dynamic")
        own_folder(args.out, "pvvjax export")
        return _export_dynamic_element(args, sweep)
    if (sweep / "axes.parquet").is_file():  # the folder of `pvvjax axes`
        if not args.element:
            raise ValueError(f"{sweep}: a study of `pvvjax axes`; export its three-axis nets with --element (and "
                             "--database)")
        _settle_flags(args, "axes")
        _check_element_settings(args)
        own_folder(args.out, "pvvjax export")
        return _export_axes_element(args, sweep)
    if args.element:
        _settle_flags(args, "element")
        _check_element_settings(args)
    elif args.format != "numpy":
        raise ValueError(f"--format {args.format}: a format of the real-time element; add --element")
    else:
        _settle_flags(args, "net")
    res = finished_sweep(sweep)
    own_folder(args.out, "pvvjax export")
    if args.element:
        return _export_element(args, res, sweep)
    if args.net:
        sel = res[res.net_id == args.net]
        if sel.empty:
            raise KeyError(f"{sweep / 'results.parquet'}: no net {args.net!r}")
    else:  # best held-out net of the requested database
        sel = res[res.database == args.database].sort_values("test_rms_g").head(1)
        if sel.empty:
            raise KeyError(f"{sweep / 'results.parquet'}: no net for database {args.database!r}")
    row = sel.iloc[0]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    [(params, meta)] = load_nets(sweep, [row.net_id], res)
    npnet.write_npz(out / "net.npz", params, meta)
    shutil.copy(npnet.__file__, out / "npnet.py")
    (out / "README.md").write_text(
        f"# Exported network {row.architecture} ({row.database}, net {row.net_id})\n\n"
        f"Held-out RMS {row.test_rms_g:.4f} g. Needs NumPy only.\n\n"
        "```python\nfrom npnet import NumpyNet\nnet = NumpyNet.load('net.npz')\n"
        f"pvv_g = net([{', '.join(meta['inputs'])}])\n```\n\nInputs in this order, canonical units "
        "(kt, lb, rpm, -, -, ft/min, %).\n")
    print(f"exported {row.database} {row.architecture} (net {row.net_id}, held-out RMS {row.test_rms_g:.4f} g) "
          f"to {out}")
    print(f"inputs: {', '.join(meta['inputs'])}")
    return 0
