"""The command line's parser and its reference (docs/cli.md), generated from it."""

from __future__ import annotations

import argparse
import math
import os

from . import _commands as C
from ._export import cmd_export

_CAMPAIGN = "campaign folder (default: the embedded synthetic campaign, generated once into the cache)"
_CONFIG = "experiment config (default: none, the defaults)"
_CAMPAIGN_OF_CONFIG = ("campaign folder (default: the config's [campaign] path, else the embedded synthetic "
                       "campaign)")


def _number(lo: float | None = None, hi: float | None = None, *, above: bool = False, below: bool = False):
    """An argparse type: a finite float within [lo, hi] (`above`/`below`: the bound itself
    excluded), so that a flag's mistake is refused by name before any work starts."""

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        low_ok = lo is None or (v > lo if above else v >= lo)
        high_ok = hi is None or (v < hi if below else v <= hi)
        if not (math.isfinite(v) and low_ok and high_ok):
            lo_s = "" if lo is None else f"{'above' if above else 'at least'} {lo:g}"
            hi_s = "" if hi is None else f"{'below' if below else 'at most'} {hi:g}"
            raise argparse.ArgumentTypeError(f"{text}: must be a finite number" + (
                f" {' and '.join(x for x in (lo_s, hi_s) if x)}" if lo_s or hi_s else ""))
        return v

    parse.__name__ = "number"  # argparse names the type in its own messages
    return parse


def _count(lo: int):
    """An argparse type: an integer of at least `lo`."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"{text}: must be at least {lo}")
        return v

    parse.__name__ = "integer"
    return parse


def _host_port(text: str) -> str:
    """An argparse type: HOST:PORT, the port within 1 to 65535."""
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r}: give HOST:PORT, e.g. localhost:12355 (port within 1 to 65535)")
    return text


_host_port.__name__ = "HOST:PORT"


def build_parser() -> argparse.ArgumentParser:
    """The `pvvjax` parser: one subcommand each, its function as `fn`."""
    from .. import __version__

    p = argparse.ArgumentParser(prog="pvvjax", description="Helicopter pilot-floor 4/rev vibration (PVV) toolkit.")
    p.add_argument("--version", action="version", version=f"pvvjax {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _data_commands(sub)
    _net_commands(sub)
    _replay_commands(sub)
    return p


def _data_commands(sub):
    s = sub.add_parser("validate", help="check a campaign folder against the data contract",
                       description="Report every problem in a campaign folder (exit 1), or exit 0 if valid.")
    s.add_argument("--campaign", required=True, help="campaign folder")
    s.add_argument("--config", help="experiment config: column mapping, window length, harmonic (default: none, "
                                    "the canonical columns)")
    s.set_defaults(fn=C.cmd_validate)

    def campaign_command(name, fn, help, description, out_help):
        s = sub.add_parser(name, help=help, description=description)
        s.add_argument("--campaign", default=None, help=_CAMPAIGN)
        s.add_argument("--out", required=True, help=out_help)
        s.add_argument("--config", help=_CONFIG)
        s.set_defaults(fn=fn)
        return s

    campaign_command("build-db", C.cmd_build_db, "build databases 1-3 from a campaign",
                     "Harmonic analysis, peak PVV per condition and db1-db3 as CSV and Parquet.", "output folder")

    s = sub.add_parser("synth", help="generate a synthetic UH-60A campaign",
                       description="Write a synthetic campaign (and its ground truth beside it).")
    s.add_argument("--out", required=True, help="campaign folder to write")
    s.add_argument("--config", help="generator config (TOML): a hidden-effect scenario "
                                    "(experiments/configs/scenarios/), or a small campaign "
                                    "(experiments/configs/small-campaign.toml: [counts] of random conditions per "
                                    "maneuver kind) (default: the embedded campaign's)")
    s.add_argument("--seed", type=_count(0), default=None, help="random seed (default: the config's, 0)")
    s.add_argument("--truth", default=None, help="ground-truth file (default: OUT.truth.json, beside OUT)")
    s.add_argument("--plots", default=None, metavar="DIR", help="also write the check figures to DIR (default: no)")
    s.add_argument("--force", action="store_true",
                   help="write the campaign into a non-empty folder that is not a synthetic campaign, beside its "
                        "files (they are kept; files of a campaign there are refused even so) (default: refused)")
    s.set_defaults(fn=C.cmd_synth)

    s = campaign_command("plot", C.cmd_plot, "figures of a campaign (PVV vs airspeed, pull-up, autorotation)",
                     "PVV vs airspeed in level flight and paper-style time histories.", "output folder for PNG files")
    s.add_argument("--paper", action="store_true",
                   help="also the paper's Figs 1-9, one file each, and their numbers beside the paper's (default: no)")



def _net_commands(sub):
    s = sub.add_parser("sweep", help="train a sweep of networks (databases x architectures x seeds x folds)",
                       description="Train every net of the config's [sweep] with its [train] settings. "
                                   "Resumable: run it again after an interruption to finish the rest.")
    s.add_argument("config", help="experiment config (TOML), e.g. experiments/configs/sweep-small.toml")
    s.add_argument("--campaign", default=None, help=_CAMPAIGN_OF_CONFIG)
    s.add_argument("--out", default=None, help="sweep folder (default: OUT_DIR/NAME/sweep)")
    s.add_argument("--coordinator", default=None, type=_host_port,
                   help="several processes (one per host, jax.distributed): HOST:PORT of process 0 (default: none, "
                        "one process)")
    s.add_argument("--num-processes", type=_count(1), default=1,
                   help="with --coordinator: how many processes (default: 1)")
    s.add_argument("--process-id", type=_count(0), default=0, help="with --coordinator: this process, 0 to N-1 "
                                                              "(default: 0)")
    s.set_defaults(fn=C.cmd_sweep)

    s = sub.add_parser("export", help="export a trained net, or a real-time element (NumPy, C or FMU) for a "
                                      "simulator host",
                       description="Copy a net's parameters and the NumPy evaluator (no JAX) into a folder; with "
                                   "--element, the real-time vibration element as a NumPy folder, C99 source or an "
                                   "FMI 2.0 co-simulation FMU.")
    s.add_argument("sweep", help="sweep folder (with results.parquet and params/), or with --element the folder of "
                                 "`pvvjax dynamic` (its best model, or --model)")
    s.add_argument("--model", default=None, choices=["quasi_static", "window_static", "window_static_rates",
                                                      "dynamic", "rnn"],
                   help="element from a `pvvjax dynamic` folder: the model, of --database (default: the comparison's "
                        "best; its window, hop and offset are the comparison's)")
    s.add_argument("--out", required=True, help="output folder")
    s.add_argument("--net", default=None, help="net id (default: the best held-out net of --database); with "
                                               "--element, the nets of its architecture (not with --database or "
                                               "--architecture: the net names both)")
    s.add_argument("--database", default=None, choices=["db1", "db2", "db3"],
                   help="database (default: db1; of a `pvvjax dynamic` folder, the best model's)")
    s.add_argument("--element", action="store_true",
                   help="export a real-time vibration element: every net of one architecture of --database, their "
                        "median (default: one net)")
    s.add_argument("--architecture", default=None,
                   help="element of a sweep: the architecture, e.g. 6-10-5-1 (default: the best median held-out RMS)")
    s.add_argument("--offset", type=_number(), default=None, help="element of a sweep or an axes study: "
                                                              "input-to-vibration offset, s, within -1 to 3 (default: "
                                                              "0)")
    s.add_argument("--stick-offset", type=_number(), default=None, help="element of a sweep or an axes study: extra "
                                                                    "offset of the sticks, s, within -2 to 2 "
                                                                    "(default: 0)")
    s.add_argument("--window", type=_number(), default=None, help="element of a sweep or an axes study: window "
                                                              "length, revolutions, within 4 to 16 (default: 8)")
    s.add_argument("--hop", type=_number(0.0, above=True), default=None,
                   help="element of a sweep or an axes study: window spacing (update interval), revolutions, above 0 "
                        "and at most the window (default: 1)")
    s.add_argument("--format", default="numpy", choices=["numpy", "c", "fmu"],
                   help="element: numpy (element.json, the nets and the NumPy modules), c (pvv_element.h and "
                        "pvv_element.c, C99, <math.h> only) or fmu (pvv_element.fmu, FMI 2.0 co-simulation, built "
                        "with the machine's C compiler) (default: numpy)")
    s.add_argument("--max-rate", type=_number(0.0, 1e5, above=True), default=None,
                   help="element, c and fmu: highest frame rate the fixed buffers are sized for, Hz, above 0 and at "
                        "most 100000 (default: 1000)")
    s.set_defaults(fn=cmd_export)

    s = sub.add_parser("realtime", help="feed a recorded counter to a real-time element frame by frame",
                       description="An example simulator host: resample a record to a frame rate, step the "
                                   "exported NumPy element once per frame, report latency percentiles.")
    s.add_argument("--model", required=True, help="element folder (pvvjax export --element)")
    s.add_argument("--record", required=True, help="counter to play, e.g. 11022")
    s.add_argument("--campaign", default=None, help=_CAMPAIGN)
    s.add_argument("--rate", type=_number(0.0, 1e5, above=True), default=None,
                   help="frame rate, Hz, above 0 and at most 100000 (default: the record's)")
    s.add_argument("--jitter", type=_number(0.0, 1.0, below=True), default=0.0,
                   help="random frame-time jitter, fraction of a frame, from 0 to below 1 (default: 0)")
    s.add_argument("--out", default=None, help="CSV file of the output signal (default: none)")
    s.set_defaults(fn=C.cmd_realtime)



def _replay_commands(sub):
    s = sub.add_parser("replay", help="quasi-static replay of recorded maneuvers through the trained nets",
                       description="Replay counters through the nets that held them out ([replay] of the config; "
                                   "trains the config's sweep first when [replay] sweep is empty).")
    s.add_argument("config", help="experiment config (TOML), e.g. experiments/configs/replay.toml")
    s.add_argument("--campaign", default=None, help=_CAMPAIGN_OF_CONFIG)
    s.add_argument("--offset", type=_number(), default=None,
                   help="input-to-vibration offset, s (default: the config's)")
    s.add_argument("--window", type=_number(1.0, 64.0), default=None,
                   help="window length, revolutions, within 1 to 64 (default: the config's)")
    s.add_argument("--counters", nargs="+", default=None, help="counters to replay (default: the config's)")
    s.add_argument("--plots", type=_count(0), default=4, help="figures for the first N counters (default: 4)")
    s.add_argument("--out", default=None, help="output folder (default: OUT_DIR/NAME/replay)")
    s.set_defaults(fn=C.cmd_replay)

    s = sub.add_parser("calibrate", help="fit the offset, window length and stick lag by gradient",
                       description="Levenberg-Marquardt from the best point of a coarse grid, per database and "
                                   "group ([calibration] of the config), checked against a brute-force grid.")
    s.add_argument("config", help="experiment config (TOML), e.g. experiments/configs/replay.toml")
    s.add_argument("--campaign", default=None, help=_CAMPAIGN_OF_CONFIG)
    s.add_argument("--groups", choices=["all", "maneuver", "counter"], default=None,
                   help="one fit for all counters, per maneuver kind, or per counter (default: the config's)")
    s.add_argument("--free", nargs="+", choices=["offset_s", "window_revs", "stick_offset_s"], default=None,
                   help="parameters to fit (default: the config's)")
    s.add_argument("--counters", nargs="+", default=None, help="counters to calibrate on (default: the config's)")
    s.add_argument("--out", default=None, help="output folder (default: OUT_DIR/NAME/calibration)")
    s.set_defaults(fn=C.cmd_calibrate)

    s = sub.add_parser("discover", help="find, name, add and confirm effects the static map misses",
                       description="Replay every counter through held-out nets, locate the residual, test the "
                                   "candidate effects at one stated level (cross-fitted, conditions as the "
                                   "units), fit the named ones, add them to the model and report whether the "
                                   "held-out gap closes. Writes OUT/discovery.json (data contract section 3) and "
                                   "OUT/report.md.")
    s.add_argument("--campaign", default=None, help=_CAMPAIGN)
    s.add_argument("--out", required=True, help="output folder")
    s.add_argument("--config", default=None, help="experiment config ([discovery], [train], [analysis] sections; "
                                                  "default: none, the defaults)")
    s.set_defaults(fn=C.cmd_discover)

    s = sub.add_parser("dynamic", help="train and compare PVV models through time against the quasi-static map",
                       description="Window sequences of every record; the quasi-static peak map, the same map on "
                                   "every window (with and without state rates), the physics-shaped dynamic model "
                                   "(map, delay, second-order response) and a GRU, held out by condition and by "
                                   "maneuver kind ([dynamic] of the config). Resumable. Writes OUT/comparison.csv, "
                                   "OUT/identified.csv, OUT/predictions.parquet and OUT/report.md.")
    s.add_argument("--campaign", default=None, help=_CAMPAIGN_OF_CONFIG)
    s.add_argument("--out", required=True, help="output folder (claimed; rerun with the same config to resume)")
    s.add_argument("--config", default=None, help="experiment config ([dynamic], [train], [analysis] sections; "
                                                  "default: none, the defaults)")
    s.add_argument("--seeds", type=_count(1), default=None, help="initialisation seeds per fold (default: the "
                                                                  "config's)")
    s.set_defaults(fn=C.cmd_dynamic)

    s = sub.add_parser("axes", help="which inputs each pilot-floor axis (vertical, longitudinal, lateral) needs",
                       description="Nets of one output per axis on each database's inputs, held out by condition "
                                   "and judged per axis by FAA Part 60 test 3.f.1 ([axes] of the config); the "
                                   "discovery on every axis no database suffices for. Resumable. Writes "
                                   "OUT/axes.csv, OUT/needs.csv, OUT/predictions.parquet, OUT/report.md and "
                                   "OUT/discovery-AXIS/.")
    s.add_argument("--campaign", default=None, help=_CAMPAIGN_OF_CONFIG)
    s.add_argument("--out", required=True, help="output folder (claimed; rerun with the same config to resume)")
    s.add_argument("--config", default=None, help="experiment config ([axes], [train], [analysis], [discovery] "
                                                  "sections; default: none, the defaults)")
    s.add_argument("--no-discovery", action="store_true",
                   help="skip the discovery on the axes no database serves (default: [axes] discovery)")
    s.set_defaults(fn=C.cmd_axes)

    s = sub.add_parser("run", help="run an experiment config end to end (the main job)",
                       description="Campaign, databases and figures for one experiment config; with [run] "
                                   "networks the paper's networks (Figs 10-12, Table 1), with [run] "
                                   "discovery_scenario a hidden-effect discovery; writes report.md and report.html.")
    s.add_argument("config", help="experiment config (TOML)")
    s.add_argument("--campaign", default=None, help=_CAMPAIGN_OF_CONFIG)
    s.set_defaults(fn=C.cmd_run)


def cli_reference(width: int = 96) -> str:
    """The command-line reference as Markdown, generated from the parser itself (every
    subcommand's `--help`), so that the docs cannot drift from the CLI."""
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(width)  # argparse wraps to the terminal width
    try:
        p = build_parser()
        parts = ["# Command-line reference", "",
                 "Generated from the CLI itself (`python experiments/reference_docs.py --docs`); "
                 "every subcommand also has `--help`.", "", "```", p.format_help().rstrip(), "```", ""]
        sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
        for name, sp in sub.choices.items():
            parts += [f"## pvvjax {name}", "", "```", sp.format_help().rstrip(), "```", ""]
        return "\n".join(parts)
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old
