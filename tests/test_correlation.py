import numpy as np
import pytest

from skdelay._correlation import autocorrelation, mutual_information, revival_peak


def test_autocorrelation_matches_direct_sum():
    s = np.random.default_rng(0).normal(size=500).cumsum()
    acf = autocorrelation(s, 40)
    x = s - s.mean()
    direct = np.array([np.dot(x[: x.size - lag], x[lag:]) for lag in range(41)]) / np.dot(x, x)
    np.testing.assert_allclose(acf, direct, atol=1e-12)
    assert acf[0] == pytest.approx(1.0)


def test_mutual_information_gaussian_ar1():
    rng = np.random.default_rng(1)
    rho, n = 0.8, 200_000
    e = rng.normal(size=n)
    s = np.empty(n)
    s[0] = e[0]
    for i in range(1, n):
        s[i] = rho * s[i - 1] + np.sqrt(1 - rho**2) * e[i]
    mi = mutual_information(s, 3, n_bins=32)
    exact = -0.5 * np.log(1 - rho ** (2 * np.arange(1, 4)))  # Gaussian I(lag)
    np.testing.assert_allclose(mi[1:], exact, rtol=0.1)
    p = np.histogram(s, bins=32)[0] / n
    assert mi[0] == pytest.approx(-np.sum(p[p > 0] * np.log(p[p > 0])), rel=1e-9)


def test_revival_peak_of_sine_and_noise_robustness():
    t = np.arange(2000)
    s = np.sin(2 * np.pi * t / 37) + 0.05 * np.random.default_rng(2).normal(size=t.size)
    assert revival_peak(autocorrelation(s, 100)) == 37
    assert revival_peak(mutual_information(s, 60)) in (18, 19)  # s_{t+T/2} = -s_t: MI revives
    assert revival_peak(np.array([5.0, 3, 1, 2, 4, 3, 1])) == 4
    assert revival_peak(np.array([5.0, 3, 1, 1.01, 0.9, 4, 3]), prominence=0.5) == 5


def test_bad_inputs():
    with pytest.raises(ValueError, match="max_lag"):
        autocorrelation(np.arange(10.0), 10)
    with pytest.raises(ValueError, match="constant"):
        mutual_information(np.ones(10), 2)
    with pytest.raises(ValueError, match="larger lag"):
        revival_peak(np.linspace(1, 0, 20))
    with pytest.raises(ValueError, match="finite"):
        revival_peak([1.0, np.nan, 2.0, 1.0])
