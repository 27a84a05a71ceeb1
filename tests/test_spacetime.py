"""Space-time representation and the choice of tau_1 (paper Fig. 1)."""

import numpy as np
import pytest

from skdelay.datasets import load_laser
from skdelay.spacetime import best_space_time_period, space_time


def test_integer_period_is_a_reshape():
    s = np.random.default_rng(0).normal(size=1003)
    st = space_time(s, 50)
    assert st.shape == (20, 50)
    np.testing.assert_array_equal(st, s[:1000].reshape(20, 50))


def test_non_integer_period_interpolates():
    s = np.arange(100.0) * 2.0  # linear: interpolation is exact
    st = space_time(s, 12.5, n_columns=5, start=1.0)
    np.testing.assert_allclose(st[3], 2.0 * (1.0 + 3 * 12.5 + np.arange(5) * 2.5))
    assert st.shape[0] == 8  # last row: 1 + 7*12.5 + 10 = 98.5 <= 99; the next would start at 101


def test_best_period_of_a_pulse_train():
    t = np.arange(8000)
    s = np.exp(-((t % 41.7) - 20.0) ** 2 / 6.0)
    period, scores = best_space_time_period(s, np.arange(40.0, 43.0, 0.1))
    assert period == pytest.approx(41.7, abs=0.051)
    assert scores.index.name == "period" and scores.max() > 0.99
    assert scores.idxmax() == period


def test_best_period_on_laser_data_exceeds_the_delay():
    # the coherent structures of Fig. 1 need tau_1 slightly above tau_0
    s = load_laser(150, n_samples=20_000, cache=False).series
    period, scores = best_space_time_period(s, np.arange(140.0, 170.0, 0.5))
    assert 150.0 < period <= 162.0, period  # measured 157.5
    assert scores[period] > scores[150.0] + 0.05


def test_bad_periods():
    s = np.sin(np.arange(100.0))
    with pytest.raises(ValueError, match="at least 2 samples"):
        space_time(s, 1.5)
    with pytest.raises(ValueError, match="fewer than 2 delay units"):
        space_time(s, 60)
    with pytest.raises(TypeError, match="number of samples"):
        space_time(s, "50")
    with pytest.raises(ValueError, match="NaN"):
        space_time(np.r_[s, np.nan], 10)
    with pytest.raises(ValueError, match="candidates is empty"):
        best_space_time_period(s, [])
