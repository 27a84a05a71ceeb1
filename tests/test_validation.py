"""Global validation: cross-prediction error, histogram/spectrum/ACF distances, revivals."""

import numpy as np
import pandas as pd
import pytest

from skdelay._selection import forecast_error_curve
from skdelay.datasets import load_laser
from skdelay.systems import MackeyGlass
from skdelay.validation import (
    Comparison,
    autocorrelation,
    autocorrelation_distance,
    cross_prediction_by_region,
    cross_prediction_error,
    histogram_distance,
    mutual_information,
    power_spectrum,
    spectrum_distance,
    value_histogram,
)

N = 20_000
Q = 2000


@pytest.fixture(scope="module")
def mg():
    sys = MackeyGlass(tau=17.0)
    return {
        "x": sys.simulate(N, random_state=0),
        "same": [sys.simulate(N, random_state=s) for s in (1, 2)],
        "tau23": MackeyGlass(tau=23.0).simulate(N, random_state=1),
        "b011": sys.simulate(N, random_state=1, b=0.11),
    }


@pytest.mark.parametrize("order", [0, 1])
def test_chi_xx_is_the_core_forecast_error(order):
    x = MackeyGlass(tau=17.0).simulate(4000, random_state=3)
    chi = cross_prediction_error(x, m=3, tau=17, order=order, theiler_window=20,
                                 n_queries=800, random_state=5)
    fe = forecast_error_curve(x, m=(3,), tau=(17,), order=order, theiler_window=20,
                              n_queries=800, random_state=5, search="exact")
    assert chi == pytest.approx(float(fe.iloc[0, 0]), rel=1e-10)


def test_chi_same_system_other_seed_within_ten_percent(mg):
    chi_xx = cross_prediction_error(mg["x"], m=3, tau=17, n_queries=Q, random_state=0)
    for y in mg["same"]:
        chi_xy = cross_prediction_error(mg["x"], y, m=3, tau=17, n_queries=Q, random_state=0)
        # measured ratios 0.995 and 0.977 (chi_xx = 0.0098, order 0, k = 30)
        assert abs(chi_xy / chi_xx - 1) < 0.10, (chi_xy, chi_xx)


def test_chi_other_delay_or_parameter_is_clearly_larger(mg):
    chi_xx = cross_prediction_error(mg["x"], m=3, tau=17, n_queries=Q, random_state=0)
    chi_tau = cross_prediction_error(mg["x"], mg["tau23"], m=3, tau=17, n_queries=Q,
                                     random_state=0)
    chi_b = cross_prediction_error(mg["x"], mg["b011"], m=3, tau=17, n_queries=Q,
                                   random_state=0)
    assert chi_tau > 5 * chi_xx, (chi_tau, chi_xx)  # measured 16x
    assert chi_b > 5 * chi_xx, (chi_b, chi_xx)  # measured 11x


def test_cross_prediction_by_region(mg):
    x, y = mg["x"], mg["tau23"]
    where = cross_prediction_by_region(x, y, m=3, tau=17, n_regions=3, n_queries=Q,
                                       random_state=0)
    assert list(where.columns) == ["low", "high", "delayed_low", "delayed_high", "count",
                                   "chi", "chi_self", "excess"]
    assert len(where) == 9 and where["count"].sum() == Q
    assert where["excess"].is_monotonic_decreasing
    assert where["low"].min() == pytest.approx(x[16:-1].min())  # in x's units
    # the cells recombine to the global errors
    chi = cross_prediction_error(x, y, m=3, tau=17, n_queries=Q, random_state=0)
    pooled = np.sqrt((where["count"] * where["chi"] ** 2).sum() / Q)
    assert pooled == pytest.approx(chi, rel=1e-10)
    assert (where["excess"] > 0).all()  # a tau=23 model fails everywhere
    same = cross_prediction_by_region(x, mg["same"][0], m=3, tau=17, n_regions=3,
                                      n_queries=Q, random_state=0)
    assert same["excess"].abs().max() < 0.2 * where["excess"].max()


def test_cross_prediction_bad_input():
    x = MackeyGlass(tau=17.0).simulate(500, random_state=0)
    bad = x.copy()
    bad[3] = np.inf
    with pytest.raises(ValueError, match="NaN or infinite"):
        cross_prediction_error(bad, m=2, tau=17)
    with pytest.raises(ValueError, match="NaN or infinite"):
        cross_prediction_error(x, bad, m=2, tau=17)
    with pytest.raises(ValueError, match="constant"):
        cross_prediction_error(np.ones(500), m=2, tau=17)
    with pytest.raises(ValueError, match="at least"):
        cross_prediction_error(x[:10], m=2, tau=17)
    with pytest.raises(ValueError, match="theiler_window"):
        cross_prediction_error(x, m=2, tau=17, theiler_window=300)
    with pytest.raises(ValueError, match="pass y"):
        cross_prediction_by_region(x, None, m=2, tau=17)


def test_histogram_distance_known_value():
    rng = np.random.default_rng(0)
    x = rng.uniform(0.0, 1.0, 200_000)
    y = rng.uniform(0.5, 1.5, 200_000)
    cmp = histogram_distance(x, y, bins=30)
    assert isinstance(cmp, Comparison)
    # Hellinger^2 = 1 - sum sqrt(p q) = 1 - 1/2 exactly for these two uniforms
    assert cmp.distance == pytest.approx(np.sqrt(0.5), abs=0.01)
    tv = histogram_distance(x, y, bins=30, metric="total_variation")
    assert tv.distance == pytest.approx(0.5, abs=0.01)
    assert list(cmp.where.columns) == ["low", "high", "x_value", "y_value", "excess"]
    top = cmp.where.iloc[:20]  # the non-overlapping parts lead, +1 for x below 0.5, -1 above 1
    assert ((top["high"] <= 0.5 + 1e-3) | (top["low"] >= 1.0 - 1e-3)).all()
    assert top["excess"].abs().min() == pytest.approx(1.0, abs=0.05)
    assert histogram_distance(x, rng.uniform(0, 1, 200_000), bins=30).distance < 0.01


def test_histogram_distance_normalised_ignores_gain_and_offset():
    rng = np.random.default_rng(1)
    x = rng.normal(3.0, 2.0, 50_000)
    cmp = histogram_distance(x, 10.0 * x - 7.0, normalise=True)
    assert cmp.distance < 1e-12
    assert cmp.where["low"].min() == pytest.approx(x.min())  # bounds in x's units
    assert histogram_distance(x, 10.0 * x - 7.0).distance > 0.5


def test_value_histogram_and_power_spectrum():
    rng = np.random.default_rng(2)
    x = rng.normal(size=50_000)
    edges, dens = value_histogram(x, bins=40)
    assert np.sum(dens * np.diff(edges)) == pytest.approx(1.0)
    dt = 0.5
    t = np.arange(2 ** 15) * dt
    s = np.sin(2 * np.pi * 0.2 * t) + 0.1 * rng.normal(size=t.size)
    f, p = power_spectrum(s, sample_dt=dt, nperseg=2048)
    assert f[-1] == pytest.approx(1 / (2 * dt))
    assert f[np.argmax(p)] == pytest.approx(0.2, abs=f[1])
    assert np.sum(p) * f[1] == pytest.approx(s.var(), rel=0.03)  # Parseval


def test_spectrum_distance_finds_the_band():
    rng = np.random.default_rng(3)
    t = np.arange(50_000) * 2.0  # sample_dt = 2 time units
    noise = rng.normal(size=(2, t.size))
    x = noise[0] + np.sin(2 * np.pi * 0.1 * t)
    y = noise[1]
    cmp = spectrum_distance(x, y, sample_dt=2.0, nperseg=1024, n_bands=25)
    top = cmp.where.iloc[0]
    assert top["low"] <= 0.1 <= top["high"]  # cycles per time unit
    assert top["excess"] > 0.3
    assert cmp.where["high"].max() == pytest.approx(0.25, abs=0.001)
    assert spectrum_distance(x, 5.0 * x, sample_dt=2.0).distance < 1e-10  # gain is ignored
    assert spectrum_distance(x, 5.0 * x, sample_dt=2.0, normalise=False).distance == \
        pytest.approx(np.log10(25.0))


def test_autocorrelation_distance(mg):
    x = mg["x"]
    same = autocorrelation_distance(x, mg["same"][0], max_lag=100)
    other = autocorrelation_distance(x, mg["tau23"], max_lag=100)
    assert same.distance < 0.05 and other.distance > 0.2
    assert other.distance > 5 * same.distance
    assert other.where["low"].min() == 1.0 and other.where["high"].max() == 100.0
    np.testing.assert_allclose(
        autocorrelation_distance(x, x, max_lag=50, sample_dt=0.5).where["high"].max(), 25.0)


@pytest.mark.parametrize("delay", [50, 150])
def test_revival_peaks_lie_beyond_the_delay_on_laser_data(delay):
    # paper Sec. III/IV: the marked ACF/MI revivals lie slightly beyond the delay (58 for
    # 50, 157 for 150: the laser's response time).  The marked revival is the largest
    # maximum beyond half the delay (the curves also carry the ~25-sample Hopf
    # oscillation).  Measured on the embedded data: 62 and 162 for both curves.
    s = load_laser(delay, n_samples=20_000, cache=False).series
    acf = autocorrelation(s, 3 * delay)
    mi = mutual_information(s, 3 * delay)
    start = delay // 2
    lag_acf = start + int(np.argmax(acf[start:]))
    lag_mi = start + int(np.argmax(mi[start:]))
    for lag in (lag_acf, lag_mi):
        assert delay < lag <= delay + 15, (lag_acf, lag_mi)
    # both are genuine local maxima standing out of the curve
    for curve, lag in ((acf, lag_acf), (mi, lag_mi)):
        assert curve[lag] > curve[lag - 3] and curve[lag] > curve[lag + 3]


def test_comparison_is_frozen():
    cmp = Comparison(0.1, pd.DataFrame())
    with pytest.raises(AttributeError):
        cmp.distance = 0.2
