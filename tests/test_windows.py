import numpy as np
import pytest

from skdelay._windows import lagged_windows, series_from_lagged


def test_lagged_windows_alignment_and_view():
    s = np.arange(10.0)
    X, y = lagged_windows(s, 4)
    assert X.shape == (6, 4)
    t = np.arange(6) + 3
    np.testing.assert_array_equal(X, s[t[:, None] - np.arange(4)])
    np.testing.assert_array_equal(y, s[t + 1])
    assert np.shares_memory(X, s) and np.shares_memory(y, s)
    assert not X.flags.writeable and not y.flags.writeable
    with pytest.raises(ValueError):
        X[0, 0] = 1.0


def test_lagged_windows_horizon_and_lists():
    X, y = lagged_windows([1.0, 2, 3, 4, 5, 6], 2, horizon=3)
    np.testing.assert_array_equal(X, [[2, 1], [3, 2]])
    np.testing.assert_array_equal(y, [5, 6])


def test_lagged_windows_large_is_cheap():
    s = np.random.default_rng(0).normal(size=200_000)
    X, _ = lagged_windows(s, 500)
    assert X.shape == (199_500, 500)
    assert X.base is not None and np.shares_memory(X, s)


@pytest.mark.parametrize(
    ("series", "n_lags", "kwargs", "match"),
    [
        ([0.0, np.nan, 1.0, 2.0], 1, {}, "NaN"),
        ([0.0, np.inf, 1.0, 2.0], 1, {}, "NaN or infinite"),
        (np.ones((5, 2)), 1, {}, "1-D"),
        (np.ones(5), 1, {}, "constant"),
        (np.arange(5.0), 5, {}, "smaller than the series length"),
        (np.arange(5.0), 4, {"horizon": 2}, "at least 6 samples"),
        (np.arange(5.0), 0, {}, "n_lags must be >= 1"),
    ],
)
def test_lagged_windows_errors(series, n_lags, kwargs, match):
    with pytest.raises(ValueError, match=match):
        lagged_windows(series, n_lags, **kwargs)


def test_lagged_windows_type_errors():
    with pytest.raises(TypeError, match="integer"):
        lagged_windows(np.arange(5.0), 2.5)
    with pytest.raises(TypeError, match="numbers"):
        lagged_windows(np.array(["a", "b", "c"]), 1)


def test_series_from_lagged_roundtrip_and_rejects():
    s = np.random.default_rng(1).normal(size=300)
    X, y = lagged_windows(s, 12)
    np.testing.assert_array_equal(series_from_lagged(X, y), s)
    np.testing.assert_array_equal(series_from_lagged(X[50:], y[50:]), s[50:])
    assert series_from_lagged(X[::-1], y[::-1]) is None
    bad = np.array(X)
    bad[100, 5] += 1e-9
    assert series_from_lagged(bad, y) is None
    assert series_from_lagged(X, y + 1.0) is None
