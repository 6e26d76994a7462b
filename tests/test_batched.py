"""The on-device trainer: many nets in one loop, equal to the per-net reference, and the
same bits whatever the batch layout (alone, grouped, compacted, checkpointed)."""

import dataclasses

import jax
import numpy as np
import pytest
from conftest import Lowerings

from pvvjax.config import TrainConfig
from pvvjax.nets import fit, hyper, make_data, mlp_init, stack_trees, train_nets

CFG = TrainConfig(learning_rate=1e-2, max_steps=600, eval_every=20, patience=3)


@pytest.fixture(scope="module")
def problem():
    """Three groups (datasets) and 48 nets of several widths, which stop at different steps."""
    def data(seed):
        rng = np.random.default_rng(seed)
        x = rng.normal(size=(90, 8)).astype(np.float32)
        y = np.tanh(x[:, 0] + x[:, 1] * x[:, 2]).astype(np.float32)
        w = (np.arange(90) % 5 > 0).astype(np.float32)
        return make_data(x, y, w, 1.0 - w)

    datasets = [data(s) for s in range(3)]
    nets = [mlp_init(jax.random.key(i), 8, (2 + i % 5, 3), max_hidden=(8, 4)) for i in range(48)]
    group = np.arange(48) % 3
    return datasets, nets, group


def _equal(a, b):
    for u, v in zip(jax.tree.leaves(a), jax.tree.leaves(b)):
        np.testing.assert_array_equal(u, v)


def _train(problem, idx, **kw):
    datasets, nets, group = problem
    groups = sorted(set(group[idx]))
    gid = np.array([groups.index(g) for g in group[idx]])
    return train_nets(stack_trees([nets[i] for i in idx]), stack_trees([datasets[g] for g in groups]), gid, CFG, **kw)


@pytest.fixture(scope="module")
def everything(problem):
    return _train(problem, np.arange(48), compact=False)


def test_nets_stop_at_different_steps_and_match_the_per_net_reference(problem, everything):
    datasets, nets, group = problem
    assert len(set(everything.steps.tolist())) > 3  # early stopping per net, on the device
    one = jax.jit(fit, static_argnums=2)
    for i in (0, 5, 13, 22):
        ref = one(nets[i], datasets[group[i]], CFG)
        assert int(ref.steps) == everything.steps[i] and int(ref.best_step) == everything.best_step[i]
        # an unbatched net compiles to other arithmetic: equal to float32 rounding
        for u, v in zip(jax.tree.leaves(ref.params), jax.tree.leaves(jax.tree.map(lambda a: a[i], everything.params))):
            np.testing.assert_allclose(v, u, rtol=0, atol=2e-5)


@pytest.mark.parametrize("layout", ["alone", "subset", "reversed", "compacted", "checkpointed"])
def test_a_net_trains_to_the_same_bits_whatever_the_batch_layout(problem, everything, layout, monkeypatch):
    from pvvjax.nets import batched

    widths, program = [], batched._program

    def recorded(state, *args, **kw):
        widths.append(jax.tree.leaves(state)[0].shape[1])
        return program(state, *args, **kw)

    monkeypatch.setattr(batched, "_program", recorded)
    if layout == "alone":
        for i in (4, 17):
            _equal(_train(problem, np.array([i])), jax.tree.map(lambda a: a[i : i + 1], everything))
        return
    idx = {"subset": np.array([1, 2, 4, 9, 11, 20, 23, 30, 47]), "reversed": np.arange(48)[::-1]}
    idx = idx.get(layout, np.arange(48))
    kw = dict(compact=True, chunk_evals=1) if layout == "compacted" else {}
    if layout == "checkpointed":
        kw = dict(compact=True, chunk_evals=1, checkpoint_s=1e-9)
    got = _train(problem, idx, **kw)
    _equal(got, jax.tree.map(lambda a: a[idx], everything))
    if layout == "compacted":
        assert set(widths) == {16, 8}  # 16 nets per group, narrowed to 8 (the first width's floor)


def test_on_done_reports_every_net_once_with_its_fit(problem, everything):
    seen = []
    _train(problem, np.arange(48), compact=True, chunk_evals=1, checkpoint_s=1e-9,
           on_done=lambda idx, fits, seconds: seen.append((idx, fits, seconds)))
    assert len(seen) > 1  # a checkpoint every segment
    ids = np.concatenate([i for i, _, _ in seen])
    assert sorted(ids.tolist()) == list(range(48))
    for idx, fits, seconds in seen:
        assert (seconds > 0).all()
        _equal(fits, jax.tree.map(lambda a: a[idx], everything))


def _hyper(n, **settings):
    return jax.tree.map(lambda a: np.full(n, a), hyper(dataclasses.replace(CFG, **settings)))


def test_training_settings_are_data_four_learning_rates_or_two_patiences_compile_once(problem, everything):
    idx = np.arange(12)
    _train(problem, idx)  # compiles the trainer for this layout
    with Lowerings() as lowered:
        fits = [_train(problem, idx, hyper=_hyper(12, learning_rate=lr)) for lr in (3e-3, 1e-2, 3e-2, 1e-1)]
        fits += [_train(problem, idx, hyper=_hyper(12, patience=p)) for p in (1, 6)]
        fits += [_train(problem, idx, hyper=_hyper(12, max_steps=200, divergence_factor=10.0, weight_decay=1e-3))]
    assert lowered["_segment"] == 0 and lowered["_init"] == 0, dict(lowered)
    _equal(fits[1], jax.tree.map(lambda a: a[idx], everything))  # lr 1e-2 as data: the bits of lr 1e-2 compiled in
    assert len({float(f.best_val_rms.sum()) for f in fits[:4]}) == 4  # every rate trained its own nets
    assert fits[4].steps.max() < fits[5].steps.max()  # patience 1 stops before patience 6
    assert fits[6].steps.max() <= 200


def test_nets_of_several_learning_rates_train_in_one_batch_as_each_alone(problem):
    """A per-net learning rate in the batch gives each net the bits it gets in a batch of its rate."""
    idx = np.arange(12)
    rates = np.tile(np.float32([3e-3, 3e-2]), 6)
    mixed = _train(problem, idx, hyper=_hyper(12)._replace(learning_rate=rates))
    for lr in (3e-3, 3e-2):
        sel = idx[rates == np.float32(lr)]
        alone = _train(problem, sel, hyper=_hyper(len(sel), learning_rate=lr))
        _equal(alone, jax.tree.map(lambda a: a[sel], mixed))


@pytest.mark.parametrize("n", [1, 5, 8, 137])
def test_row_sums_and_affine_layers_match_numpy(n):
    from pvvjax.nets._sums import affine, pairwise_sum

    rng = np.random.default_rng(n)
    v = rng.normal(size=(3, n, 4)).astype(np.float32)
    for axis in (0, 1, -1):
        np.testing.assert_allclose(pairwise_sum(v, axis), v.astype(np.float64).sum(axis), rtol=1e-5, atol=1e-5)
    w, b = rng.normal(size=(4, 2)).astype(np.float32), rng.normal(size=2).astype(np.float32)
    np.testing.assert_allclose(affine(v, w, b), v.astype(np.float64) @ w + b, rtol=1e-5, atol=1e-5)
    grads = jax.grad(lambda b: affine(v, w, b).sum())(b)  # the bias gradient counts every row
    np.testing.assert_allclose(grads, np.full(2, 3 * n), rtol=1e-6)
