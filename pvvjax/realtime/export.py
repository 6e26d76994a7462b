"""A real-time element for a simulator host, written from trained nets (NumPy only at run time).

`element_spec` gathers what the element needs besides its nets: inputs, window and offset,
the training envelope, and the seat shake's phase and harmonic content measured on the flight
test; `write_element` writes it with the nets' parameter files and the two NumPy modules
(`npnet.py`, `rtelement.py`) that `VibrationElement.load` reads.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from ..analysis.axes import analyze_axes, resolved_harmonics
from ..analysis.harmonics import analyze
from ..data.batch import to_batch
from ..data.campaign import Campaign
from . import element, npnet

__all__ = ["axis_shake", "element_spec", "seat_shake_content", "write_element"]


def seat_shake_content(campaign: Campaign, window_revs: float, harmonic: int | None = None) -> tuple[float, dict]:
    """The flight test's seat shake as the element synthesises it: the phase of the analysed
    harmonic (rad, amplitude-weighted over every valid window), and the 1P, 2P and 2N/rev
    content beside it (those that are not N/rev itself) as {k: [median amplitude ratio to the
    analysed harmonic, weighted phase]}.

    Args:
        campaign: the flight test. window_revs: analysis window, revolutions.
        harmonic: the analysed harmonic N (default: the aircraft's blade count).
    """
    harmonic = harmonic or campaign.aircraft.blades
    batch = to_batch(campaign, [])
    wn = analyze(batch, window_revs, harmonic=harmonic)
    valid = np.asarray(wn.valid)
    an = np.asarray(wn.amplitude)[valid]
    phase = float(np.angle(np.sum(an * np.exp(1j * np.asarray(wn.phase)[valid]))))
    content = {}
    for k in sorted({1, 2, 2 * harmonic} - {harmonic}):  # a 2-bladed rotor's 2P is its N/rev
        wk = analyze(batch, window_revs, harmonic=k)
        ak, pk = np.asarray(wk.amplitude)[valid], np.asarray(wk.phase)[valid]
        content[k] = [float(np.median(ak / an)), float(np.angle(np.sum(ak * np.exp(1j * pk))))]
    return phase, content


def axis_shake(campaign: Campaign, outputs, window_revs: float) -> list[dict]:
    """Each axis's seat shake as the element synthesises it (`VibrationElement(shake=...)`),
    from one windowed pass over the flight test (`analysis.analyze_axes`): its N/rev phase
    (rad, amplitude-weighted over every valid window), its 1/rev of rotor track and balance
    (median amplitude, g, and weighted phase: constant, as track and balance is), and its
    2N/rev as a median ratio to the N/rev with its weighted phase, where the sampling
    resolves it.

    Args:
        campaign: the flight test. outputs: the axes, e.g. ("az_g", "ax_g", "ay_g").
        window_revs: analysis window, revolutions.
    """
    n = campaign.aircraft.blades
    batch = to_batch(campaign, [], axis=tuple(outputs))
    ks = resolved_harmonics(batch, sorted({1, n, 2 * n}), window_revs)
    win = analyze_axes(batch, ks, window_revs)
    valid = np.asarray(win.valid)
    amp, ph = np.asarray(win.amplitude), np.asarray(win.phase)  # (B, A, H, W)
    weighted = lambda a, p: float(np.angle(np.sum(a * np.exp(1j * p))))  # noqa: E731
    out = []
    for i in range(len(outputs)):
        at = {k: (amp[:, i, h][valid], ph[:, i, h][valid]) for h, k in enumerate(ks)}
        an = at[n][0]
        s = dict(phase_rad=weighted(*at[n]), harmonics={})
        if 1 in at and n != 1:
            s.update(once_g=float(np.median(at[1][0])), once_phase_rad=weighted(*at[1]))
        if 2 * n in at:
            s["harmonics"][2 * n] = [float(np.median(at[2 * n][0] / an)), weighted(*at[2 * n])]
        out.append(s)
    return out


def element_spec(nets: list[str], inputs: list[str], envelope: tuple, campaign: Campaign, analysis_window_revs: float,
                 *, window_revs: float, hop_revs: float, offset_s: float, stick_offset_s: float,
                 outputs=None) -> dict:
    """The element's settings (`element.json`).

    Args:
        nets: parameter file names, beside element.json; the element predicts their median.
        inputs: the database's inputs, in the nets' order. envelope: (lo, hi) of the training
            inputs, each (n_inputs,): frames outside are flagged.
        campaign: the flight test the nets were trained on (seat-shake content, rotor).
        analysis_window_revs: the window of the campaign's harmonic analysis, revolutions.
        window_revs, hop_revs: the element's input window and update interval, revolutions.
        offset_s: input-to-vibration offset, s. stick_offset_s: extra offset of the sticks, s.
        outputs: the axes the nets' outputs predict (e.g. az_g, ax_g, ay_g), each with its
            shake measured by `axis_shake`; None: one output, the vertical, its phase and
            harmonic content from `seat_shake_content`.
    """
    if outputs is None:
        phase, content = seat_shake_content(campaign, analysis_window_revs)
        shake = dict(phase_rad=phase, harmonics=content)
    else:
        shake = dict(outputs=list(outputs), shake=axis_shake(campaign, outputs, analysis_window_revs))
    lo, hi = envelope
    return dict(nets=list(nets), inputs=list(inputs), window_revs=window_revs, hop_revs=hop_revs, offset_s=offset_s,
                stick_offset_s=stick_offset_s, **shake,
                envelope=dict(lo=[float(v) for v in lo], hi=[float(v) for v in hi]),
                aircraft=dict(rotor_radius_ft=campaign.aircraft.rotor_radius_ft, g_ft_s2=campaign.aircraft.g_ft_s2,
                              blades=campaign.aircraft.blades, nominal_rpm=campaign.aircraft.nominal_rpm))


def write_element(out, nets: list, spec: dict) -> Path:
    """Write an element folder: the nets' parameter files under `spec["nets"]`' names
    (`nets`: one (parameters, metadata) pair each), element.json, and the NumPy modules it
    runs on. Returns the folder."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for (params, meta), name in zip(nets, spec["nets"]):
        npnet.write_npz(out / name, params, meta)
    (out / "element.json").write_text(json.dumps(spec, indent=2))
    shutil.copy(npnet.__file__, out / "npnet.py")
    shutil.copy(element.__file__, out / "rtelement.py")
    return out
