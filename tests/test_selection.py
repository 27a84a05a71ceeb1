"""Delay selection on simulated Mackey-Glass data and the scan machinery."""

import numpy as np
import pandas as pd
import pytest
from _dde import measured_mackey_glass
from joblib import parallel_config
from sklearn.model_selection import GridSearchCV, TimeSeriesSplit
from sklearn.neighbors import KNeighborsRegressor
from sklearn.pipeline import Pipeline

from skdelay._correlation import autocorrelation, mutual_information, revival_peak
from skdelay._embedding import TwoWindowEmbedding, required_lags
from skdelay._local_linear import LocalLinearDelayMap
from skdelay._scan import ScanOptions, scan_series
from skdelay._selection import (
    DelaySelectorCV,
    forecast_error_curve,
    locate_dips,
    theiler_from,
)
from skdelay._windows import lagged_windows

N_MG = 10_000  # samples of every simulated record
N_QUERIES = 2_000


@pytest.fixture(scope="module")
def mg30():
    return measured_mackey_glass(N_MG, 30, seed=0)


@pytest.mark.parametrize("delay", [17, 30, 100])
def test_delay_of_mackey_glass_within_one_sample(delay):
    # 0.5 % measurement noise, 12-bit ADC, sample step 1, a=0.2, b=0.1, n=10
    s = measured_mackey_glass(N_MG, delay, seed=1)
    taus = range(delay - 15, delay + 16)
    X, y = lagged_windows(s, required_lags(5, taus[-1]))
    sel = DelaySelectorCV(m=(2, 3, 4, 5), tau=taus, n_queries=N_QUERIES, random_state=0).fit(X, y)
    dips = sel.delay_by_m_
    assert list(dips.index) == [2, 3, 4, 5]
    np.testing.assert_array_less(np.abs(dips["delay"] - delay), 1.0)  # every m: dip at T0
    assert abs(sel.delay_ - delay) < 1.0
    assert 0.5 <= sel.delay_error_ <= 6
    assert abs(sel.best_params_["tau"] - delay) <= 1
    # the dip is a real feature: well below the error away from the delay
    fe = sel.forecast_error_
    assert np.all(fe.min() < 0.9 * fe.median())
    # ACF / MI revival peaks lie later than the delay (response time of the system)
    acf_peak = revival_peak(autocorrelation(s, 3 * delay + 60))
    mi_peak = revival_peak(mutual_information(s, 3 * delay + 60))
    assert acf_peak > delay + 2 and mi_peak > delay + 2


def test_grid_search_over_tau_finds_the_delay(mg30):
    X, y = lagged_windows(mg30, 40)
    pipe = Pipeline([("embedding", TwoWindowEmbedding(m=2)),
                     ("model", LocalLinearDelayMap(n_neighbors=30))])
    search = GridSearchCV(pipe, {"embedding__tau": list(range(24, 37))},
                          cv=TimeSeriesSplit(n_splits=3)).fit(X, y)
    assert abs(search.best_params_["embedding__tau"] - 30) <= 1


def test_delay_selector_with_time_series_split(mg30):
    X, y = lagged_windows(mg30, required_lags(3, 45))
    sel = DelaySelectorCV(m=(2, 3), tau=range(15, 46), cv=3, n_queries=800,
                          random_state=0).fit(X, y)
    assert sel.n_splits_ == 3
    assert np.all(np.abs(sel.delay_by_m_["delay"] - 30) < 1.0)
    res = sel.cv_results_
    n_cand = 2 * 31
    for key in ("mean_test_score", "std_test_score", "rank_test_score", "param_m",
                "param_tau", "split0_test_score", "split2_test_score"):
        assert len(res[key]) == n_cand
    assert len(res["params"]) == n_cand
    best_rank = res["params"][int(np.argmin(res["rank_test_score"]))]
    assert abs(best_rank["tau"] - 30) <= 1
    assert res["params"][sel.best_index_] == sel.best_params_
    assert sel.best_score_ == res["mean_test_score"][sel.best_index_] < 0
    pred = sel.predict(X[:100])
    assert np.sqrt(np.mean((pred - y[:100]) ** 2)) < 0.05
    assert sel.score(X, y) > 0.99


@pytest.mark.parametrize("noise", [0.01, 0.05])
def test_noise_floor(noise):
    # measured ratio min sigma / noise: 1.22-1.36 (noise on the target plus the
    # noise carried through the local map's coefficients)
    s = measured_mackey_glass(N_MG, 30, noise=noise, bits=None, seed=2)
    fe = forecast_error_curve(s, m=(2, 4), tau=range(26, 35), n_queries=N_QUERIES,
                              random_state=0)
    ratio = fe.min() / noise
    assert np.all((ratio > 1.0) & (ratio < 1.6)), ratio


def test_candidate_search_is_exact_with_all_candidates(mg30):
    s = mg30[:800]
    db = np.arange(required_lags(3, 40) - 1, s.size - 1)
    q = db[::5]
    taus = np.array([1, 5, 29, 30, 31, 40])
    for theiler, queries in [(5, q), (None, q[q > 500])]:
        db_use = db if theiler is not None else db[db < 500]
        split = [(db_use, None if theiler is not None else queries)]
        kw = {"k": 12, "theiler": theiler or 0, "refine": False,
              "n_queries": queries.size if theiler is not None else None}
        ex = scan_series(s, [3], taus, split, ScanOptions(search="exact", **kw),
                         random_state=0)
        full = scan_series(s, [3], taus, split, ScanOptions(n_candidates=db.size, **kw),
                           random_state=0)
        np.testing.assert_allclose(full.error, ex.error, rtol=1e-10)
        np.testing.assert_allclose(full.se, ex.se, rtol=1e-8)
        assert np.all(full.exact == 1.0)


def test_candidate_search_close_to_exact(mg30):
    taus = range(20, 41, 2)
    kw = {"m": (2, 4), "tau": taus, "n_queries": 1000, "random_state": 0}
    fast = forecast_error_curve(mg30, **kw)
    exact = forecast_error_curve(mg30, search="exact", **kw)
    assert np.all(np.abs(fast / exact - 1) < 0.12)
    assert np.all(np.abs(fast.min() / exact.min() - 1) < 0.05)
    assert all(0 <= v <= 1 for v in fast.attrs["exact_fraction"].values())
    radius = forecast_error_curve(mg30, m=(2,), tau=(30,), n_queries=500, random_state=0,
                                  radius=0.05)
    radius_exact = forecast_error_curve(mg30, m=(2,), tau=(30,), n_queries=500, random_state=0,
                                        radius=0.05, search="exact")
    assert radius.iloc[0, 0] == pytest.approx(radius_exact.iloc[0, 0], rel=0.1)


def test_lag_matrix_and_column_paths_agree(mg30):
    s = mg30[:1200]
    X, y = lagged_windows(s, required_lags(3, 33))
    est = LocalLinearDelayMap(n_neighbors=10)
    ms, taus = np.array([2, 3]), np.array([28, 30, 33])
    for cv in (None, TimeSeriesSplit(n_splits=2)):
        sel = DelaySelectorCV(est, m=ms, tau=taus, cv=cv, search="exact", theiler_window=4)
        splits = sel._splits(X, y)
        w = 4 if cv is None else None
        by_columns, se_columns = sel._scan_columns(X, y, ms, taus, splits, est, w)
        L = X.shape[1]
        res = scan_series(
            s, ms, taus, [(tr + L - 1, None if te is None else te + L - 1) for tr, te in splits],
            ScanOptions(k=10, theiler=4, search="exact"), random_state=0)
        np.testing.assert_allclose(res.error, by_columns, rtol=1e-10)
        np.testing.assert_allclose(res.se, se_columns, rtol=1e-8)


def test_non_lag_matrix_input_and_other_regressors(mg30):
    X, y = lagged_windows(mg30[:3000], 35)
    perm = np.random.default_rng(0).permutation(X.shape[0])
    sel = DelaySelectorCV(m=(2,), tau=range(26, 35), random_state=0).fit(X[perm], y[perm])
    assert abs(sel.delay_ - 30) <= 1.5  # Theiler window counts rows here, not time
    knn = DelaySelectorCV(KNeighborsRegressor(5), m=(2,), tau=range(26, 35), cv=2).fit(X, y)
    assert knn.forecast_error_.shape == (9, 1)
    with pytest.raises(ValueError, match="LocalLinearDelayMap"):
        DelaySelectorCV(KNeighborsRegressor(), m=2, tau=3).fit(X, y)
    with pytest.raises(ValueError, match="equal_neighbourhood"):
        DelaySelectorCV(m=(2, 3), tau=3, equal_neighbourhood=True).fit(X[perm], y[perm])


def test_equal_neighbourhood(mg30):
    kw = {"m": (2, 3, 5), "tau": range(26, 35), "n_queries": 600, "random_state": 0}
    seg = forecast_error_curve(mg30, equal_neighbourhood=True, **kw)
    lengths = seg.attrs["segment_length"]
    assert lengths[2] < lengths[3] < lengths[5] == mg30.size - required_lags(5, 34)
    assert np.all(np.abs(locate_dips(seg)["delay"] - 30) < 1.5)
    rad = forecast_error_curve(mg30, equal_neighbourhood="radius", **kw)
    assert rad.attrs["radius"] > 0 and np.all(np.isfinite(rad))
    assert np.all(np.abs(locate_dips(rad)["delay"] - 30) < 1.5)


def test_n_jobs_and_dask_give_the_same_table(mg30, monkeypatch):
    kw = {"m": (2, 3), "tau": range(27, 34), "n_queries": 300, "random_state": 0}
    ref = forecast_error_curve(mg30[:4000], **kw)
    # threads by default; processes (memory-mapped lists) when the user asks for loky
    pd.testing.assert_frame_equal(forecast_error_curve(mg30[:4000], n_jobs=2, **kw), ref)
    with parallel_config(backend="loky"):
        pd.testing.assert_frame_equal(forecast_error_curve(mg30[:4000], n_jobs=2, **kw), ref)
    distributed = pytest.importorskip("distributed")
    pytest.importorskip("dask")
    client = distributed.Client(processes=False, n_workers=1, threads_per_worker=2,
                                dashboard_address=None)
    import skdelay._scan as scan

    monkeypatch.setattr(scan, "SHARE_BYTES", 0)  # every array goes out as a memory map
    with client, parallel_config(backend="dask"):
        dask_table = forecast_error_curve(mg30[:4000], n_jobs=2, **kw)
    pd.testing.assert_frame_equal(dask_table, ref)


def test_locate_dips_definition():
    values = [10.0, 10, 9, 6, 3, 6, 9, 10, 10]
    curve = pd.DataFrame({2: values, 3: values}, index=pd.Index(range(1, 10), name="tau"))
    dips = locate_dips(curve, level=0.5)
    assert dips.loc[2, "delay"] == pytest.approx(5.0)
    assert dips.loc[3, "delay"] == pytest.approx(4.5)  # odd m: half a sample earlier
    assert dips.loc[2, "half_width"] == pytest.approx(1.0)  # level 6: crossings at 4 and 6
    assert dips.loc[2, "tau_min"] == 5 and dips.loc[2, "min_error"] == 3.0
    flat = locate_dips(pd.DataFrame({2: [1.0, 1.0, 1.0]}, index=[4, 5, 6]))
    assert flat.loc[2, "half_width"] >= 0.5
    with pytest.raises(ValueError, match="level"):
        locate_dips(curve, level=0.0)


def test_theiler_auto_is_decorrelation_time(mg30):
    w = theiler_from(mg30, "auto")
    acf = autocorrelation(mg30, 100)
    assert acf[w] < np.exp(-1) <= acf[w - 1]
    assert theiler_from(mg30, 7) == 7
    with pytest.raises(ValueError, match="auto"):
        theiler_from(mg30, "none")


@pytest.mark.parametrize(
    ("series", "kwargs", "match"),
    [
        (np.r_[np.nan, np.arange(500.0)], {}, "NaN"),
        (np.ones(500), {}, "constant"),
        (np.ones((300, 2)), {}, "1-D"),
        (np.arange(60.0) ** 1.5, {"tau": 80}, "needs"),
        (np.arange(500.0) ** 1.5, {"tau": [0, 3]}, "positive integers"),
        (np.arange(500.0) ** 1.5, {"m": []}, "empty"),
        (np.arange(500.0) ** 1.5, {"tau": 5, "search": "kd"}, "search"),
        (np.arange(500.0) ** 1.5, {"tau": 5, "equal_neighbourhood": "x"}, "equal_neighbourhood"),
        (np.arange(500.0) ** 1.5, {"tau": 5, "n_queries": 0}, "n_queries"),
    ],
)
def test_forecast_error_curve_bad_input(series, kwargs, match):
    with pytest.raises(ValueError, match=match):
        forecast_error_curve(series, **kwargs)


def test_delay_selector_bad_input(mg30):
    X, y = lagged_windows(mg30[:500], 20)
    with pytest.raises(ValueError,
                       match=r"needs 31; build X with lagged_windows\(series, n_lags=31\)"):
        DelaySelectorCV(m=(2, 3), tau=30).fit(X, y)
    Xn = np.array(X)
    Xn[3, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        DelaySelectorCV(m=2, tau=5).fit(Xn, y)
    with pytest.raises(ValueError, match="sample"):
        DelaySelectorCV(m=2, tau=5).fit(X[:2], y[:2])


@pytest.mark.parametrize(("params", "name"), [
    ({"search": "kd"}, "search"), ({"dip_level": 0.0}, "dip_level"), ({"refine": "yes"}, "refine"),
    ({"n_queries": 0}, "n_queries"), ({"theiler_window": -1}, "theiler_window"),
    ({"equal_neighbourhood": "all"}, "equal_neighbourhood"), ({"n_candidates": 0}, "n_candidates"),
    ({"estimator": "knn"}, "estimator"), ({"random_state": "x"}, "random_state"),
    ({"progress": 2}, "progress"), ({"m": 0}, "m"),
])
def test_delay_selector_refuses_a_bad_parameter_before_any_work(mg30, params, name, monkeypatch):
    # declared in _parameter_constraints and checked first: "search" and "n_candidates" were
    # checked only on the local-model path, "dip_level" only after the whole scan
    import skdelay._selection as sel

    def no_scan(*args, **kwargs):
        raise AssertionError("the scan started")

    monkeypatch.setattr(sel, "scan_series", no_scan)
    X, y = lagged_windows(mg30[:500], 20)
    with pytest.raises(ValueError, match=f"The '{name}' parameter of DelaySelectorCV"):
        DelaySelectorCV(**{"m": 2, "tau": 5, **params}).fit(X, y)


def test_delay_selector_takes_every_documented_parameter_value(mg30):
    X, y = lagged_windows(mg30[:3000], 40)
    for params in ({"equal_neighbourhood": "segment", "theiler_window": 0},
                   {"random_state": np.random.default_rng(0), "search": "exact"},
                   {"cv": 3, "estimator": LocalLinearDelayMap(n_neighbors=20)}):
        sel = DelaySelectorCV(m=2, tau=range(24, 37), **params).fit(X, y)
        assert abs(sel.delay_ - 30) <= 1, (params, sel.delay_)
