import numpy as np
import pandas as pd
import pytest
from sklearn.pipeline import Pipeline

from skdelay._embedding import TwoWindowEmbedding, required_lags, two_window_columns
from skdelay._local_linear import LocalLinearDelayMap
from skdelay._windows import lagged_windows


@pytest.mark.parametrize(
    ("m", "tau", "expected"),
    [
        (2, 17, [0, 1, 16, 17]),  # (s_t, s_t-1, s_t+1-tau, s_t-tau)
        (3, 17, [0, 1, 2, 15, 16, 17]),
        (4, 17, [0, 1, 2, 3, 15, 16, 17, 18]),
        (5, 17, [0, 1, 2, 3, 4, 14, 15, 16, 17, 18]),
        (1, 17, [0, 16]),
        (2, 1, [0, 1, 0, 1]),  # overlapping windows: tau <= (m - 1) // 2 + 1
        (5, 2, [0, 1, 2, 3, 4, 0, 1, 2, 3, 4]),
    ],
)
def test_columns_convention(m, tau, expected):
    cols = two_window_columns(m, tau)
    assert cols.tolist() == expected
    assert required_lags(m, tau) == max(expected) + 1 == max(tau + m // 2, m)


def test_every_window_holds_the_delayed_pair():
    # the second window always contains lags tau - 1 and tau (s_{t+1-tau}, s_{t-tau})
    for m in range(2, 9):
        for tau in range(m, 60):
            second = two_window_columns(m, tau)[m:]
            assert {tau - 1, tau} <= set(second.tolist())
            assert np.all(np.diff(second) == 1)


def test_transform_selects_series_samples():
    s = np.random.default_rng(0).normal(size=200)
    X, _ = lagged_windows(s, 30)
    V = TwoWindowEmbedding(m=3, tau=20).fit_transform(X)
    t = np.arange(X.shape[0]) + 29
    lags = [0, 1, 2, 18, 19, 20]
    np.testing.assert_array_equal(V, s[t[:, None] - lags])
    assert V.shape == (X.shape[0], 6)


def test_stateless_and_feature_names():
    X, _ = lagged_windows(np.arange(40.0) ** 1.5, 12)
    emb = TwoWindowEmbedding(m=2, tau=10)
    np.testing.assert_array_equal(emb.transform(X), X[:, [0, 1, 9, 10]])  # no fit needed
    assert emb.__sklearn_tags__().requires_fit is False
    df = pd.DataFrame(np.asarray(X), columns=[f"lag{i}" for i in range(12)])
    emb.fit(df)
    assert emb.get_feature_names_out().tolist() == ["lag0", "lag1", "lag9", "lag10"]
    assert TwoWindowEmbedding(2, 3).get_feature_names_out(
        [f"a{i}" for i in range(5)]).tolist() == ["a0", "a1", "a2", "a3"]


def test_too_few_lags_says_how_many():
    X, _ = lagged_windows(np.arange(50.0) ** 2, 10)
    with pytest.raises(ValueError, match=r"needs at least 12.*n_lags=12"):
        TwoWindowEmbedding(m=4, tau=10).fit(X)
    with pytest.raises(ValueError, match="n_lags=12"):
        TwoWindowEmbedding(m=4, tau=10).transform(X)


@pytest.mark.parametrize("bad", [{"m": 0}, {"tau": 0}, {"m": 2.5}])
def test_bad_parameters(bad):
    X, _ = lagged_windows(np.arange(50.0) ** 2, 10)
    with pytest.raises((ValueError, TypeError)):
        TwoWindowEmbedding(**bad).fit(X)


def test_overlapping_windows_in_a_pipeline():
    rng = np.random.default_rng(1)
    s = np.cumsum(rng.normal(size=600))
    X, y = lagged_windows(s, 5)
    for m, tau in [(2, 1), (3, 1), (5, 2), (4, 3)]:
        pipe = Pipeline([("emb", TwoWindowEmbedding(m=m, tau=tau)),
                         ("model", LocalLinearDelayMap(n_neighbors=15))]).fit(X, y)
        assert np.all(np.isfinite(pipe.predict(X)))
