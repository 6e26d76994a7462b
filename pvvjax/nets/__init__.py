"""The paper's networks as pure functions, their training and the sweeps over them.

`networks` initialises and applies MLP and RBF nets (padded to share one program);
`train` fits them full-batch; `batched` trains many in one on-device loop; `sweep` trains
databases × architectures × seeds × folds, resumable; `evaluation` scores held-out
predictions (Table 1, Figs 10-12).
"""

from .batched import predict_many, stack_trees, train_nets
from .evaluation import BAND_G, attach_measured, heldout_predictions, search_architecture, table1
from .networks import (
    apply_for,
    architecture_name,
    mlp_apply,
    mlp_init,
    mlp_pad,
    n_weights,
    rbf_apply,
    rbf_fit,
    scaling,
)
from .sweep import (
    N_INPUTS,
    SWEEP_AXES,
    collect,
    databases_fingerprint,
    heldout_models,
    load_nets,
    load_params,
    net_table,
    run_sweep,
    save_params,
    stack_data,
    sweep_settings,
)
from .train import (
    TRAINABLE,
    Data,
    Fit,
    TrainingError,
    TrainState,
    condition_folds,
    descend,
    done,
    fit,
    init_state,
    make_data,
    masked_metrics,
    result,
    run,
    split_masks,
)

__all__ = [
    "BAND_G",
    "Data",
    "Fit",
    "N_INPUTS",
    "SWEEP_AXES",
    "TRAINABLE",
    "TrainState",
    "TrainingError",
    "apply_for",
    "architecture_name",
    "attach_measured",
    "collect",
    "databases_fingerprint",
    "condition_folds",
    "descend",
    "done",
    "fit",
    "heldout_models",
    "heldout_predictions",
    "init_state",
    "load_nets",
    "load_params",
    "make_data",
    "masked_metrics",
    "mlp_apply",
    "mlp_init",
    "mlp_pad",
    "n_weights",
    "net_table",
    "predict_many",
    "rbf_apply",
    "rbf_fit",
    "result",
    "run",
    "run_sweep",
    "save_params",
    "scaling",
    "search_architecture",
    "split_masks",
    "stack_data",
    "stack_trees",
    "sweep_settings",
    "table1",
    "train_nets",
]
