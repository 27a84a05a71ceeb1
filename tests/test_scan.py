"""The scan module: options, scale invariance, standard errors, significance, refinement."""

import warnings

import numpy as np
import pandas as pd
import pytest
from _dde import measured_mackey_glass
from joblib import parallel_config

from skdelay._dips import locate_dip
from skdelay._embedding import required_lags
from skdelay._local_linear import LocalLinearDelayMap
from skdelay._scan import ScanOptions, default_n_candidates, neighbourhood_mode
from skdelay._selection import DelaySelectorCV, NoDipWarning, forecast_error_curve, locate_dips
from skdelay._windows import lagged_windows


@pytest.fixture(scope="module")
def mg30():
    return measured_mackey_glass(6000, 30, seed=0)


# ----------------------------------------------------------------------------- options
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"ridge": -1e-3}, r"ridge must be a finite number >= 0"),
        ({"radius": 0.0}, r"radius must be None \(k-NN\) or a finite number > 0"),
        ({"order": 2}, r"order must be 0 \(local constant\) or 1 \(local linear\), got 2"),
        ({"k": 10, "n_candidates": 5},
         r"n_candidates=5 is smaller than n_neighbors=10: .* use n_candidates >= 10"),
        ({"search": "kd"}, r"search must be 'auto', 'tree', 'candidates' or 'exact', got 'kd'"),
        ({"neighbourhood": "x"}, r"equal_neighbourhood must be False"),
        ({"n_queries": 0}, r"n_queries must be >= 1"),
    ],
)
def test_scan_options_reject_bad_values(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ScanOptions(**kwargs)


def test_scan_options_normalise_and_default_candidates():
    assert [neighbourhood_mode(v) for v in (False, None, True, "segment", "radius")] == [
        "none", "none", "segment", "segment", "radius"]
    opts = ScanOptions(k=30, neighbourhood=True, ridge=0)
    assert opts.neighbourhood == "segment" and opts.candidates_for(10**5) == 240
    assert default_n_candidates(30) == 240 and ScanOptions(k=3).candidates_for(500) == 64
    # long records: the lists of one m stay within 256 MB, but at least 2k candidates
    assert default_n_candidates(30, 10**6) == 67 and default_n_candidates(30, 10**7) == 60
    with pytest.raises(AttributeError):
        opts.k = 3  # frozen


def test_theiler_window_that_leaves_no_neighbours(mg30):
    s = mg30[:300]
    with pytest.raises(ValueError, match=r"theiler_window=5000 is not shorter than the 2\d\d rows"):
        forecast_error_curve(s, m=(2,), tau=range(1, 10), theiler_window=5000)
    with pytest.raises(ValueError, match=r"theiler_window=140 leaves 9 of the 290 rows as "
                       r"neighbours of a query, fewer than n_neighbors=30"):
        forecast_error_curve(s, m=(2,), tau=range(1, 10), theiler_window=140)
    with pytest.raises(ValueError, match=r"radius must be None"):
        forecast_error_curve(s, m=(2,), tau=range(1, 10), radius=-1.0)


# ----------------------------------------------------------------------------- scale
def test_curve_is_scale_invariant(mg30):
    s = measured_mackey_glass(3000, 30, noise=0.01, bits=None, seed=3)  # no ties
    kw = {"m": (2, 3), "tau": range(26, 35), "n_queries": 400, "random_state": 0}
    ref = forecast_error_curve(s, **kw)
    for factor in (1e300, 1e-300, -7.3):
        other = forecast_error_curve(s * factor, **kw)
        np.testing.assert_allclose(other, ref, rtol=1e-9)
        np.testing.assert_allclose(other.attrs["se"], ref.attrs["se"], rtol=1e-6)
    assert 0.01 < ref.min().min() < 0.05  # the noise floor, not a scale artefact


def test_constant_series_are_rejected():
    with pytest.raises(ValueError, match="constant"):
        forecast_error_curve(np.full(500, 3.0), m=(2,), tau=range(1, 5))
    wobble = 1.0 + 1e-16 * np.random.default_rng(0).standard_normal(500)
    with pytest.raises(ValueError, match=r"constant up to rounding"):
        forecast_error_curve(wobble, m=(2,), tau=range(1, 5))


# ----------------------------------------------------------------------------- significance
def _periodic_feedback(n, per_delay=50, delay=1.0, substeps=5, seed=0):
    """dx/dt = -x + 2 x(t-T) / (1 + x(t-T)^10), T = 1, sampled at ``per_delay`` per delay.

    The right-hand side depends on the present only through -x; with T = 1 the
    solution is a limit cycle, so the state is fixed by the last few samples and
    the delayed window adds nothing: no dip.  (With T = 1.7 or 3 the solution is
    chaotic and the dip stays significant even at 200 samples per delay.)
    """
    from skdelay.systems import measure

    h = delay / per_delay / substeps
    d = per_delay * substeps
    steps = (n + 2000) * substeps
    x = np.empty(steps + d + 1)
    x[:d + 1] = 0.5
    for i in range(d, d + steps):
        f0 = -x[i] + 2.0 * x[i - d] / (1 + x[i - d] ** 10)
        xp = x[i] + h * f0
        f1 = -xp + 2.0 * x[i - d + 1] / (1 + x[i - d + 1] ** 10)
        x[i + 1] = x[i] + 0.5 * h * (f0 + f1)
    return measure(x[d + 2000 * substeps::substeps][:n], noise=0.005, random_state=seed)


def test_mackey_glass_dips_are_significant():
    from skdelay.systems import MackeyGlass, measure

    x = MackeyGlass(tau=30.0).simulate(8000, random_state=0)
    s = measure(x, noise=0.005, bits=12, random_state=0)
    X, y = lagged_windows(s, required_lags(5, 45))
    with warnings.catch_warnings():
        warnings.simplefilter("error", NoDipWarning)
        sel = DelaySelectorCV(tau=range(15, 46), n_queries=2000, random_state=0).fit(X, y)
    dips = sel.delay_by_m_
    assert dips["significant"].all(), dips["reason"]
    assert np.all(np.abs(dips["delay"] - 30) < 1.0)
    assert np.all(dips["z"] > 2 * dips["threshold"])
    assert abs(sel.delay_ - 30) < 1.0
    best = dips.loc[sel.best_params_["m"]]
    assert sel.best_params_["m"] == int(dips["min_error"].idxmin())
    assert sel.delay_error_ == best["delay_error"] and 0.5 <= sel.delay_error_ <= 5
    assert sel.best_params_["tau"] == best["tau_best"] and abs(best["tau_best"] - 30) <= 1
    se = sel.forecast_error_.attrs["se"]
    assert se.shape == sel.forecast_error_.shape
    # sigma ~ 0.006-0.015; 2000 queries give a relative standard error of a few percent
    rel = se / sel.forecast_error_
    assert np.all((rel > 0.003) & (rel < 0.1))


def test_a_narrow_dip_on_a_rising_curve_is_measured_from_its_own_rim():
    # a notch at 17.3 (width 1.2) on an error that rises and undulates with tau, scanned to
    # 300: the whole scan's median lies far above the notch's shoulders, and a level taken
    # from it spanned the neighbouring valleys too (centre 16.1, half-width 4.8)
    taus = np.arange(1, 301)
    rng = np.random.default_rng(3)
    se = np.full(taus.size, 2e-5)
    c = (0.001 + 1e-5 * taus + 0.01 * np.exp(-taus / 1.5) + 2e-4 * np.sin(2 * np.pi * taus / 20)
         - 0.0006 * np.exp(-0.5 * ((taus - 17.3) / 1.2) ** 2)
         + se * rng.standard_normal(taus.size))
    dip = locate_dip(taus, c, se=se)
    assert dip.significant and dip.tau_min == 17 and dip.tau_best == 17
    assert abs(dip.centre - 17.3) < 0.5 and 0.5 <= dip.half_width < 2.5
    # the depth (significance) is still read against the whole scan's median
    assert dip.baseline == pytest.approx(np.median(c))
    # a single valley keeps the median's level: the same notch without the undulation
    # and trend, scanned over 1..40, gives the same run whichever level is used
    flat = 0.001 - 0.0006 * np.exp(-0.5 * ((taus[:40] - 17.3) / 1.2) ** 2)
    single = locate_dip(taus[:40], flat, se=se[:40])
    assert abs(single.centre - 17.3) < 0.1


def test_the_centre_error_from_query_batches_matches_the_spread_over_records():
    # every cell of a scan forecasts the same queries, so a heavy-tailed per-query factor
    # moves the whole curve together: it inflates each cell's standard error but not the
    # dip's position.  Resampling the query batches (the same batches at every delay)
    # must give the spread of the centre over independent records; redrawing each cell
    # independently within its standard error overstates it (here ~3x)
    taus = np.arange(1.0, 81.0)
    shape = 1.0 - 0.3 * np.exp(-0.5 * ((taus - 30.3) / 2.0) ** 2) + 0.002 * taus
    n_q, n_b = 3200, 32

    def record(seed):
        rng = np.random.default_rng(seed)
        g = rng.exponential(size=n_q) ** 2
        sq = g[:, None] * shape ** 2 * (1 + 0.3 * rng.standard_normal((n_q, taus.size)))
        b = sq.reshape(n_b, n_q // n_b, taus.size).mean(axis=1).T  # (n_tau, n_batches)
        c = np.sqrt(b.mean(axis=1))
        se = b.std(axis=1, ddof=1) / np.sqrt(n_b) / (2 * c)
        boot = locate_dip(taus, c, se=se, batch_msq=b[None], random_state=seed)
        redraw = locate_dip(taus, c, se=se, random_state=seed)
        return boot.centre, boot.centre_se, redraw.centre_se

    centre, boot_se, redraw_se = np.array([record(s) for s in range(20)]).T
    # batches that do not belong to the curve are refused, not silently ignored
    with pytest.raises(ValueError, match=r"batch_msq must have shape \(n_splits, 80, n_batches\)"):
        locate_dip(taus, shape, batch_msq=np.ones((1, 79, 32)))
    with pytest.raises(TypeError, match=r"batch_msq must be a DataFrame with columns \(m, split"):
        locate_dips(pd.DataFrame({2: shape}, index=taus), batch_msq=np.ones((1, 80, 32)))
    spread = centre.std(ddof=1)
    assert abs(centre.mean() - 30.3) < 0.2
    assert 0.5 < np.median(boot_se) / spread < 2.0
    assert np.median(redraw_se) / spread > 2.0


@pytest.mark.parametrize(("seeds", "kw"), [
    ((11, 12), {"m": (2, 5), "n_queries": 1500, "refine": False}),
    # another record, fewer queries, refined: its m = 2 rim at tau = 19 falls back by only
    # 1.9 independent standard errors, a significant fall paired over the query batches
    ((5, 6), {"m": (2, 3, 4, 5), "n_queries": 500}),
])
def test_a_wide_scan_of_clean_mackey_glass_finds_its_delay(seeds, kw):
    # the analysis scans Mackey-Glass tau = 17 to its strongest autocorrelation revival
    # (~300 samples); before the dip's own rim, this gave centres of 28-37 +- 27-39
    from skdelay.systems import MackeyGlass, measure

    s = measure(MackeyGlass(tau=17.0).simulate(20_000, random_state=seeds[0]), bits=12,
                random_state=seeds[1])
    curve = forecast_error_curve(s, tau=range(1, 301), random_state=0, **kw)
    dips = locate_dips(curve)
    print(dips[["delay", "half_width", "centre_se", "tau_best", "significant"]])
    assert dips["significant"].all()
    assert np.all(np.abs(dips["delay"] - 17) < 1.0)
    assert np.all(dips["half_width"] < 4.0)
    assert np.all(np.abs(dips["tau_best"] - 17) <= 1)
    # an honest error bar: the centre is known to a fraction of a sample (the scan's
    # query batches resampled); redrawing each cell independently gave 9-68 samples
    assert np.all(dips["centre_se"] < 0.5)
    assert np.all(dips["delay_error"] < 4.0)
    assert np.all(np.abs(dips["delay"] - 17) < dips["delay_error"])


def test_refinement_targets_the_batch_centre_error_unless_told_otherwise():
    # on a wide scan the independent redraws overstate the centre's error (other valleys),
    # so refinement under centre_error="redraws" recomputes many cells for nothing
    from skdelay.systems import MackeyGlass, measure

    s = measure(MackeyGlass(tau=17.0).simulate(20_000, random_state=11), bits=12,
                random_state=12)
    kw = {"m": (2, 5), "tau": range(1, 301), "n_queries": 1500, "random_state": 0}
    fast = forecast_error_curve(s, **kw)
    slow = forecast_error_curve(s, centre_error="redraws", **kw)
    n_fast = int(fast.attrs["queries"].to_numpy().sum())
    n_slow = int(slow.attrs["queries"].to_numpy().sum())
    print(n_fast, n_slow)
    assert n_slow > 1.5 * n_fast
    a, b = locate_dips(fast), locate_dips(slow)
    assert np.all(a["centre_se"] < 0.2)
    assert np.all(np.abs(a["delay"] - b["delay"]) < 2 * np.hypot(a["centre_se"], b["centre_se"]))
    with pytest.raises(ValueError, match=r"centre_error must be 'batches' or 'redraws'"):
        forecast_error_curve(s, centre_error="bootstrap", **kw)


@pytest.mark.parametrize("kind", ["ar1", "oversampled"])
def test_no_dip_gives_nan_delay_and_a_warning(kind):
    if kind == "ar1":
        rng = np.random.default_rng(0)
        s = np.zeros(6000)
        for i in range(1, s.size):
            s[i] = 0.9 * s[i - 1] + rng.standard_normal()
        taus = range(1, 61)
    else:
        s = _periodic_feedback(6000)
        taus = range(1, 101)
    X, y = lagged_windows(s, required_lags(5, taus[-1]))
    with pytest.warns(NoDipWarning, match=r"no window length shows a significant") as rec:
        sel = DelaySelectorCV(tau=taus, n_queries=2000, random_state=0).fit(X, y)
    message = str(rec[0].message)
    assert "a longer record" in message and "a wider tau range" in message
    assert "m=2: " in message and "m=5: " in message
    assert np.isnan(sel.delay_) and np.isnan(sel.delay_error_)
    assert not sel.delay_by_m_["significant"].any()
    fe = sel.forecast_error_
    m_min = int(fe.min().idxmin())
    assert sel.best_params_ == {"m": m_min, "tau": int(fe[m_min].idxmin())}
    assert sel.predict(X[:5]).shape == (5,)


def test_default_grid_adapts_to_the_lag_columns(mg30):
    X, y = lagged_windows(mg30, 45)
    sel = DelaySelectorCV(n_queries=1500, random_state=0).fit(X, y)
    fe = sel.forecast_error_
    assert list(fe.columns) == [2, 3, 4, 5]
    assert fe.index[0] == 1 and fe.index[-1] == 43  # required_lags(5, 43) = 45
    assert abs(sel.delay_ - 30) < 1.0
    X3, y3 = lagged_windows(mg30[:400], 3)
    small = DelaySelectorCV()
    with pytest.warns(NoDipWarning, match="only 2 delay"):
        small.fit(X3, y3)
    assert list(small.forecast_error_.columns) == [2, 3]
    assert list(small.forecast_error_.index) == [1, 2]


def test_degenerate_inputs_raise(mg30):
    X, y = lagged_windows(mg30[:400], 12)
    for rows in (3, 20, 40):
        with pytest.raises(ValueError, match=rf"n_neighbors=30 but X has {rows} rows"):
            DelaySelectorCV(LocalLinearDelayMap(30), m=2, tau=8).fit(X[:rows], y[:rows])
    with pytest.raises(ValueError, match=r"X has 4 rows, too few for a delay scan"):
        DelaySelectorCV(m=2, tau=8, theiler_window=1).fit(X[:4], y[:4])
    with pytest.raises(ValueError, match=r"X is constant \(every value equals 2.0\)"):
        DelaySelectorCV(m=2, tau=8).fit(np.full((300, 12), 2.0), np.full(300, 2.0))
    with pytest.raises(ValueError, match=r"X has 1 feature\(s\)"):
        DelaySelectorCV().fit(X[:, :1], y)


# ----------------------------------------------------------------------------- refinement, tasks
def test_refinement_adds_queries_at_the_dip_only(mg30):
    kw = {"m": (2, 3), "tau": range(15, 46), "n_queries": 150, "random_state": 0}
    fe = forecast_error_curve(mg30, **kw)
    coarse, queries = fe.attrs["coarse"], fe.attrs["queries"]
    n_rows = mg30.size - required_lags(3, 45)
    for m in (2, 3):
        refined = ~coarse[m]
        assert refined.any() and coarse[m].any()
        taus = refined.index[refined.to_numpy()]
        assert taus.min() <= 30 <= taus.max() and taus.max() - taus.min() < 20
        assert np.all(queries.loc[taus, m] > 150) and np.all(queries.loc[~refined, m] == 150)
        assert queries[m].max() <= n_rows
    dips = locate_dips(fe)
    at_all = queries.max() == n_rows
    assert np.all((dips["centre_se"] < 0.2) | at_all)
    assert np.all(np.abs(dips["delay"] - 30) < 1.0)
    flat = forecast_error_curve(mg30, refine=False, **kw)
    assert flat.attrs["coarse"].all().all() and (flat.attrs["queries"] == 150).all().all()
    # the coarse cells are the same computation in both runs, except those around the dip
    # that the refinement recomputed with exact neighbours (same queries)
    polished = coarse & (fe.attrs["exact"] == 1) & (flat.attrs["exact"] < 1)
    same = coarse & ~polished
    assert same.to_numpy().sum() > 20
    np.testing.assert_allclose(flat[same], fe[same], rtol=1e-12)


def test_the_dip_is_read_off_exact_neighbourhoods(monkeypatch):
    # the coarse pass of a long record uses the candidate lists, which are approximate
    # (exact fraction < 1); the refinement gives the dip's cells the tree search with their
    # own queries, so there the curve is the tree search's, bit for bit.  A record that long
    # takes minutes: on ~3*10^4 rows the cost model is told that trees are dear instead
    import skdelay._scan as scan

    s = measured_mackey_glass(30_000, 40, noise=0.01, bits=12, seed=1)
    kw = {"m": (2, 4), "tau": range(20, 61), "n_queries": 500, "random_state": 0}
    with monkeypatch.context() as patch:
        patch.setattr(scan, "TREE_BUILD", 1e3)
        auto = forecast_error_curve(s, **kw)
    tree = forecast_error_curve(s, search="tree", refine=False, **kw)
    lists = forecast_error_curve(s, search="candidates", refine=False, **kw)
    exact, queries = auto.attrs["exact"], auto.attrs["queries"]
    dips = locate_dips(auto, se=auto.attrs["se"])
    for m in (2, 4):
        assert dips.loc[m, "significant"] and abs(dips.loc[m, "delay"] - 40) < 1
        near = np.abs(auto.index - dips.loc[m, "delay"]) <= 2 * dips.loc[m, "half_width"]
        assert np.all(exact.loc[near, m] == 1)  # every cell of the dip run: exact
        assert np.all(exact.loc[~near, m].to_numpy()[:5] < 1)  # far away: still the lists
        at_coarse = near & (queries[m] == 500).to_numpy()
        np.testing.assert_array_equal(auto.loc[at_coarse, m], tree.loc[at_coarse, m])
        # ... and the lists alone would have given another curve there
        assert np.abs(lists.loc[near, m] / tree.loc[near, m] - 1).max() > 1e-4


@pytest.mark.parametrize(("n_rows", "n_queries", "n_taus", "tree"), [
    (5_000, 200, 40, True),  # benchmarks/delay_scan.py --part c: tree 0.4 s, lists 1.4 s
    (30_000, 500, 200, True),  # tree 6.9 s, lists 7.8 s
    (100_000, 1000, 200, True),  # tree 26.3 s, lists 22.8 s: not worth approximating
    (100_000, 4000, 200, True),  # tree 43.2 s, lists 46.3 s
    (6_000, 10, 100, False),  # ten queries: 0.12 s of trees against 0.05 s of lists
    (1_000_000, 10_000, 500, False),  # the paper's coarse pass: the lists by 6.7x
    (1_000_000, 1_000_000, 21, True),  # its full-precision check (the lists by 1.6x)
])
def test_auto_search_takes_the_lists_only_where_they_halve_the_cost(
        n_rows, n_queries, n_taus, tree):
    from skdelay._scan import _use_tree

    rng = np.random.default_rng(0)
    db_t = np.arange(10, n_rows)
    q_t = db_t if n_queries >= n_rows else np.sort(rng.choice(db_t, n_queries, replace=False))
    for m in (2, 5):
        assert _use_tree(m, db_t, q_t, np.arange(1, n_taus + 1), ScanOptions()) is tree


def test_a_coarse_pass_on_a_short_record_is_exact():
    # 500 queries on 3*10^4 rows: the old rule (lists above 10 rows per query) used the
    # approximate lists, although one tree per tau costs less there (and is exact)
    s = measured_mackey_glass(30_000, 40, noise=0.01, bits=12, seed=1)
    fe = forecast_error_curve(s, m=(2, 4), tau=range(30, 41), n_queries=500, refine=False,
                              random_state=0)
    assert (fe.attrs["exact"] == 1).all().all()


def test_progress_bar_and_shared_arrays(mg30, capsys, monkeypatch):
    import skdelay._scan as scan

    kw = {"m": (2, 3), "tau": range(27, 34), "n_queries": 300, "random_state": 0}
    ref = forecast_error_curve(mg30[:3000], **kw)
    assert capsys.readouterr().err == ""  # quiet by default
    monkeypatch.setattr(scan, "SHARE_BYTES", 0)  # every array through the memory maps
    with parallel_config(backend="loky"):  # processes (threads, the default, share memory)
        shared = forecast_error_curve(mg30[:3000], n_jobs=2, progress=True, **kw)
    err = capsys.readouterr().err
    assert "delay scan" in err and "task" in err
    np.testing.assert_array_equal(shared.to_numpy(), ref.to_numpy())
    # chunks of different sizes: numpy's std may round the last bit differently
    np.testing.assert_allclose(shared.attrs["se"].to_numpy(), ref.attrs["se"].to_numpy(),
                               rtol=1e-12)


def test_a_shared_memory_map_pickles_as_its_path_and_a_slice_as_its_data():
    import pickle

    import skdelay._scan as scan

    shared = scan._Shared(True)
    try:
        a = np.random.default_rng(0).normal(size=scan.SHARE_BYTES // 8 + 100)
        mapped = shared(a)
        blob = pickle.dumps(mapped, protocol=5)
        assert len(blob) < 1000  # the path, not the 16 MB of data (Dask would copy them)
        np.testing.assert_array_equal(pickle.loads(blob), a)
        part = pickle.loads(pickle.dumps(mapped[10:20]))
        np.testing.assert_array_equal(part, a[10:20])
        assert not isinstance(part, np.memmap)
        assert shared(a[:10]) is not None and type(shared(a[:10])) is np.ndarray  # small: as is
    finally:
        shared.close()


# ----------------------------------------------------------------------------- searches
@pytest.mark.parametrize("every_point", [False, True])
def test_tree_search_is_the_exact_knn(every_point):
    # unquantised data: no equal distances, so the exact k-NN is unique
    s = measured_mackey_glass(3000, 30, noise=0.01, bits=None, seed=5)
    kw = {"m": (2, 4), "tau": range(1, 41), "n_queries": None if every_point else 300,
          "refine": False, "random_state": 0}
    tree = forecast_error_curve(s, search="tree", **kw)
    exact = forecast_error_curve(s, search="exact", **kw)
    np.testing.assert_allclose(tree.to_numpy(), exact.to_numpy(), rtol=1e-9)
    # every point a query runs the queries in the tree's order: each error still counts in
    # its own time's batch, so the standard errors are those of the exact search
    np.testing.assert_allclose(tree.attrs["se"].to_numpy(), exact.attrs["se"].to_numpy(),
                               rtol=1e-9)
    assert tree.attrs["exact_fraction"] == {2: 1.0, 4: 1.0}
    # the candidate lists miss true neighbours here (what the tree search is for)
    cand = forecast_error_curve(s, search="candidates", **kw)
    assert np.abs(cand.to_numpy() / exact.to_numpy() - 1).max() > 1e-6
    assert min(cand.attrs["exact_fraction"].values()) < 1


def test_tree_search_of_held_out_queries_is_the_exact_knn():
    # queries that are not database times (a time-series split's test fold against its
    # training rows) run in the order of the leaves they descend to, and stay exact
    from skdelay._scan import TREE_LEAF_SIZE, tree_cells, window_components

    s = measured_mackey_glass(1200, 30, noise=0.01, bits=None, seed=5)
    db_t, q_t = np.arange(40, 800), np.arange(840, 1150)
    sq = {}
    for name, queries in (("held_out", q_t), ("one_by_one", None)):
        U = window_components(s, 2, db_t, 2)
        out = np.zeros((1, q_t.size))  # one batch per query: every error on its own
        if queries is not None:
            tree_cells(s, U, queries, db_t, 2, np.array([29]), 6, 3, 1e-3, 1, 0.0,
                       TREE_LEAF_SIZE, out, queries.size)
        else:  # each query alone: no seeds from a neighbour in time
            for i, q in enumerate(q_t):
                one = np.zeros((1, 1))
                tree_cells(s, U, np.array([q]), db_t, 2, np.array([29]), 6, 3, 1e-3, 1,
                           0.0, TREE_LEAF_SIZE, one, 1)
                out[0, i] = one[0, 0]
        sq[name] = out
    np.testing.assert_allclose(sq["held_out"], sq["one_by_one"], rtol=1e-9)


def test_tree_search_stays_exact_on_rough_windows():
    # white noise: the two leading components hold little of a window, so the projected
    # bound is loose -- slower, but the neighbours (and sigma) must not change
    s = np.random.default_rng(3).normal(size=1500)
    kw = {"m": (5,), "tau": range(1, 12), "refine": False, "random_state": 0}
    tree = forecast_error_curve(s, search="tree", **kw)
    exact = forecast_error_curve(s, search="exact", **kw)
    np.testing.assert_allclose(tree.to_numpy(), exact.to_numpy(), rtol=1e-9)


def test_auto_search_is_exact_at_full_precision_and_uses_lists_for_sparse_queries(mg30):
    kw = {"m": (3,), "tau": range(25, 36), "refine": False, "random_state": 0}
    auto = forecast_error_curve(mg30[:3000], **kw)  # every point a query: the tree search
    assert auto.attrs["exact_fraction"] == {3: 1.0}
    np.testing.assert_allclose(
        auto.to_numpy(), forecast_error_curve(mg30[:3000], search="tree", **kw).to_numpy())
    # 10 queries on ~6000 rows and 100 taus: one tree per tau would cost more than the
    # queries (the cost model: 0.12 s of trees against 0.05 s of lists)
    kw["tau"] = range(1, 101)
    sparse = forecast_error_curve(mg30, n_queries=10, **kw)
    lists = forecast_error_curve(mg30, n_queries=10, search="candidates", **kw)
    np.testing.assert_array_equal(sparse.to_numpy(), lists.to_numpy())


@pytest.mark.parametrize("n, n_queries, m", [(6000, 400, (2,)), (3000, None, (3,)),
                                             (30_000, None, (2,)), (6000, 40, (2, 4))])
def test_tree_search_gives_the_plain_trees_result_to_the_last_bit(n, n_queries, m):
    # a series without repeated values: the projected tree finds the plain tree's
    # neighbourhoods, fits them in its order and sums the errors as it does (30 000 queries
    # at m = 2 span two of the plain search's query slices); the gap diagnosis relies on it.
    # 40 queries on 6000 rows read the series itself, not the tree-ordered copy (LOCAL_COPY)
    from skdelay._scan import LOCAL_COPY

    assert (n_queries is not None and LOCAL_COPY * n_queries < n) == (n_queries == 40)
    s = measured_mackey_glass(n, 30, noise=0.05, bits=None, seed=11)
    assert np.unique(s).size == s.size
    kw = {"m": m, "tau": [3, 17, 29, 30, 44], "n_neighbors": 20, "n_queries": n_queries,
          "refine": False, "random_state": 0}
    tree = forecast_error_curve(s, search="tree", **kw)
    exact = forecast_error_curve(s, search="exact", **kw)
    assert np.array_equal(tree.to_numpy(), exact.to_numpy())
    assert np.array_equal(tree.attrs["se"].to_numpy(), exact.attrs["se"].to_numpy())
