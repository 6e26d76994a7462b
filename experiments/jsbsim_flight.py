"""JSBSim's AH-1S flown with the vibration element in the loop.

    python experiments/jsbsim_flight.py experiments/configs/jsbsim-ah1s.toml [--docs]

1. The AH-1S's rotor constants are read from JSBSim's model (`realtime.jsbsim_aircraft`).
2. A synthetic campaign of that aircraft (UH-60A-like physics scaled to its 2-bladed rotor:
   a stand-in until measured data exist) trains the config's nets (`pvvjax sweep`), exported as
   the element (`pvvjax export --element`: NumPy; and C, `--format c`, where a C compiler is).
   With `model = "dynamic"` the element is `pvvjax dynamic`'s `best` model instead (the config's
   [dynamic] and [train]: the lowest held-out RMS of its models, with the physics-shaped
   model's delay and response, the rates or the GRU's state where the best has them); with
   `model = "axes"` they are `pvvjax axes`'s nets of three outputs (the config's [axes]), and the
   element shakes the seat in three axes (its 2/rev N/rev on the AH-1S's two blades, with each
   axis's 1/rev of track and balance).
3. Each flight of the config runs JSBSim's `ah1s_flight_test.xml` script frame by frame; each
   frame is mapped to the data contract's channels (`realtime.JSBSIM_CHANNELS`) and fed to the
   element, the rotor azimuth integrated from the rotor speed. A flight may add a pitch-attitude
   pulse through the AFCS trim (`ap/afcs/manual/theta-trim-rad`).

Writes, under OUT_DIR/NAME: per flight `FLIGHT.parquet` (every frame: the channels, PVV and seat
shake of each seat axis x, y, z, flags, per-frame latency), `flights.csv` (one row per flight) and
`flights.png` (airspeed, pitch rate and rotor speed over each axis's PVV and seat shake); with
--docs the figure also goes to docs/figures/jsbsim_ah1s.png.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from pvvjax.config import (
    AxesConfig,
    CampaignConfig,
    DynamicConfig,
    ExperimentConfig,
    SweepConfig,
    TrainConfig,
    load_config,
)
from pvvjax.realtime import CElement, VibrationElement, c_compiler, compile_shared
from pvvjax.realtime.jsbsim import JSBSIM_CHANNELS, frame_channels, jsbsim_aircraft, quiet_stdout

THETA_TRIM = "ap/afcs/manual/theta-trim-rad"
# The element's outputs each frame writes: PVV and shake of the first output, then of each seat axis.
OUTPUTS = ("pvv_g", "shake_g", "pvv_x_g", "pvv_y_g", "pvv_z_g", "shake_x_g", "shake_y_g", "shake_z_g")


@dataclass(frozen=True)
class Flight:
    """One flight of the script.

    Attributes:
        variant: the script's `simulation/test-variant` (1: AFCS-held acceleration to maximum
            speed at 5000 ft; 3: 90 kt at 5000 ft, power loss, autorotation and flare).
        end_s: stop at this simulation time, s (or where the script ends).
        pulse_at_s, pulse_s, pulse_rad: a pitch-attitude pulse: the AFCS pitch trim raised by
            pulse_rad for pulse_s from pulse_at_s (0 s: none).
    """

    variant: int = 1
    end_s: float = 600.0
    pulse_at_s: float = 0.0
    pulse_s: float = 0.0
    pulse_rad: float = 0.0


@dataclass(frozen=True)
class JSBSimFlightConfig:
    """The example: the aircraft, its synthetic campaign and nets, the element, the flights.

    Attributes:
        name, out_dir: results go to out_dir/name.
        aircraft, script: JSBSim's model and script (relative to JSBSim's root folder).
        sample_rate_hz: the synthetic campaign's sample rate (64 per revolution at 115 % rpm).
        counts: the campaign's random conditions per maneuver kind (empty: the default campaign).
        database, offset_s, window_revs, hop_revs: the quasi-static element (`pvvjax export
            --element`).
        model: "quasi_static" (the sweep's nets, replayed), "dynamic" (`pvvjax dynamic`'s best
            model of `database`, with its own windows) or "axes" (`pvvjax
            axes`'s nets of `database`, one output per pilot-floor axis: a three-axis shake).
        sweep, train, dynamic, axes: the nets (as an experiment config's sections).
        flights: name -> `Flight`.
    """

    name: str = "jsbsim-ah1s"
    out_dir: str = "runs"
    aircraft: str = "ah1s"
    script: str = "scripts/ah1s_flight_test.xml"
    sample_rate_hz: float = 400.0
    counts: dict[str, int] = field(default_factory=dict)
    database: str = "db1"
    offset_s: float = 0.5
    window_revs: float = 8.0
    hop_revs: float = 1.0
    model: Literal["quasi_static", "dynamic", "axes"] = "quasi_static"
    sweep: SweepConfig = field(default_factory=SweepConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    dynamic: DynamicConfig = field(default_factory=DynamicConfig)
    axes: AxesConfig = field(default_factory=AxesConfig)
    flights: dict[str, Flight] = field(default_factory=dict)


def _pvvjax(args: list[str]):
    """Run a `pvvjax` command (the one a user would type) in this process; an error stops here."""
    from pvvjax.cli import main as pvvjax

    if pvvjax(args) != 0:
        raise SystemExit(f"pvvjax {' '.join(args)} failed")


def train_element(cfg: JSBSimFlightConfig, out: Path) -> tuple[Path, Path | None]:
    """The aircraft's campaign, nets and element; returns (NumPy element folder, C library or None)."""
    import jsbsim

    from pvvjax.experiment import prepare_sweep
    from pvvjax.synth import SynthConfig, cached_campaign

    constants = jsbsim_aircraft(jsbsim.get_default_root_dir(), cfg.aircraft)
    print(f"{cfg.aircraft} from JSBSim: " + ", ".join(f"{k} {v:g}" for k, v in constants.items()))
    scfg = SynthConfig(name=f"{cfg.aircraft}-synthetic", sample_rate_hz=cfg.sample_rate_hz, counts=dict(cfg.counts),
                       aircraft=constants)
    campaign = cached_campaign(scfg)
    print(f"synthetic {cfg.aircraft} campaign (UH-60A-like physics scaled to its rotor): {campaign}")
    ecfg = ExperimentConfig(name=cfg.name, out_dir=cfg.out_dir, campaign=CampaignConfig(path=str(campaign)),
                            sweep=dataclasses.replace(cfg.sweep, databases=(cfg.database,)), train=cfg.train,
                            dynamic=dataclasses.replace(cfg.dynamic, databases=(cfg.database,)),
                            axes=dataclasses.replace(cfg.axes, databases=(cfg.database,)))
    if cfg.model == "axes":
        from pvvjax.experiment import resolve_campaign
        from pvvjax.seat import run_study

        folder, study, _ = run_study(ecfg.with_(axes=dataclasses.replace(ecfg.axes, discovery=False)),
                                     resolve_campaign(ecfg)[0], campaign, out / "axes")
        print(study.table.drop(columns="fails").round(4).to_string(index=False))
        export = ["export", str(folder), "--element", "--database", cfg.database,
                  "--offset", repr(cfg.offset_s), "--window", repr(cfg.window_revs), "--hop", repr(cfg.hop_revs)]
    elif cfg.model == "dynamic":
        from pvvjax.dynamics.study import run_dynamic
        from pvvjax.experiment import resolve_campaign

        folder, table = run_dynamic(ecfg, resolve_campaign(ecfg)[0], campaign, out / "dynamic")
        print(table[["model", "rms_g", "faa_pass_share", "best"]].to_string(index=False))
        export = ["export", str(folder), "--element", "--database", cfg.database]
    else:
        _, _, res, sweep = prepare_sweep(ecfg, out / "sweep")
        print(f"{len(res)} nets in {sweep}")
        export = ["export", str(sweep), "--element", "--database", cfg.database,
                  "--offset", repr(cfg.offset_s), "--window", repr(cfg.window_revs), "--hop", repr(cfg.hop_revs)]
    _pvvjax(export + ["--out", str(out / "element")])
    if c_compiler() is None:
        print("no C compiler: the C element is left out")
        return out / "element", None
    _pvvjax(export + ["--format", "c", "--max-rate", "200", "--out", str(out / "c")])
    return out / "element", compile_shared([out / "c" / "pvv_element.c"], out / "c" / "libpvv_element.so")


def fly(cfg: JSBSimFlightConfig, flight: Flight, element: Path, c_library: Path | None) -> pd.DataFrame:
    """One flight, every JSBSim frame through the element (and the C element): a frame table."""
    import jsbsim

    el = VibrationElement.load(element)
    cel = CElement(c_library) if c_library else None
    rows, clock = [], time.perf_counter_ns
    with quiet_stdout():
        fdm = jsbsim.FGFDMExec(jsbsim.get_default_root_dir())
        fdm.set_debug_level(0)
        fdm.load_script(cfg.script)
        fdm["simulation/test-variant"] = flight.variant
        fdm.run_ic()
        trim = None
        while fdm.get_sim_time() < flight.end_s and fdm.run():
            t = fdm.get_sim_time()
            if flight.pulse_s and t >= flight.pulse_at_s:
                trim = fdm[THETA_TRIM] if trim is None else trim
                fdm[THETA_TRIM] = trim + (flight.pulse_rad if t < flight.pulse_at_s + flight.pulse_s else 0.0)
            t, x = frame_channels(fdm)
            s = clock()
            o = el.step(t, None, x)  # no azimuth in JSBSim's rotor model: the rotor speed is integrated
            lat = (clock() - s) / 1e3
            row = [t, *x, *(getattr(o, k) for k in OUTPUTS), o.amplitude_g, o.ready, o.out_of_envelope, o.rejected,
                   lat]
            if cel is not None:
                s = clock()
                c = cel.step(t, None, x)
                row += [*(c[k] for k in OUTPUTS), (clock() - s) / 1e3]
            rows.append(row)
    cols = ["time_s", *JSBSIM_CHANNELS, *OUTPUTS, "amplitude_g", "ready", "out_of_envelope", "rejected",
            "latency_us"] + ([f"c_{k}" for k in OUTPUTS] + ["c_latency_us"] if cel is not None else [])
    df = pd.DataFrame(rows, columns=cols)
    return df.astype({k: bool for k in ("ready", "out_of_envelope", "rejected")})


def summarize(name: str, df: pd.DataFrame) -> dict:
    ready = df[df.ready]
    row = dict(flight=name, frames=len(df), sim_s=float(df.time_s.iloc[-1] - df.time_s.iloc[0]),
               frame_rate_hz=float(1.0 / np.median(np.diff(df.time_s))), max_pvv_g=float(ready.pvv_g.max()),
               out_of_envelope_share=float(ready.out_of_envelope.mean()), rejected=int(df.rejected.sum()),
               numpy_latency_median_us=float(df.latency_us.median()),
               numpy_latency_p99_us=float(df.latency_us.quantile(0.99)))
    if "c_pvv_g" in df:
        row.update(c_latency_median_us=float(df.c_latency_us.median()),
                   c_latency_p99_us=float(df.c_latency_us.quantile(0.99)),
                   c_minus_numpy_g=float(np.abs(df[[f"c_{k}" for k in OUTPUTS]].to_numpy()
                                                - df[list(OUTPUTS)].to_numpy()).max()))
    return row


def figure(flights: dict[str, pd.DataFrame], plans: dict[str, Flight], path: Path):
    """Airspeed, pitch rate and rotor speed over each seat axis's PVV and seat shake, a column
    per flight (a flight with a pitch pulse from 20 s before it); an element of one axis shows
    its vertical only."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [("airspeed_kt", "airspeed, kt"), ("pitch_rate_dps", "pitch rate, deg/s"), ("rotor_rpm", "rotor, rpm")]
    fig, axes = plt.subplots(5, len(flights), figsize=(4.2 * len(flights), 10), sharex="col", squeeze=False)
    for col, (name, df) in enumerate(flights.items()):
        if plans[name].pulse_s:
            df = df[df.time_s >= plans[name].pulse_at_s - 20.0]
        for r, (k, label) in enumerate(rows):
            axes[r, col].plot(df.time_s, df[k], "k-", lw=0.8)
            axes[r, col].set_ylabel(label if col == 0 else "")
        seat = [a for a in "zxy" if df[f"pvv_{a}_g"].abs().max() > 0]
        words = dict(z="vertical", x="longitudinal", y="lateral")
        for ax in axes[3:, col]:
            ax.fill_between(df.time_s, 0, 1, where=df.ready & df.out_of_envelope, transform=ax.get_xaxis_transform(),
                            color="0.9", lw=0, label="out of envelope", zorder=0)
        for i, a in enumerate(seat):
            axes[3, col].plot(df.time_s, df[f"pvv_{a}_g"], f"C{i}-", lw=1.4, label=f"{words[a]} ({a})")
            axes[4, col].plot(df.time_s, df[f"shake_{a}_g"], color=f"C{i}", lw=0.15, alpha=0.4)
        axes[3, col].set_ylabel("N/rev PVV, g" if col == 0 else "")
        axes[4, col].set_ylabel("seat shake, g" if col == 0 else "")
        axes[4, col].set_xlabel("simulation time, s")
        axes[0, col].set_title(name)
        if col == 0:
            axes[3, col].legend(fontsize=7, loc="upper left")
        for a in axes[:, col]:
            a.grid(alpha=0.3)
    fig.suptitle("JSBSim AH-1S with the vibration element in the loop (2/rev per seat axis, synthetic training "
                 "campaign)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("config", help="the example's config (experiments/configs/jsbsim-ah1s.toml)")
    ap.add_argument("--docs", action="store_true", help="also write docs/figures/jsbsim_ah1s.png")
    args = ap.parse_args(argv)
    cfg = load_config(args.config, JSBSimFlightConfig)
    if not cfg.flights:
        sys.exit(f"{args.config}: no [flights.NAME] to fly")
    out = Path(cfg.out_dir) / cfg.name
    element, c_library = train_element(cfg, out)
    flights, rows = {}, []
    for name, flight in cfg.flights.items():
        t0 = time.perf_counter()
        df = fly(cfg, flight, element, c_library)
        df.to_parquet(out / f"{name}.parquet", index=False)
        flights[name] = df
        rows.append(summarize(name, df))
        print(f"{name}: {len(df)} frames, {df.time_s.iloc[-1]:.0f} s flown in {time.perf_counter() - t0:.1f} s; "
              f"{out / (name + '.parquet')}")
    table = pd.DataFrame(rows)
    table.to_csv(out / "flights.csv", index=False)
    print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    figure(flights, cfg.flights, out / "flights.png")
    if args.docs:
        figure(flights, cfg.flights, Path("docs/figures/jsbsim_ah1s.png"))
    print(f"summary: {out / 'flights.csv'}; figure: {out / 'flights.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
