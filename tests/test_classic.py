"""Classic (Takens-style) cross-check tools against textbook values.

Reference values:
- Hénon (a=1.4, b=0.3): D2 = 1.21 (Grassberger & Procaccia 1983), lambda_1 = 0.419.
- Mackey-Glass tau=23: D2 ~ 2.44 (Grassberger & Procaccia 1983).
- Lorenz (10, 28, 8/3): lambda_1 = 0.906 per time unit.
- Mackey-Glass tau=17: lambda_1 = 0.0054 per time unit, from the exact tangent
  dynamics ``MackeyGlass(tau=17).lyapunov_spectrum(2, random_state=0)``
  (0.00539 +- 0.00023; 17 s, so not recomputed here).
"""

import numpy as np
import pytest

from skdelay._testing_maps import henon, lorenz
from skdelay.classic import (
    correlation_dimension,
    correlation_sum,
    delay_embedding,
    false_nearest_neighbors,
    maximal_lyapunov_exponent,
    noise_reduction,
    poincare_section,
)
from skdelay.systems import MackeyGlass

LAMBDA_LORENZ = 0.906
LAMBDA_MG17 = 0.0054


@pytest.fixture(scope="module")
def henon_series():
    return henon(10_000, random_state=0)


@pytest.fixture(scope="module")
def lorenz_series():
    return lorenz(100_000, sample_dt=0.02, random_state=0)


def test_delay_embedding_is_a_readonly_view():
    s = np.arange(20.0)
    X = delay_embedding(s, 3, 4)
    assert X.shape == (12, 3)
    np.testing.assert_array_equal(X[5], [5.0, 9.0, 13.0])
    assert np.shares_memory(X, s)
    assert not X.flags.writeable


def test_poincare_section_interpolates_the_maxima():
    dt = 0.3  # coarse: the raw sample maxima miss the peaks by up to 1 - cos(0.15)
    t = np.arange(0, 200, dt)
    times, values = poincare_section(3.0 * np.sin(t) + 1.0, sample_dt=dt)
    k = np.arange(times.size)
    np.testing.assert_allclose(times, np.pi / 2 + 2 * np.pi * k, atol=2e-3)
    np.testing.assert_allclose(values, 4.0, atol=3e-3)
    raw_error = np.max(np.abs(3.0 * np.sin(np.round(times / dt) * dt) + 1.0 - 4.0))
    assert raw_error > 5 * np.max(np.abs(values - 4.0))
    _, minima = poincare_section(np.sin(t), sample_dt=dt, kind="minima")
    np.testing.assert_allclose(minima, -1.0, atol=1e-3)


def test_noise_reduction_on_noisy_henon(henon_series):
    clean = henon_series
    noisy = clean + 0.05 * clean.std() * np.random.default_rng(1).normal(size=clean.size)
    cleaned = noise_reduction(noisy, dim=7, q=2, iterations=3, n_neighbors=30)
    factor = np.std(noisy - clean) / np.std(cleaned - clean)
    assert factor >= 3.0, factor  # measured 3.9


def test_correlation_sum_matches_brute_force():
    s = henon(600, random_state=3)
    X = delay_embedding(s, 2, 1)
    radii = np.array([0.01, 0.05, 0.2, 1.0])
    w = 3
    d = np.max(np.abs(X[:, None, :] - X[None, :, :]), axis=2)
    i, j = np.indices(d.shape)
    far = np.abs(i - j) > w
    expected = [(d[far] <= r).mean() for r in radii]
    _, c = correlation_sum(s, 2, 1, radii, theiler_window=w, n_reference=None, max_pairs=None)
    np.testing.assert_allclose(c, expected, rtol=1e-12)
    # pair budget (random subsets at large r) stays within a few per cent
    _, c_budget = correlation_sum(s, 2, 1, radii, theiler_window=w, n_reference=None,
                                  max_pairs=2000, random_state=0)
    np.testing.assert_allclose(c_budget, expected, rtol=0.05)


def test_correlation_dimension_henon(henon_series):
    res = correlation_dimension(henon_series, dims=range(1, 6), random_state=0)
    assert abs(res.dimension - 1.21) < 0.08, res.dimension  # measured 1.225
    assert res.local_slopes.shape == (48, 5)
    lo, hi = res.scaling_range
    assert 0 < lo < hi


def test_correlation_dimension_mackey_glass_tau23():
    x = MackeyGlass(tau=23.0).simulate(20_000, random_state=0)
    res = correlation_dimension(x, dims=range(4, 9), lag=10, theiler_window=50,
                                n_reference=3000, random_state=0)
    assert abs(res.dimension - 2.4) < 0.25, res.dimension  # measured 2.35 (2.48 at N = 1e5)


def test_maximal_lyapunov_exponent_lorenz(lorenz_series):
    res = maximal_lyapunov_exponent(lorenz_series, dim=5, lag=5, theiler_window=50,
                                    sample_dt=0.02, max_steps=250, n_neighbors=5,
                                    n_reference=2000, random_state=0)
    assert abs(res.exponent / LAMBDA_LORENZ - 1) < 0.10, res.exponent  # measured 0.935
    assert res.divergence.index[-1] == pytest.approx(5.0)
    assert res.fit_range[0] > 0.2  # the fast initial transient is not fitted


def test_maximal_lyapunov_exponent_mackey_glass_tau17():
    x = MackeyGlass(tau=17.0).simulate(30_000, random_state=0)
    res = maximal_lyapunov_exponent(x, dim=6, lag=6, theiler_window=100, max_steps=800,
                                    n_neighbors=5, n_reference=2000, random_state=0)
    assert abs(res.exponent / LAMBDA_MG17 - 1) < 0.30, res.exponent  # measured 0.0059


def test_maximal_lyapunov_exponent_henon_fixed_range(henon_series):
    res = maximal_lyapunov_exponent(henon_series, dim=2, max_steps=10, fit_range=(0, 4),
                                    random_state=0)
    assert abs(res.exponent - 0.419) < 0.06, res.exponent


def test_false_nearest_neighbors(henon_series, lorenz_series):
    fnn = false_nearest_neighbors(henon_series, max_dim=4, n_reference=3000, random_state=0)
    assert fnn.loc[1, "fraction"] > 0.5
    assert fnn.loc[2, "fraction"] < 0.02
    fl = false_nearest_neighbors(lorenz_series[:20_000], max_dim=4, lag=5, theiler_window=20,
                                 n_reference=3000, random_state=0)
    assert fl.loc[1, "fraction"] > 0.3
    assert fl.loc[3, "fraction"] < 0.02


@pytest.mark.parametrize("func, kwargs", [
    (correlation_sum, {"dim": 2}),
    (maximal_lyapunov_exponent, {"dim": 2}),
    (noise_reduction, {}),
    (false_nearest_neighbors, {}),
    (poincare_section, {}),
])
def test_bad_input(func, kwargs):
    good = henon(500, random_state=0)
    bad = good.copy()
    bad[10] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        func(bad, **kwargs)
    with pytest.raises(ValueError, match="constant"):
        func(np.ones(500), **kwargs)
    with pytest.raises(ValueError, match="at least"):
        func(good[:2], **kwargs)


def test_theiler_window_too_large():
    s = henon(100, random_state=0)
    with pytest.raises(ValueError, match="theiler_window"):
        correlation_sum(s, 2, theiler_window=200)
    with pytest.raises(ValueError, match="theiler_window"):
        maximal_lyapunov_exponent(s, dim=2, max_steps=10, theiler_window=100)
