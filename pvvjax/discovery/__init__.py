"""Discovery: find where simulation and measurement disagree, name the missing effect,
add it to the model and show the gap shrink (data-contract §3).

1. **Baseline.** Nets of one database, trained k-fold by condition over several seeds
   (`fit_ensemble`) on its peak rows. Every counter is replayed by the nets that held its
   condition out; the input-to-vibration offset is fitted on the held-out windows.
2. **Localize.** Window residuals (measured − predicted, median over seeds) by maneuver
   kind, flight regime and position inside the maneuvers (`residuals.localize`).
3. **Explain, by one calibrated test, three kinds in turn** (`misfits`, then `explain`).
   Where the held-out residual is predictable from the model's inputs and their physical
   composites at all (`capacity_test`), the **misfit** is named first by the static forms of
   the inputs that carry it (knees, bands, products; forward selection, Holm in each round),
   and its out-of-fold fit is taken off the residual. Then the forms of the inputs'
   **history** (rates, spreads inside the window, lags of the corrected prediction: a
   response, or the window-averaging, that the baseline lacks) are tested beyond the
   inputs' window values, and last every other candidate (`candidates`: channels,
   magnitudes, rates, spreads, knees, bands, products) is tested as **missing** beyond both.
   Each test partials the residual and the candidate out of what is held fixed by the best,
   out of fold, of the mean, an additive spline and trees (`partial_out`, whose skill is
   reported), a t over conditions (the independent units), Holm's first step over the
   round's candidates at `discovery.level`. The best that passes is named, the rest tested
   again given it, until nothing passes; candidates the data cannot tell from it are named
   with it (`tied`).
4. **Fit and add.** A named knee, band or lag gets its parameters by least squares
   (optimistix Levenberg–Marquardt, from where the test named them), and their intervals over a bootstrap
   of conditions. The named effects join the model at once: the misfit's forms as a linear
   term on its prediction, fitted out of fold by condition (more inputs of the same channels
   would only be refitted by the nets); a missing channel or knee as a network input, a band
   as a learned gain on the nets' output, a lag as a first-order lag of the replayed
   prediction, with the model retrained once at the baseline's offset. Before and after are
   held out by condition.

The workflow reads the campaign only (never a generator's ground truth).

Its public modules: `candidates` (the candidate library: channels × operators, as window
means like the replay), `effects` (the operators), `residuals` (where the residual
concentrates) and `report` (discovery.json, report.md, figures). Its private modules, one
concept each: `_model` (the nets, the replay windows, the predictions and metrics),
`_train` (a model's nets trained on the peaks), `_fits` (least-squares fits of a lag, a knee
or band, the offset), `_citest` (cross-fitted conditional-independence tests with
conditions as the units: `gcm_test`, `capacity_test`, `holm`), `_nuisance` (the test's
nuisance regressions: the inputs' composites and history, `partial_out`), `_explain`
(`misfits`, `explain`: the candidates named by that test at one level, stepwise), `_tested` (the discovery's test, fits
and the model with the named effects), `_results` (the typed outcome: an `Effect`, a
`Round`) and `_workflow` (`discover`, `summary`).
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
from ._explain import (
    Explanation,
    Named,
    carried_by,
    explain,
    misfits,
    of_history,
    out_of_fold_linear,
    shadow,
    static_inputs,
)
from ._model import Model, fit_ensemble, floor_features, gain_apply, metrics
from ._nuisance import Partialled, composites, input_history, partial_out
from ._results import Effect, Round
from ._tested import bootstrap_weights
from ._workflow import Discovery, discover, summary
from .candidates import Candidate, channels_lacking, describe, from_key, library, window_table, window_tables
from .report import write_discovery
from .residuals import localize, residual_windows

__all__ = [
    "Candidate",
    "Discovery",
    "Effect",
    "Explanation",
    "Model",
    "Named",
    "Round",
    "UnitTest",
    "capacity_test",
    "carried_by",
    "cross_fit",
    "default_learner",
    "bootstrap_weights",
    "channels_lacking",
    "describe",
    "discover",
    "explain",
    "misfits",
    "effects",
    "fit_ensemble",
    "floor_features",
    "from_key",
    "gcm_test",
    "holm",
    "gain_apply",
    "library",
    "localize",
    "metrics",
    "of_history",
    "out_of_fold_linear",
    "partial_out",
    "Partialled",
    "composites",
    "input_history",
    "shadow",
    "static_inputs",
    "regression_tests",
    "residual_windows",
    "summary",
    "unit_folds",
    "window_table",
    "window_tables",
    "write_discovery",
]
