"""The probes of a named term (experiments/term_backfit_probe.py, attributable_noise.py): the
benchmark world they rebuild, with other nets per fold and other [train] settings."""

import pytest
from conftest import experiment


def test_a_world_takes_its_nets_and_train_settings_and_refuses_an_unknown_one():
    probe, noise = experiment("term_backfit_probe"), experiment("attributable_noise")
    sc0, plain = probe.world_config("0:pitch-acceleration")
    sc, cfg = probe.world_config("2:pitch-acceleration", 16, noise._settings(["weight_decay=0.1", "optimizer=lm"]))
    assert sc["name"] == "pitch-acceleration" and sc["synth"].seed == sc0["synth"].seed + 2 == 33
    assert cfg.discovery.seeds == 16 and cfg.train.weight_decay == 0.1 and cfg.train.optimizer == "lm"
    assert cfg.train.learning_rate == plain.train.learning_rate  # the rest is the config's
    assert plain.train.weight_decay == 0.0 and plain.train.optimizer == "adam"
    with pytest.raises(SystemExit, match="weight_decai.*did you mean 'weight_decay'"):
        probe.world_config("0:pitch-acceleration", train={"weight_decai": 0.1})
    with pytest.raises(SystemExit, match="--train.optimizer: 'sgd'"):
        probe.world_config("0:pitch-acceleration", train={"optimizer": "sgd"})
