"""Vibration through time: window sequences of every record (`window_sequences`), the
dynamic part of a PVV model (a delay and a unit-gain second-order response) as pure,
jit-able and differentiable functions of them, the physics-shaped model (a static map
followed by them) and a recurrent one, trained by `nets.train.fit` like a static net,
compared with the quasi-static map on the same held-out windows (`compare`, `study`) and
scored as a simulator is qualified (`scores`: FAA Part 60 test 3.f.1)."""

from .compare import (
    Split,
    Trained,
    condition_split,
    fit_peak_map,
    fit_sequence_model,
    heldout,
    kind_split,
)
from .models import Recurrent, Response, dynamic_apply, dynamic_init, identified, rnn_apply, rnn_init
from .response import delayed, second_order
from .scores import FAA_RATIO, faa_pass, heldout_scores, nominal_cruise, rms_by_kind, row_peaks
from .sequences import Sequences, window_sequences
from .study import EXPORTABLE, run_comparison

__all__ = ["EXPORTABLE", "FAA_RATIO", "Recurrent", "Response", "Sequences", "Split", "Trained", "condition_split",
           "delayed", "dynamic_apply", "dynamic_init", "faa_pass", "fit_peak_map", "fit_sequence_model",
           "heldout", "heldout_scores", "identified", "kind_split", "nominal_cruise",
           "rms_by_kind", "rnn_apply", "rnn_init", "row_peaks", "run_comparison", "second_order", "window_sequences"]
