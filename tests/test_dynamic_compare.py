"""The comparison of PVV models through time (pvvjax.dynamics.compare, scores, study and
`pvvjax dynamic`): the FAA 3.f.1 test and the trend against hand-worked and brute-force
references, the batched training against one net trained alone, every condition held out
once, and the command's outputs, resumption and refusals."""

import itertools
import json

import jax
import numpy as np
import pandas as pd
import pytest

from pvvjax.config import TrainConfig
from pvvjax.dynamics import compare
from pvvjax.dynamics import scores as scores_module


def test_faa_tolerance_is_plus_3_minus_6_db_or_a_tenth_of_the_cruise_level():
    measured = np.array([0.1, 0.1, 0.1, 0.1, 0.02, 0.02])
    pred = np.array([0.14125, 0.1413, 0.0502, 0.0500, 0.029, 0.031])  # exact dB: 1.41254 and 0.50119
    assert scores_module.faa_pass(pred, measured, nominal_g=0.1).tolist() == [True, False, True, False, True, False]
    assert scores_module.FAA_RATIO == pytest.approx((0.501187, 1.412538), rel=1e-5)


def test_rms_by_kind_is_each_kinds_windows_alone():
    """Each kind's RMS over its own rows' real windows, against a loop over the windows; a
    row of NaN prediction is left out, and a kind left with no window is NaN."""
    rng = np.random.default_rng(4)
    measured = rng.uniform(0.05, 0.2, (6, 20))
    pred = measured + rng.normal(0, 0.02, (6, 20))
    mask = np.arange(20)[None, :] < np.array([20, 5, 12, 20, 9, 3])[:, None]
    kinds = ["level", "pullup", "level", "roll", "pullup", "turn"]
    pred[3] = np.nan
    got = scores_module.rms_by_kind(pred, measured, mask, kinds)
    assert list(got) == ["level", "pullup", "roll", "turn"] and np.isnan(got["roll"])
    for kind in ("level", "pullup", "turn"):
        err = [pred[r, w] - measured[r, w] for r in range(6) for w in range(20) if kinds[r] == kind and mask[r, w]]
        assert got[kind] == pytest.approx(np.sqrt(np.mean(np.square(err))))


def test_kendall_tau_and_peaks_against_brute_force():
    rng = np.random.default_rng(3)
    time = np.cumsum(rng.uniform(0.2, 0.3, (12, 30)), axis=1)
    measured = rng.uniform(0.05, 0.2, (12, 30))
    pred = measured + rng.normal(0, 0.02, (12, 30))
    mask = np.arange(30)[None, :] < rng.integers(10, 31, 12)[:, None]
    kinds = ["pullup"] * 6 + ["level"] * 6
    got = scores_module.heldout_scores(pred, measured, mask, time, kinds, ("pullup",), nominal_g=0.1)
    pp = np.array([pred[r, mask[r]].max() for r in range(12)])
    pm = np.array([measured[r, mask[r]].max() for r in range(12)])
    pairs = list(itertools.combinations(range(12), 2))
    concordant = sum(np.sign(pp[i] - pp[j]) * np.sign(pm[i] - pm[j]) for i, j in pairs)
    assert got["kendall_tau"] == pytest.approx(concordant / len(pairs))  # no ties: tau-a = tau-b
    assert got["rms_g"] == pytest.approx(np.sqrt(np.mean((pred - measured)[mask] ** 2)))
    tp = np.array([time[r, np.argmax(np.where(mask[r], pred[r], -1))] for r in range(6)])
    tm = np.array([time[r, np.argmax(np.where(mask[r], measured[r], -1))] for r in range(6)])
    assert got["time_of_peak_err_median_s"] == pytest.approx(np.median(np.abs(tp - tm)))
    assert got["peak_err_rms_g"] == pytest.approx(np.sqrt(np.mean((pp - pm) ** 2)))
    with pytest.raises(ValueError, match="no level flight with an advance ratio in"):
        scores_module.nominal_cruise(pm, ["turn"] * 12, np.full(12, 0.3), (0.25, 0.35))
    assert scores_module.nominal_cruise(pm, ["level"] * 12, np.linspace(0, 0.4, 12), (0.25, 0.35)) == pytest.approx(
        np.median(pm[(np.linspace(0, 0.4, 12) >= 0.25) & (np.linspace(0, 0.4, 12) <= 0.35)]))


def test_splits_hold_every_condition_out_once_and_every_kind_once():
    conditions = np.array([f"c{i}" for i in range(20)])
    kinds = np.array(["level", "pullup", "turn", "roll"] * 5)
    cs = compare.condition_split(conditions, 5, 0)
    assert (cs.test.sum(axis=0) == 1).all() and not (cs.test & cs.val).any()
    ks = compare.kind_split(conditions, kinds, 5, 0)
    assert ks.labels == ("level", "pullup", "roll", "turn") and (ks.test.sum(axis=0) == 1).all()
    assert not (ks.test & ks.val).any() and ks.val.any(axis=1).all()
    pred = np.arange(5 * 2 * 20 * 3, dtype=float).reshape(5, 2, 20, 3)
    held = compare.heldout(pred, cs)
    fold = np.argmax(cs.test, axis=0)
    np.testing.assert_array_equal(held, pred.mean(axis=1)[fold, np.arange(20)])


def test_batched_training_equals_each_net_trained_alone():
    """`fit_sequence_model` trains (fold, seed) nets on padded row selections in one vmapped
    program; each must equal `nets.train.fit` on its fold's rows alone."""
    from pvvjax.nets import train
    from pvvjax.nets.networks import mlp_apply, mlp_init, scaling

    rng = np.random.default_rng(0)
    x = rng.normal(size=(15, 8, 2)).astype(np.float32)
    y = (0.1 + 0.03 * np.tanh(x[..., 0]) - 0.01 * x[..., 1]).astype(np.float32)
    mask = np.arange(8)[None, :] < rng.integers(3, 9, 15)[:, None]
    split = compare.condition_split([f"c{i // 1}" for i in range(15)], 3, 1)
    cfg = TrainConfig(max_steps=150, eval_every=25, patience=100)
    init = compare.static_init(2, (4,))
    got = compare.fit_sequence_model(init, mlp_apply, x, y, mask, split, 2, cfg)
    for f, s in [(0, 0), (2, 1)]:
        rows = ~split.test[f] & ~split.val[f]
        sc = scaling(x[rows][mask[rows]], y[rows][mask[rows]])
        p0 = mlp_init(jax.random.key(s), 2, (4,), scale=sc)
        w, wv = (mask * rows[:, None]).astype(np.float32), (mask * split.val[f][:, None]).astype(np.float32)
        alone = jax.jit(lambda p, d: train.fit(p, d, cfg))(p0, train.Data(x, y, w, x, y, wv))
        np.testing.assert_allclose(got.pred[f, s], np.asarray(mlp_apply(alone.params, x)), atol=2e-5)
        assert got.best_step[f, s] == int(alone.best_step)


def test_training_in_chunks_that_drop_stopped_nets_and_on_real_windows_alone_gives_the_same_nets():
    """The chunked training (progress between chunks; stopped nets leave the batch) and the
    pointwise rows of a static map (its real windows, no padding) train the same nets as
    one uninterrupted batch over padded records."""
    from pvvjax.nets.networks import mlp_apply

    rng = np.random.default_rng(0)
    x = rng.standard_normal((15, 30, 3)).astype(np.float32)
    y = (0.2 + 0.1 * np.tanh(x[..., 0]) + 0.02 * rng.standard_normal((15, 30))).astype(np.float32)
    mask = np.ones((15, 30), bool)
    mask[3, 20:] = mask[8, 4:] = False
    split = compare.condition_split([f"c{i}" for i in range(15)], 5, 0)
    cfg = TrainConfig(max_steps=3000, eval_every=10, patience=3, learning_rate=0.01)
    init = compare.static_init(3, (4,))
    seen = []
    chunked = compare.fit_sequence_model(init, mlp_apply, x, y, mask, split, 3, cfg, chunk_evals=1,
                                         progress=lambda *a: seen.append(a))
    whole = compare.fit_sequence_model(init, mlp_apply, x, y, mask, split, 3, cfg, chunk_evals=10**6)
    windows = compare.fit_sequence_model(init, mlp_apply, x, y, mask, split, 3, cfg, pointwise=True)
    assert len(set(whole.best_step.ravel())) > 5  # the nets stop at many steps: the batch shrinks as they do
    assert [n for _, _, n in seen][0] == 15 and seen[-1][2] == 0 and len(seen) > 10
    np.testing.assert_array_equal(chunked.best_step, whole.best_step)
    np.testing.assert_array_equal(chunked.pred, whole.pred)
    np.testing.assert_array_equal(windows.best_step, whole.best_step)
    np.testing.assert_allclose(windows.pred, whole.pred, atol=1e-6)


def test_the_recurrent_model_is_causal():
    from pvvjax.dynamics import rnn_apply, rnn_init

    p = rnn_init(jax.random.key(0), 3, 5)
    x = np.random.default_rng(1).normal(size=(2, 20, 3)).astype(np.float32)
    y0 = np.asarray(rnn_apply(p, x))
    x2 = x.copy()
    x2[:, 12:] += 1.0
    y1 = np.asarray(rnn_apply(p, x2))
    np.testing.assert_array_equal(y0[:, :12], y1[:, :12])
    assert np.abs(y0[:, 12:] - y1[:, 12:]).max() > 1e-3


SMALL = """
[train]
max_steps = 100
eval_every = 50
patience = 2

[dynamic]
seeds = 1
folds = 3
rnn_hidden = 4
"""


@pytest.fixture(scope="module")
def dynamic_run(small_campaign_dir, tmp_path_factory):
    """`pvvjax dynamic` on the small campaign (run once per code version and cached, as the
    small sweep is), copied into this module's folder with its config."""
    import shutil

    from conftest import cached_folder

    from pvvjax.cli import main

    def args_in(folder):
        (folder / "small.toml").write_text(SMALL)
        return ["dynamic", "--campaign", str(small_campaign_dir), "--out", str(folder / "out"), "--config",
                str(folder / "small.toml")]

    def make(tmp):
        assert main(args_in(tmp)) == 0
        return tmp / "out"

    folder = tmp_path_factory.mktemp("dynamic")
    args = args_in(folder)
    shutil.copytree(cached_folder("dynamic", "report.md", make), folder / "out")
    return folder, folder / "out", args


@pytest.mark.check
def test_dynamic_command_writes_every_model_every_window_once(dynamic_run, small_campaign_dir):
    from pvvjax.config import DYNAMIC_MODELS
    from pvvjax.data.campaign import load_campaign

    _, out, _ = dynamic_run
    table = pd.read_csv(out / "comparison.csv")
    assert list(table.model) == list(DYNAMIC_MODELS) and table.best.sum() == 1
    assert table.loc[table.best, "rms_g"].iloc[0] == table.rms_g.min()  # every model flies: the lowest of all
    for col in ("rms_g", "peak_err_rms_g", "time_of_peak_err_median_s", "faa_pass_share", "kendall_tau",
                "rms_kind_holdout_g", "config_hash", "campaign"):
        assert table[col].notna().all(), col
    assert table.loc[table.model == "dynamic", "f_n_hz"].iloc[0] > 0
    pred = pd.read_parquet(out / "predictions.parquet")
    assert list(pred.columns) == ["counter", "maneuver", "fold", "database", "model", "t_start_s", "t_end_s",
                                  "pvv_g", "measured_g"]
    assert pred.pvv_g.dtype == np.float64 and pred.t_start_s.dtype == np.float64 and pred.notna().all().all()
    camp = load_campaign(small_campaign_dir)
    assert set(pred.counter) == set(camp.counters.index)
    per = pred.groupby(["model", "counter"]).fold.nunique()
    assert (per == 1).all()  # every counter held out by one fold
    sizes = pred.groupby("model").size()
    assert sizes.nunique() == 1  # every model scored on the same windows
    kinds = pd.read_csv(out / "by_kind.csv")
    level = kinds[(kinds.model == "window_static") & (kinds.maneuver == "level")]
    r = pred[(pred.model == "window_static") & (pred.maneuver == "level")]
    assert level.rms_g.iloc[0] == pytest.approx(np.sqrt(np.mean((r.pvv_g - r.measured_g) ** 2)))
    assert level.windows.iloc[0] == len(r) and set(kinds.maneuver) == set(pred.maneuver)
    assert kinds.groupby("model").windows.sum().nunique() == 1 and kinds.campaign.nunique() == 1
    ident = pd.read_csv(out / "identified.csv")
    assert set(ident.split) == {"condition", "maneuver"} and (ident.zeta > 0).all()
    report = (out / "report.md").read_text()
    assert "3.f.1" in report and "figures/through_time_db1.png" in report and "## Window RMS by maneuver kind" in report
    assert (out / "figures" / "through_time_db1.png").stat().st_size > 10_000


@pytest.mark.check
def test_dynamic_command_resumes_and_refuses_another_config(dynamic_run, capsys):
    from pvvjax.cli import main

    folder, out, args = dynamic_run
    before = (out / "comparison.csv").read_text()
    assert main(args) == 0
    assert capsys.readouterr().out.count("saved part") == 10
    assert (out / "comparison.csv").read_text() == before  # same config, data, seed: the same numbers
    (folder / "other.toml").write_text(SMALL.replace("folds = 3", "folds = 4"))
    assert main(args[:-1] + [str(folder / "other.toml")]) == 2
    assert "dynamic" in json.loads((out / "owner.json").read_text())["settings"]


@pytest.mark.check
def test_export_takes_the_best_model_or_a_named_one_into_the_element(dynamic_run, small_campaign_dir, tmp_path):
    from pvvjax.cli import main
    from pvvjax.data.campaign import load_campaign
    from pvvjax.dynamics import identified
    from pvvjax.realtime.element import CHANNELS, VibrationElement
    from pvvjax.realtime.npnet import read_npz

    _, out, _ = dynamic_run
    assert main(["export", str(out), "--element", "--model", "dynamic", "--out", str(tmp_path / "el")]) == 0
    spec = json.loads((tmp_path / "el" / "element.json").read_text())
    stacked, _ = read_npz(out / "parts" / "db1-condition-dynamic.params.npz")
    ident = identified(stacked)
    assert spec["response"]["zeta"] == pytest.approx(float(np.median(ident["zeta"])))
    assert spec["window_revs"] == 2.0 and len(spec["nets"]) == 3  # 3 folds x 1 seed
    el = VibrationElement.load(tmp_path / "el")
    rec = load_campaign(small_campaign_dir).records["11022"]
    outs = [el.step(t, az, x) for t, az, x in zip(rec.time_s, rec.azimuth_deg, rec[list(CHANNELS)].to_numpy(float))]
    assert outs[-1].ready and all(np.isfinite(o.pvv_g) for o in outs)
    best = pd.read_csv(out / "comparison.csv").query("best").model.iloc[0]
    assert main(["export", str(out), "--element", "--out", str(tmp_path / "best")]) == 0
    assert ("response" in json.loads((tmp_path / "best" / "element.json").read_text())) == (best == "dynamic")
    table = pd.read_csv(out / "comparison.csv")
    assert best == table[table.degenerate.isna()].sort_values("rms_g").model.iloc[0]  # the lowest of all
    for model in ("window_static_rates", "rnn"):  # every model flies: rates and the GRU's state in the element
        assert main(["export", str(out), "--element", "--model", model, "--out", str(tmp_path / model)]) == 0
        spec = json.loads((tmp_path / model / "element.json").read_text())
        assert spec["inputs"][-1] == "d_climb_rate_fpm_dt" and len(spec["envelope"]["lo"]) == 12
        el = VibrationElement.load(tmp_path / model)
        assert el.nets[0].stateful == (model == "rnn")
        outs = [el.step(t, az, x) for t, az, x in zip(rec.time_s, rec.azimuth_deg,
                                                      rec[list(CHANNELS)].to_numpy(float))]
        assert outs[-1].ready and np.ptp([o.pvv_g for o in outs]) > 0
    assert main(["export", str(out), "--out", str(tmp_path / "plain")]) == 2  # a comparison exports elements only


@pytest.mark.check
def test_a_degenerate_model_is_flagged_never_best_and_exported_only_by_name(dynamic_run, small_campaign_dir,
                                                                           tmp_path):
    import shutil

    from pvvjax.cli import main
    from pvvjax.config import load_config
    from pvvjax.data.campaign import load_campaign
    from pvvjax.dynamics.reporting import result_notes
    from pvvjax.dynamics.study import comparison_table, run_parts

    _, out, _ = dynamic_run
    cfg = load_config(out / "config.toml")
    parts = run_parts(load_campaign(small_campaign_dir), cfg, out / "parts", log=lambda m: None)
    d, by_split = parts["db1"]
    seq = d.seq
    # window_static: each condition's measured mean throughout, constant through every maneuver;
    # dynamic: the measured windows themselves (no error at all), with a delay of 1000 s, beyond every record.
    mean = (seq.amplitude * seq.mask).sum(1) / seq.mask.sum(1)
    t, arrays = by_split["condition"]["window_static"]
    by_split["condition"]["window_static"] = (t, {**arrays, "heldout": np.where(seq.mask, mean[:, None], np.nan)})
    t, arrays = by_split["condition"]["dynamic"]
    response = {**t.params["response"], "delay_raw": np.full_like(t.params["response"]["delay_raw"], 1e3)}
    by_split["condition"]["dynamic"] = (t._replace(params={**t.params, "response": response}),
                                        {**arrays, "heldout": np.where(seq.mask, seq.amplitude, np.nan)})
    table = comparison_table(parts, cfg).set_index("model")
    assert table.rms_g["dynamic"] == 0.0 and not table.best["dynamic"]
    assert "identified delay_s 1000 outside its range" in table.degenerate["dynamic"]
    assert "a constant prediction through" in table.degenerate["window_static"] and not table.best["window_static"]
    fit = table[table.degenerate == ""]
    assert table.best[fit.rms_g.idxmin()] and table.best.sum() == 1 and len(fit) == 3  # the lowest of the rest
    assert any("**dynamic** (db1) is degenerate" in ln for ln in result_notes(table.reset_index()))

    folder = tmp_path / "dyn"
    shutil.copytree(out, folder)
    table.reset_index().assign(best=False).to_parquet(folder / "comparison.parquet")
    assert main(["export", str(folder), "--element", "--out", str(tmp_path / "none")]) == 2  # nothing fit to export
    with pytest.warns(UserWarning, match=r"exporting dynamic \(db1\), a degenerate model: identified delay_s"):
        assert main(["export", str(folder), "--element", "--model", "dynamic", "--out", str(tmp_path / "named")]) == 0


@pytest.mark.check
def test_main_job_reports_the_dynamic_stage(tmp_path, small_campaign_dir, capsys):
    from pvvjax.cli import main

    cfg = tmp_path / "d.toml"
    cfg.write_text(f'''name = "d"\nout_dir = "{tmp_path.as_posix()}"
[campaign]\npath = "{small_campaign_dir.as_posix()}"
[run]\ndynamic = true\nhtml = false
[train]\nmax_steps = 50\neval_every = 25
[dynamic]\nmodels = ["quasi_static", "window_static", "dynamic"]\nseeds = 1\nfolds = 3\nkind_holdout = false\n''')
    assert main(["run", str(cfg)]) == 0
    assert "[4/4] PVV through time" in capsys.readouterr().out
    report = (tmp_path / "d" / "report.md").read_text()
    assert "## PVV through time" in report and "dynamic/figures/through_time_db1.png" in report
    table = pd.read_csv(tmp_path / "d" / "dynamic" / "comparison.csv")
    assert list(table.model) == ["quasi_static", "window_static", "dynamic"] and "rms_kind_holdout_g" not in table


def test_record_pieces_score_every_real_window_once_after_its_burn_in():
    """Pieces of 12 windows with a burn-in of 4 cover each chosen record's real windows once:
    the first piece of a record from its start, every later one after 4 windows of its own
    record; unchosen records and padding are never scored."""
    from pvvjax.dynamics.compare import _pieces, record_pieces

    lengths = np.array([30, 12, 5, 40, 13])
    mask = np.arange(40)[None, :] < lengths[:, None]
    rows = np.array([True, True, True, False, True])
    row, start, scored = record_pieces(mask, rows, 12, 4)
    assert set(row) == {0, 1, 2, 4}
    x = np.stack(np.meshgrid(np.arange(40), np.arange(5))[::-1], -1).astype(np.float32)  # (R, W, 2): row, window
    y = x[..., 1] + 100 * x[..., 0]
    n = len(row) + 3
    xp, yp, wp = _pieces(x, y, mask, row, start, scored, n, 12)
    assert xp.shape == (n, 12, 2) and wp[len(row):].sum() == 0  # padded pieces score nothing
    got = sorted(int(v) for v in yp[wp > 0])
    want = sorted(int(r * 100 + w) for r in np.flatnonzero(rows) for w in range(lengths[r]))
    assert got == want  # every real window of the chosen records, once
    for p in range(len(row)):
        first = np.flatnonzero(wp[p])[0] if wp[p].any() else None
        if first is not None and start[p] > 0:
            assert first >= 4 and (xp[p, :first, 0] == row[p]).all()  # its burn-in: its own record's windows
    with pytest.raises(ValueError, match="burn-in"):
        record_pieces(mask, rows, 4, 4)
