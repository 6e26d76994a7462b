"""Quasi-static replay: window sums against independent references (exact integrals of the
linear interpolant, the block path, numpy.searchsorted), gradients in offset and window
length against finite differences (at whole-sample offsets too), and agreement with the
databases at the peak window."""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd
import pytest
from conftest import Lowerings

from pvvjax import _lookup
from pvvjax.analysis.databases import STATE_CHANNELS
from pvvjax.analysis.harmonics import plan_windows, record_columns, stack_columns, window_sums, with_prefix
from pvvjax.data.batch import to_batch
from pvvjax.data.campaign import campaign_from_frames, load_campaign
from pvvjax.replay import quasistatic as R

make_lookup, search = _lookup.make_lookup, _lookup.search

SPR, RPM = 64, 257.8


def lagged_campaign(tau0, n: int = 3, seconds: float = 40.0, seed: int = 0):
    """Counters whose 4/rev amplitude follows the advance ratio τ0 seconds late (linearly),
    with smooth random airspeed histories: a replay with offset τ0 reproduces it. τ0 may
    be one value per counter."""
    rng = np.random.default_rng(seed)
    taus = np.broadcast_to(np.asarray(tau0, float), (n,))
    fs = SPR * RPM / 60.0
    t = np.arange(0.0, seconds, 1.0 / fs)
    rows, recs = [], {}
    for i, tau0 in enumerate(taus):
        f = rng.uniform(0.05, 0.3, 3)
        ph = rng.uniform(0, 2 * np.pi, 3)
        speed = lambda s: 100.0 + 25.0 * sum(np.sin(2 * np.pi * fk * s + p) for fk, p in zip(f, ph)) / 3  # noqa: E731
        mu_late = speed(t - tau0) * 1.6878 / (RPM * 2 * np.pi / 60 * 26.83)
        amp = 0.1 + 0.5 * (mu_late - 0.25)
        psi = 2 * np.pi * RPM / 60.0 * t
        name = f"M{i + 1}"
        recs[name] = pd.DataFrame({
            "time_s": t, "az_g": 1.0 + amp * np.cos(4 * psi + 0.3), "rotor_rpm": RPM, "airspeed_kt": speed(t),
            "pitch_rate_dps": 0.0, "roll_angle_deg": 0.0, "climb_rate_fpm": 0.0, "collective_pct": 50.0,
            "lateral_pct": 50.0, "longitudinal_pct": 55.0,
        })
        rows.append(dict(counter=name, maneuver="pullup", gross_weight_lb=16000.0, density_ratio=1.0))
    return campaign_from_frames(pd.DataFrame(rows), recs)


def linear_model():
    """The exact map of `lagged_campaign`: PVV = 0.1 + 0.5 (μ - 0.25)."""
    params = dict(w=jnp.asarray(0.5), b=jnp.asarray(0.1 - 0.5 * 0.25), y_shift=jnp.asarray(0.0))
    return dict(params=params, idx=jnp.asarray(R.input_index("db1")))


def linear_apply(p, x):
    return p["b"] + p["w"] * x[..., 0]


def test_lookup_search_matches_numpy():
    rng = np.random.default_rng(1)
    xp = np.cumsum(rng.uniform(0.95, 1.05, 3000)).astype(np.float32)
    x = np.concatenate([rng.uniform(xp[0] - 3, xp[-1] + 3, 4000), xp, np.nextafter(xp, np.inf),
                        np.nextafter(xp, -np.inf)]).astype(np.float32)
    got = search(jax.tree.map(jnp.asarray, make_lookup(xp)), jnp.asarray(xp), jnp.asarray(x))
    np.testing.assert_array_equal(np.asarray(got), np.searchsorted(xp, x))


def _columns(dtype=np.float64, wobble=0.05, seed=0):
    rng = np.random.default_rng(seed)
    n = 40 * SPR
    t = np.arange(n) / (SPR * RPM / 60)
    rev = np.concatenate([[0.0], np.cumsum((1 + wobble * np.sin(t[1:])) / SPR)])  # varying rotor speed
    pad = -n % 16
    rev_p = np.concatenate([rev, rev[-1] + (rev[-1] - rev[-2]) * np.arange(1, pad + 1)])
    width = np.zeros(n + pad)
    width[:n] = 0.5 * (np.r_[np.diff(rev)[:1], np.diff(rev)] + np.r_[np.diff(rev), np.diff(rev)[-1:]])
    x = np.pad(np.stack([np.sin(t), rng.standard_normal(n)], -1), ((0, pad), (0, 0)), mode="edge")
    az = np.pad(1 + 0.1 * np.cos(8 * np.pi * rev) + 0.02 * rng.standard_normal(n), (0, pad))
    psi = 2 * np.pi * rev_p
    tt = np.pad(t, (0, pad), mode="linear_ramp", end_values=t[-1] + pad * (t[1] - t[0]))
    f = lambda v: jnp.asarray(v, dtype)  # noqa: E731
    cols = record_columns(f(az), f(np.cos(psi)), f(np.sin(psi)), f(rev_p), f(width), f(tt), f(x), harmonic=4, block=16)
    return cols, rev[:n], x[:n]


def test_linear_edge_window_is_the_integral_of_the_linear_interpolant():
    with jax.enable_x64(True):
        cols, rev, x = _columns()
        plan = plan_windows(_FakeBatch(rev), 12.0, 1.0, edge="linear")
        a = jnp.asarray([0.7, 3.0 + 0.5 / SPR, 5.0, 10.37])
        b = a + jnp.asarray([8.0, 5.3, 11.9, 4.0])
        sums = window_sums(stack_columns(cols), a, b, kind="linear", taper_revs=0.0, plan=plan)
        mean = np.asarray(sums[:, 6:8] / sums[:, -1:])
        for j in range(4):  # dense reference: integrate the linear interpolant with a fine trapezoid rule
            r = np.linspace(float(a[j]), float(b[j]), 200001)
            ref = [np.trapezoid(np.interp(r, rev, x[:, c]), r) / (float(b[j]) - float(a[j])) for c in range(2)]
            np.testing.assert_allclose(mean[j] + np.asarray(cols.x_ref), ref, rtol=0, atol=1e-6)
            # The length is exact for uniform spacing; with a varying rotor speed the sample hats
            # are symmetric approximations of the true (asymmetric) ones.
            assert float(sums[j, -1]) == pytest.approx(float(b[j] - a[j]), rel=1e-5)


class _FakeBatch:
    def __init__(self, rev):
        self.rev = rev[None]
        self.mask = np.ones_like(self.rev, bool)


@pytest.mark.parametrize("kind", ["linear", "cell"])
def test_prefix_path_equals_block_path(kind):
    with jax.enable_x64(True):
        cols, rev, _ = _columns()
        plan = plan_windows(_FakeBatch(rev), 12.0, 1.0, edge=kind)
        rng = np.random.default_rng(3)
        a = jnp.asarray(rng.uniform(-0.5, 25, 30))
        b = a + jnp.asarray(rng.uniform(1.0, 12.0, 30))
        ref = window_sums(cols, a, b, kind=kind, taper_revs=0.0, plan=plan)
        fast = window_sums(with_prefix(cols), a, b, kind=kind, taper_revs=0.0, plan=plan)
        np.testing.assert_allclose(np.asarray(fast), np.asarray(ref), rtol=1e-9, atol=1e-9)


def test_prefix_sums_are_float64_cumulative_sums_per_record():
    # float32 columns: the (hi, lo) pair holds the float64 prefix sums of width · column
    # (and of the width), record by record under leading batch axes.
    c1, c2 = _columns(np.float32, seed=1), _columns(np.float32, seed=2)
    batched = with_prefix(jax.tree.map(lambda a, b: jnp.stack([a, b]), stack_columns(c1[0]), stack_columns(c2[0])))
    for r, (cols, _, _) in enumerate((c1, c2)):
        stacked = np.stack([np.asarray(v, np.float64) for v in cols.cols], 1)
        w = np.asarray(cols.width, np.float64)[:, None]
        ref = np.cumsum(np.concatenate([stacked * w, w], 1), 0)
        hi, lo = (np.asarray(p[r], np.float64) for p in batched.prefix)
        assert hi.dtype == np.float64 and np.all(hi[0] == 0) and np.all(lo[0] == 0)
        np.testing.assert_allclose(hi[1:] + lo[1:], ref, rtol=1e-12, atol=1e-12)
        single = with_prefix(cols)
        np.testing.assert_array_equal(np.asarray(single.prefix[0]), np.asarray(batched.prefix[0][r]))
        np.testing.assert_array_equal(np.asarray(single.prefix[1]), np.asarray(batched.prefix[1][r]))


@pytest.fixture(scope="module")
def small_replay(small_campaign_dir, small_dbs):
    """float64 records of the small campaign's maneuvers and an RBF db1 model."""
    from pvvjax.nets.networks import rbf_fit
    from pvvjax.nets.sweep import stack_data

    camp = load_campaign(small_campaign_dir)
    ctr = camp.counters[camp.counters.maneuver.isin(["pullup", "pushover", "roll", "flare", "autorotation"])]
    x, y, in_mask, _ = stack_data(small_dbs, ["db1"], 5, 0)["db1"]
    params = jax.tree.map(np.asarray, rbf_fit(jax.random.key(0), x, y, 24, in_mask=in_mask))
    with jax.enable_x64(True):
        batch = to_batch(camp, STATE_CHANNELS, list(ctr.index), dtype=np.float64)
        recs = R.prepare(batch)
        settings = R.make_settings(batch, hop_revs=1.0)
        params = jax.tree.map(lambda a: jnp.asarray(a, jnp.float64 if a.dtype == np.float32 else a.dtype), params)
    model = dict(params=params, idx=jnp.asarray(R.input_index("db1")))
    return camp, ctr, batch, recs, settings, model


def _one(tree, i):
    return jax.tree.map(lambda a: a[i], tree)


def test_replay_at_zero_offset_matches_the_database_at_the_peak_window(small_replay, small_dbs):
    from pvvjax.nets.networks import rbf_apply

    camp, ctr, batch, recs, _, model = small_replay
    peaks = small_dbs["peaks"].set_index("condition")
    with jax.enable_x64(True):
        settings = R.make_settings(batch, min_window_revs=8.0, max_window_revs=8.0)  # consecutive 8-rev windows
        run = jax.jit(lambda rec: R.replay(model, rec, 0.0, 8.0, settings=settings, apply=rbf_apply))
        checked = 0
        for i, counter in enumerate(ctr.index):
            row = peaks.loc[ctr.loc[counter, "condition"]]
            if row.counter != counter:
                continue
            rep = run(_one(recs, i))
            j = int(np.argmin(np.abs(np.asarray(rep.time) - row.peak_time_s)))
            # Database windows have sample-cell edges, replay windows linear ones: equal to ~1e-3.
            assert float(rep.measured[j]) == pytest.approx(row.peak_pvv_g, rel=2e-3)
            feats = dict(zip(R.FEATURES, np.asarray(rep.features[j])))
            for f in ("advance_ratio", "mlf", "gross_weight_lb", "collective_pct"):
                assert feats[f] == pytest.approx(row[f], rel=2e-3, abs=1e-3), f
            checked += 1
    assert checked >= 5


@pytest.mark.parametrize("tau0", [0.0, 3 / (SPR * RPM / 60), 0.4123])  # zero, a whole number of samples, fractional
@pytest.mark.parametrize("L0", [8.0, 7.37])
def test_gradients_match_finite_differences(small_replay, tau0, L0):
    from pvvjax.nets.networks import rbf_apply

    *_, recs, settings, model = small_replay
    rec = _one(recs, 0)
    with jax.enable_x64(True):
        @jax.jit
        def f(tau, L):
            rep = R.replay(model, rec, tau, L, settings=settings, apply=rbf_apply)
            t = R.cost_terms(rep)
            return jnp.stack([R.replay_cost(rep), t["peak_error_g"], t["phase_error_s"], t["rms_g"],
                              jnp.sum(rep.predicted * rep.weight), jnp.sum(rep.measured * rep.weight)])

        jac = jax.jacfwd(f, argnums=(0, 1))(jnp.float64(tau0), jnp.float64(L0))
        for arg, g in enumerate(jac):
            h = 1e-5
            plus = f(tau0 + h * (arg == 0), L0 + h * (arg == 1))
            minus = f(tau0 - h * (arg == 0), L0 - h * (arg == 1))
            fd = (plus - minus) / (2 * h)
            np.testing.assert_allclose(np.asarray(g), np.asarray(fd), rtol=2e-4, atol=1e-6 * (1 + np.abs(fd).max()))
        assert np.abs(np.asarray(jac[0])[4]) > 0  # the offset does move the prediction


def test_replay_recovers_a_known_lag_shape():
    camp = lagged_campaign(0.8, n=1)
    batch = to_batch(camp, STATE_CHANNELS)
    recs = R.prepare(batch)
    settings = R.make_settings(batch, hop_revs=1.0)
    rec = _one(recs, 0)
    rms = jax.jit(lambda tau: R.cost_terms(R.replay(linear_model(), rec, tau, 8.0, settings=settings,
                                                    apply=linear_apply))["rms_g"])
    err = {tau: float(rms(tau)) for tau in (0.0, 0.8, 1.6)}
    assert err[0.8] < 1e-3 < min(err[0.0], err[1.6])


def test_soft_peak_approaches_the_hard_peak():
    rng = np.random.default_rng(0)
    v = jnp.asarray(rng.uniform(0.05, 0.3, 40))
    t = jnp.arange(40.0)
    w = jnp.ones(40).at[:3].set(0.0)
    pk, tp = R.soft_peak(v, t, w, 1e-4)
    j = 3 + int(np.argmax(np.asarray(v[3:])))
    assert float(pk) == pytest.approx(float(v[j]), abs=1e-6) and float(tp) == pytest.approx(j, abs=1e-3)
    # Windows of weight 0 never count, however large.
    pk0, _ = R.soft_peak(v.at[0].set(9.0), t, w, 1e-3)
    assert float(pk0) < 0.31


def test_prepare_rejects_other_channels(small_campaign_dir):
    camp = load_campaign(small_campaign_dir)
    with pytest.raises(ValueError, match="channels"):
        R.prepare(to_batch(camp, ("airspeed_kt",), list(camp.counters.index[:1])))


def test_stick_lag_moves_only_the_stick_inputs(small_replay):
    from pvvjax.nets.networks import rbf_apply

    _, _, batch, recs, _, model = small_replay
    replay = jax.jit(R.replay, static_argnames=("settings", "apply"))  # one compilation per settings
    with jax.enable_x64(True):
        settings = R.make_settings(batch, hop_revs=1.0, stick_lag=True)
        rec = _one(recs, 0)
        f0 = np.asarray(replay(model, rec, 0.5, 8.0, 0.0, settings=settings, apply=rbf_apply).features)
        f1 = np.asarray(replay(model, rec, 0.5, 8.0, 0.7, settings=settings, apply=rbf_apply).features)
        plain = R.make_settings(batch, hop_revs=1.0)
        f2 = np.asarray(replay(model, rec, 1.2, 8.0, 0.0, settings=plain, apply=rbf_apply).features)
    sticks = [R.FEATURES.index(s) for s in R.STICKS]
    others = [i for i in range(len(R.FEATURES)) if i not in sticks]
    np.testing.assert_array_equal(f0[:, others], f1[:, others])
    assert np.abs(f0[:, sticks] - f1[:, sticks]).max() > 1e-3
    np.testing.assert_allclose(f1[:, sticks], f2[:, sticks], rtol=1e-12)  # sticks at 0.5 + 0.7 s


def test_replays_at_other_offsets_share_one_program_and_equal_replays_that_bake_them_in():
    # The offset bounds (how far the input windows may reach) and the reference length enter
    # the compiled replay as data (a `Settings` PyTree): replaying at another offset reuses the
    # program, and gives what a replay with the settings as static constants gives.
    from pvvjax.nets.networks import mlp_init

    camp = lagged_campaign(0.5, n=2, seconds=20.0)
    batch = to_batch(camp, STATE_CHANNELS)
    recs = R.prepare(batch)
    seeds = [mlp_init(jax.random.key(k), 8, (4,), in_mask=np.r_[np.ones(6), np.zeros(2)]) for k in range(2)]
    net = dict(params=jax.tree.map(lambda *a: jnp.stack(a), *seeds), idx=jnp.asarray(R.input_index("db1")))
    model = jax.tree.map(lambda a: jnp.broadcast_to(a, (2, *jnp.shape(a))), net)
    info = camp.counters[["maneuver", "condition"]]
    with Lowerings() as lowered:
        _replays_at_offsets(batch, recs, model, info)
    assert lowered["_replay_all"] <= 1


def _replays_at_offsets(batch, recs, model, info):
    from pvvjax.replay.tables import replay_windows, settings_at

    for tau in (0.0, 0.5, 1.25):
        s = settings_at(batch, (tau, 8.0, 0.0))
        w = replay_windows(info, recs, {"db1": model}, (tau, 8.0, 0.0), s)
        baked = jax.jit(jax.vmap(lambda m, r: R.replay(m, r, tau, 8.0, settings=s)))(model, recs)  # noqa: B023
        keep = np.asarray(baked.weight).ravel() > 0  # the table keeps the windows with weight
        for col, ref in (("predicted_g", baked.predicted), ("measured_g", baked.measured), ("weight", baked.weight)):
            np.testing.assert_allclose(w[col].to_numpy(), np.asarray(ref).ravel()[keep], rtol=1e-6, atol=1e-7)
        # Inputs τ > 0 before the first windows reach before the record: weighted out (the bound is data).
        assert ((~keep).sum() + (w.weight < 0.999).sum() > 0) == (tau > 0)


def test_campaigns_of_different_sizes_in_one_bucket_share_the_compiled_analysis_and_replay():
    """Record counts, lengths and window counts come in buckets: two campaigns of other sizes
    (3 counters of 20 s, 4 of 19 s) compile the analysis, the replay's preparation and the
    replay once, and each equals its own replay computed without the shared padding."""
    from pvvjax.analysis.harmonics import analyze
    from pvvjax.nets.networks import mlp_init
    from pvvjax.replay.tables import replay_all, settings_at

    net = mlp_init(jax.random.key(0), 8, (4,), in_mask=np.r_[np.ones(6), np.zeros(2)])
    runs = []
    with Lowerings(fresh=True) as lowered:
        for n, seconds in ((3, 20.0), (4, 19.0)):
            batch = to_batch(lagged_campaign(0.5, n=n, seconds=seconds, seed=n), STATE_CHANNELS)
            win = analyze(batch, 8.0)
            recs = R.prepare(batch)
            settings = settings_at(batch, (0.5, 8.0, 0.0))
            model = dict(params=jax.tree.map(lambda a: jnp.broadcast_to(a, (n, *jnp.shape(a))), net),
                         idx=jnp.asarray(np.broadcast_to(R.input_index("db1"), (n, 8))))
            rep = replay_all(model, recs, jnp.asarray([0.5, 8.0, 0.0]), settings=settings)
            runs.append((batch, win, recs, settings, model, rep))
    assert runs[0][0].time.shape[1] == runs[1][0].time.shape[1] and runs[0][3].plan == runs[1][3].plan
    assert lowered["_replay_all"] == 1 and lowered["_prepare"] == 1, dict(lowered)
    assert lowered["harmonic_windows"] == 1, dict(lowered)
    for batch, win, recs, settings, model, rep in runs:  # the padded batch's rows equal the rows alone
        assert rep.time.shape[0] == win.amplitude.shape[0] == len(batch.counters)
        one = jax.jit(lambda m, r: R.replay(m, r, 0.5, 8.0, settings=settings))(  # noqa: B023
            jax.tree.map(lambda a: a[-1], model), jax.tree.map(lambda a: a[-1], recs))
        np.testing.assert_allclose(np.asarray(rep.predicted[-1]), one.predicted, rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(np.asarray(rep.measured[-1]), one.measured, rtol=1e-6, atol=1e-7)


@pytest.fixture(scope="module")
def small_sweep_replay(small_campaign_dir, small_sweep):
    """The shared small sweep's replay set of the transient maneuvers (db1, db3), its common
    offset and the calibration settings of the main job's research check."""
    from pvvjax.config import CalibrationConfig
    from pvvjax.replay import studies
    from pvvjax.replay.tables import load_replay_set

    camp = load_campaign(small_campaign_dir)
    counters = camp.counters[camp.counters.maneuver.isin(["pullup", "pushover", "roll", "autorotation", "flare"])]
    rset = load_replay_set(camp, list(counters.index), small_sweep, ["db1", "db3"])
    cc = CalibrationConfig(grid_offset_step_s=0.5, grid_window_step_revs=2.0)
    return rset, cc, studies.one_offset(*rset, cc, log=lambda *a: None)


# The main job's studies (its research check: tests/test_cli.py) on the shared small sweep's
# held-out nets.


@pytest.mark.check
@pytest.mark.heavy
def test_each_kinds_own_offset_does_at_least_as_well_on_it_as_the_common_one(small_sweep_replay, tmp_path):
    from pvvjax.replay import studies

    rset, cc, common = small_sweep_replay
    kinds = studies.offset_per_kind(*rset, cc, common, tmp_path, log=lambda *a: None).tables["offset_per_kind"]
    cost = kinds.pivot_table(index=["database", "maneuver"], columns="offsets", values="cost")
    assert (cost["one per kind"] <= cost["one for all"] * 1.01 + 1e-6).all()


@pytest.mark.check
@pytest.mark.heavy
def test_the_window_length_study_and_the_stick_lag(small_sweep_replay, tmp_path):
    # The gradient optimum of (offset, window length) is no worse than the brute-force grid's
    # best point; the stick lag replays the pull-up with and without it.
    from pvvjax.replay import studies

    rset, cc, common = small_sweep_replay
    wl = studies.window_length(*rset, cc, tmp_path, log=lambda *a: None)
    assert (wl.tables["window_length"].gradient_cost <= wl.tables["window_length"].grid_cost * 1.02).all()
    assert len(wl.tables["window_length"]) == 4 and wl.markdown.startswith("## Window length")
    lag = studies.stick_lag(*rset, cc, common, "11022", tmp_path, log=lambda *a: None)
    assert lag.markdown.startswith("## A separate lag") and all(Path(f).exists() for f in lag.figures)


def test_a_counter_without_a_whole_window_is_named_not_dropped_silently():
    import pandas as pd

    from pvvjax.replay import peak_summary

    rows = [dict(database="db1", counter=c, condition=c, maneuver="level", window=k, time_s=float(k),
                 measured_g=0.1 + 0.01 * k, predicted_g=0.1, weight=w, offset_s=0.0, window_revs=8.0,
                 stick_offset_s=0.0) for c, w in (("A", 1.0), ("B", 0.6)) for k in range(3)]
    with pytest.warns(UserWarning, match=r"1 counter\(s\) get no whole window .*: B"):
        summary = peak_summary(pd.DataFrame(rows))
    assert list(summary.counter) == ["A"]


def test_one_records_defect_leaves_every_other_records_replay_bitwise_unchanged():
    # A logger glitch in one record's azimuth (a sample out of step: the plan that record's own
    # samples need grows) or in its vibration changes that record's replay only: the records
    # are replayed in groups of the plan each one needs (`Settings.groups`).
    import dataclasses

    from pvvjax.nets.networks import mlp_init
    from pvvjax.replay.tables import replay_all, settings_at

    n, j = 4, 2
    batch = to_batch(lagged_campaign(0.5, n=n, seconds=20.0, seed=1), STATE_CHANNELS)
    net = mlp_init(jax.random.key(0), 8, (4,), in_mask=np.r_[np.ones(6), np.zeros(2)])
    model = dict(params=jax.tree.map(lambda a: jnp.broadcast_to(a, (n, *jnp.shape(a))), net),
                 idx=jnp.asarray(np.broadcast_to(R.input_index("db1"), (n, 8))))

    def run(b):
        s = settings_at(b, (0.5, 8.0, 0.0), hop_revs=1.0)
        return s, replay_all(model, R.prepare(b), jnp.asarray([0.5, 8.0, 0.0]), settings=s)

    settings, base = run(batch)
    assert settings.groups == ()  # one plan serves these records
    others = np.arange(n) != j
    rev = np.array(batch.rev)
    step = rev[j, 401] - rev[j, 400]
    cases = {}
    for name, shift in (("azimuth step short", -0.45), ("azimuth step long", 0.45), ("azimuth glitch", -0.9)):
        a = rev.copy()
        a[j, 401:] += shift * step
        cases[name] = dataclasses.replace(batch, rev=a)
    accel = np.array(batch.accel)
    accel[j, 400] += 5.0
    cases["vibration spike"] = dataclasses.replace(batch, accel=accel)
    for name, b in cases.items():
        s, out = run(b)
        if name.startswith("azimuth"):
            assert len(s.groups) == 2 and any(rows == (j,) for _, rows in s.groups), (name, s.groups)
        for before, after in zip(base, out):
            np.testing.assert_array_equal(np.asarray(before)[others], np.asarray(after)[others], err_msg=name)
        assert any(not np.array_equal(np.asarray(x)[j], np.asarray(y)[j], equal_nan=True) for x, y in zip(base, out))
