"""Re-measuring a finished discovery with another ensemble (experiments/attributable_ensemble.py):
its models rebuilt from the folder `write_discovery` leaves reproduce the discovery's own
before and after, so that more nets per fold change only the training noise."""

import numpy as np
import pytest
from conftest import experiment


@pytest.fixture(scope="module")
def ae():
    return experiment("attributable_ensemble")


@pytest.mark.parametrize("augment, term_refit", [("additive", "peaks"), ("input", "peaks"), ("additive", "named")])
def test_a_rebuilt_discovery_reproduces_its_before_and_after(ae, monkeypatch, tmp_path, small_campaign_dir, augment,
                                                             term_refit):
    from pvvjax.config import DiscoveryConfig, ExperimentConfig, TrainConfig
    from pvvjax.data.campaign import load_campaign
    from pvvjax.discovery import _round, _workflow, discover
    from pvvjax.discovery.report import write_discovery
    from pvvjax.discovery.selection import Selected

    def propose(win, yhat, resid, M, rows, own, floor, d, seed, complexity, keys, is_floor):
        j = next(i for i, k in enumerate(keys) if k.startswith("abs_rate:pitch_rate_dps") and not is_floor[i])
        return [("all", j, Selected(j, 0.1, 0.1, 0.001))], [], {"all": (rows, floor)}

    monkeypatch.setattr(_workflow, "_propose", propose)  # one effect named, the rest the workflow's own
    confirm = _round._confirm
    monkeypatch.setattr(_round, "_confirm", lambda *a, **k: (True, confirm(*a, **k)[1]))
    campaign = load_campaign(small_campaign_dir)
    d = DiscoveryConfig(seeds=2, folds=3, max_effects=1, augment=augment, offset_step_s=0.5, term_refit=term_refit,
                        train_stride=16)
    cfg = ExperimentConfig(train=TrainConfig(max_steps=100), discovery=d)
    res = discover(campaign, cfg, log=lambda m: None)
    assert [e["operator"] for e in res.effects] == ["abs_rate"] and res.after != res.before
    write_discovery(res, tmp_path, cfg)
    (row,) = ae.chosen_rounds(tmp_path).itertuples()  # the named try, its parameters at full precision
    named, got = dict(res.effects[0]["candidate"].parameters), dict(ae.named_candidate(row).parameters)
    if term_refit == "named":  # the row is the try's (its coefficient fitted on the peak nets)
        assert ae.window_refit(row) == "windows" and row.window_refit_coefficient == named.pop("coefficient")
        assert got.pop("coefficient") != row.window_refit_coefficient
    else:
        assert ae.window_refit(row) == ""
    assert got == named

    starts = {}
    ctx, base, after, _ = ae.rebuild(campaign, cfg, tmp_path, log=lambda m: None,
                                     each=lambda rnd, model: starts.setdefault(rnd, model))
    assert after.extra if augment == "input" else after.terms
    assert list(starts) == [1, 2] and starts[1] is base and starts[2] is after  # each round's start
    for model, want in ((base, res.before), (after, res.after)):
        got = ae.measure(ctx, model)
        for k in ("ensemble_rms_g", "rms_g", "peak_error_g"):
            assert got[k] == pytest.approx(want[k], rel=1e-9), k
    assert np.isnan(ae.measure(ctx, base)["region_g"])  # no kinds given
    if term_refit == "named":
        return
    # `--augment`: the named effect added the other way of its proposal, from the same baseline
    from pvvjax.discovery._confirm import _augment

    other = "input" if augment == "additive" else "additive"
    _, base2, swapped, _ = ae.rebuild(campaign, cfg, tmp_path, log=lambda m: None, way=other)
    assert bool(swapped.terms) == (other == "additive") and bool(swapped.extra) == (other == "input")
    c = swapped.terms[-1][0] if other == "additive" else swapped.extra[-1]
    assert c.parameters == {k: v for k, v in named.items() if k != "coefficient"}  # the proposal, unfitted
    assert ae.measure(ctx, base2) == ae.measure(ctx, base)  # the same before
    assert ae.measure(ctx, swapped) == ae.measure(ctx, _augment(ctx, base, c, other))
    assert ae.table_name(4, 8, "input") == "attributable_nets4_draws8_input.csv"
    if augment == "additive":  # `--refit windows`: the named term refitted on window nets
        _, _, refitted, _ = ae.rebuild(campaign, cfg, tmp_path, log=lambda m: None, refit="windows")
        term = refitted.terms[-1][0]
        assert ae.measure(ctx, refitted) == ae.measure(ctx, _augment(ctx, base, term, "additive", refit="windows"))
        assert ae.measure(ctx, refitted) != ae.measure(ctx, after)
        assert ae.table_name(4, 8, refit="windows") == "attributable_nets4_draws8_refit-windows.csv"


def test_a_second_run_replaces_its_scenarios_rows_and_keeps_the_others(ae, tmp_path):
    import pandas as pd

    path = tmp_path / "attributable_nets16.csv"
    ae._save(pd.DataFrame(dict(scenario=["roll-rate", "sideslip"], attributable=[0.8, 0.9])), path)
    ae._save(pd.DataFrame(dict(scenario=["long-lag", "sideslip"], attributable=[1.1, 0.7])), path)
    got = pd.read_csv(path).set_index("scenario").attributable.to_dict()
    assert got == {"roll-rate": 0.8, "long-lag": 1.1, "sideslip": 0.7}


def test_a_folder_run_with_other_training_settings_is_refused_but_not_one_before_a_choice_setting(ae):
    from pvvjax._strict import to_dict
    from pvvjax.config import DiscoveryConfig

    now = DiscoveryConfig(folds=5, resonance_input=True, term_refit="named")
    then = {k: v for k, v in to_dict(now).items() if k not in ("resonance_input", "tie_share")}
    assert ae._other_settings({"discovery": then}, now) == {}  # added since, at its default or choice-only
    assert ae._other_settings({"discovery": {**then, "folds": 3}}, now) == {"folds": (3, 5)}
    assert set(ae._other_settings({"discovery": then}, DiscoveryConfig(folds=5, tie_share=0.25))) == {"tie_share"}
    # "named" rebuilds as "peaks" save where rounds.csv says the window refit was kept; not "windows"
    assert ae._other_settings({"discovery": {**then, "term_refit": "peaks"}}, now) == {}
    assert ae._other_settings({"discovery": {**then, "term_refit": "windows"}}, now) == {
        "term_refit": ("windows", "named")}


def test_a_world_over_training_draws_is_the_shrink_of_the_mean_before_after_and_null(ae):
    def m(g, e):
        return dict(peak_error_g=g, ensemble_rms_g=e)

    draws = [(m(0.050, 0.040), m(0.044, 0.036), m(0.040, 0.035)),  # closes 0.6 of its gap
             (m(0.046, 0.042), m(0.044, 0.040), m(0.042, 0.036)),  # 0.5
             (m(0.048, 0.044), m(0.043, 0.039), m(0.038, 0.037))]  # 0.5
    got = ae.over_draws(draws, "peak_error_g", named=True)
    assert (got["before"], got["after"], got["null"]) == pytest.approx((0.048, 0.04367, 0.040), abs=1e-5)
    assert got["attributable"] == pytest.approx((0.048 - 0.131 / 3) / (0.048 - 0.040))  # not the mean of 0.6, 0.5, 0.5
    assert got["attributable_draws"] == "0.600;0.500;0.500"
    gaps = np.array([0.010, 0.004, 0.010])
    assert got["gap_g"] == pytest.approx(gaps.mean())
    assert got["gap_se_g"] == pytest.approx(gaps.std(ddof=1) / np.sqrt(3))
    assert got["gap_z"] == pytest.approx(gaps.mean() / got["gap_se_g"])
    assert got["attributable_ensemble"] == pytest.approx((0.042 - 0.115 / 3) / (0.042 - 0.036))
    assert got["before_draws"] == "0.05;0.046;0.048" and got["null_draws"] == "0.04;0.042;0.038"
    assert 0.5 <= got["attributable_lo"] <= got["attributable"] <= got["attributable_hi"] <= 0.6  # within the draws'
    # a fourth draw whose null is far above its before: most resamples have no gap
    shaky = ae.over_draws([*draws, (m(0.03, 0.04), m(0.03, 0.04), m(0.06, 0.04))], "peak_error_g", named=True)
    assert np.isnan(shaky["attributable_lo"]) and shaky["attributable_hi"] >= 0.5
    nothing = ae.over_draws(draws, "peak_error_g", named=False)  # nothing named closes nothing
    assert nothing["attributable"] == nothing["attributable_ensemble"] == nothing["attributable_hi"] == 0.0
    assert nothing["gap_g"] == got["gap_g"]
    one = ae.over_draws(draws[:1], "peak_error_g", named=True)  # one draw: the table's own measure, no spread
    assert one["attributable"] == pytest.approx(0.6) and np.isnan(one["gap_se_g"]) and np.isnan(one["gap_z"])
    assert np.isnan(one["attributable_lo"]) and np.isnan(one["attributable_hi"])


def test_a_training_draw_shifts_the_training_seed_only(ae):
    from pvvjax.config import DiscoveryConfig, ExperimentConfig

    cfg = ExperimentConfig(seed=3, discovery=DiscoveryConfig(seeds=4, split_seed=7))
    assert ae._draw_config(cfg, 4, 0) == cfg  # draw 0: the discovery's own training
    two = ae._draw_config(cfg, 16, 2)
    assert two.seed == 2003 and two.discovery.seeds == 16 and two.discovery.split_seed == 7  # the same folds
    assert ae.table_name(16) == "attributable_nets16.csv" and ae.table_name(4, 4) == "attributable_nets4_draws4.csv"
