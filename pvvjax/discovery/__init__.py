"""Discovery: find where simulation and measurement disagree, name the missing effect, add
it to the model and show the gap shrink (data-contract §3).

1. **Baseline.** Nets of one database, trained k-fold by condition over several seeds
   (`fit_ensemble`) on its peak rows. Every counter is replayed by the nets that held its
   condition out; the input-to-vibration offset is fitted on the held-out windows.
   With `lag_test`, window nets and a lag of learnable τ between them and the measured PVV,
   trained jointly (`_learned`), then ask whether the vibration lags the state more slowly
   than the fast dynamics the offset stands for (`_lag_test`); window nets trained *through*
   lags of several time constants (`delag`) add a confirmed slow lag as the first effect,
   their reference (the best nets without one) the baseline, and every later model trains
   through it.
2. **Localize.** Window residuals (measured − predicted, median over seeds) by maneuver
   kind, flight regime and position inside the maneuvers (`residuals.localize`).
3. **Explain.** The candidate library (`candidates`) and lags of the model's own
   prediction, ranked by forward selection with cross-validation by condition and a
   selection-aware block permutation test (`selection.forward_select`). A chosen knee,
   resonance or time constant is then refined by least squares (optimistix LM).
4. **Add and confirm.** A candidate becomes an extra network input (each condition's
   database row gets the candidate at its peak window, and the nets are retrained with the
   same folds and seeds); a lag becomes a learned first-order lag of the replayed
   prediction (offset and τ refitted); a resonance becomes a gain on the nets' output,
   1 + a·band(rotor speed), with a trained jointly with the nets (`gain_apply`: a structural
   mode magnifies the whole 4P response). The effect is kept only if the held-out RMS of the
   ensemble's prediction (median over seeds) drops by `min_shrink`: a candidate that only re-expresses the static map's
   error floor, or retraining noise, gains nothing once the nets are retrained with it.
   Then the next round, until nothing significant confirms.

The workflow reads the campaign only (never a generator's ground truth).

Its public modules: `candidates` (the candidate library: channels × operators, as window
means like the replay), `effects` (the operators), `selection` (forward selection with a
block-permutation test), `residuals` (where the residual concentrates) and `report`
(discovery.json, report.md, figures). Its private modules, one concept each: `_model` (the nets, the replay windows, the
predictions and metrics), `_fits` (least-squares fits of a lag, a knee or band, the offset),
`_propose` (the candidate matrix, the floor covariates and the selection's proposals),
`_confirm` (add a candidate, retrain, compare by condition, name), `_citest` (cross-fitted
conditional-independence tests with conditions as the units: `gcm_test`, `capacity_test`, `holm`),
`_explain` (`explain`: the candidates named by that test at one level, stepwise), `_results` (the typed
outcome: a trial's `Confirmation`, an `Effect`, a `Round`), `_round` (one round's
tries, each way, judged and one named), `_lag` (the lag test) and `_workflow` (`discover`,
`summary`).
"""

from . import effects
from ._citest import (
    UnitTest,
    capacity_test,
    cross_fit,
    default_learner,
    gcm_test,
    holm,
    regression_tests,
    unit_folds,
)
from ._explain import Explanation, Named, carried_by, explain, neighbour_left
from ._model import Model, delag, fit_ensemble, floor_features, gain_apply, metrics
from ._propose import knn_floor
from ._results import Confirmation, Effect, Round
from ._workflow import Discovery, Residual, discover, selection_gain, summary
from .candidates import Candidate, describe, from_key, library, window_table, window_tables
from .report import write_discovery
from .residuals import localize, residual_windows
from .selection import Selected, forward_select

__all__ = [
    "Candidate",
    "Confirmation",
    "Discovery",
    "Effect",
    "Explanation",
    "Model",
    "Named",
    "Residual",
    "Round",
    "Selected",
    "UnitTest",
    "capacity_test",
    "carried_by",
    "cross_fit",
    "default_learner",
    "delag",
    "describe",
    "discover",
    "explain",
    "effects",
    "fit_ensemble",
    "floor_features",
    "forward_select",
    "from_key",
    "gcm_test",
    "holm",
    "gain_apply",
    "knn_floor",
    "library",
    "localize",
    "metrics",
    "neighbour_left",
    "regression_tests",
    "residual_windows",
    "selection_gain",
    "summary",
    "unit_folds",
    "window_table",
    "window_tables",
    "write_discovery",
]
