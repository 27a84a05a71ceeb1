"""Property-based tests (hypothesis) of the public functions' input handling.

Each property states the answer, not just "no crash": an estimator of shape
(correlation, mutual information, false neighbours, distances ...) gives
*exactly* the unit-scale answer on ``2**k * x`` (a power of two scales
floats exactly, so every internally standardised quantity is bit-identical),
the same answer on float32/int copies of the same values, and a
``ValueError``/``TypeError`` from skdelay whose message names the problem
for NaN, short series and bad parameter values.
"""

import math
import re

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import given, settings
from hypothesis import strategies as st

from skdelay import _correlation as corr
from skdelay import classic, spacetime, validation
from skdelay._checks import MAX_BINS, sample_dt_from_index
from skdelay._testing_maps import henon

N = 400
X = henon(N, random_state=0)
Y = henon(N, random_state=1)
#: 2**498 ~ 1e150: the scale range the estimators must handle exactly
MAX_EXPONENT = 498
FAST = settings(max_examples=25, deadline=None, derandomize=True)

scales = st.integers(-MAX_EXPONENT, MAX_EXPONENT).map(lambda k: 2.0 ** k)

#: name -> f(x, y) whose result must not depend on the units of x and y
SCALE_FREE = {
    "autocorrelation": lambda x, y: corr.autocorrelation(x, 20),
    "mutual_information": lambda x, y: corr.mutual_information(x, 5, n_bins=8),
    "false_nearest_neighbors": lambda x, y: classic.false_nearest_neighbors(
        x, max_dim=3).to_numpy(),
    "correlation_sum": lambda x, y: classic.correlation_sum(
        x, 2, n_reference=200, random_state=0)[1],
    "histogram_distance": lambda x, y: validation.histogram_distance(x, y, bins=20).distance,
    "histogram_distance_normalised": lambda x, y: validation.histogram_distance(
        x, y, bins=20, normalise=True).distance,
    "spectrum_distance": lambda x, y: validation.spectrum_distance(x, y, nperseg=64).distance,
    "autocorrelation_distance": lambda x, y: validation.autocorrelation_distance(
        x, y, max_lag=20).distance,
    "cross_prediction_error": lambda x, y: validation.cross_prediction_error(
        x, y, m=2, tau=2, n_neighbors=8, random_state=0),
    "best_space_time_period": lambda x, y: spacetime.best_space_time_period(x, [3, 4, 5])[0],
}


@pytest.mark.parametrize("name", sorted(SCALE_FREE))
def test_scale_free_results_are_exact_at_any_scale(name):
    func = SCALE_FREE[name]
    unit = func(X, Y)

    @FAST
    @given(scale=scales)
    def check(scale):
        np.testing.assert_array_equal(func(scale * X, scale * Y), unit)

    check()


#: name -> f(x) that is linear in x: f(c x) == c f(x)
LINEAR = {
    "space_time": lambda x: spacetime.space_time(x, 3.5),
    "poincare_section": lambda x: classic.poincare_section(x)[1],
    "noise_reduction": lambda x: classic.noise_reduction(x, dim=3, q=1, iterations=1),
}


@pytest.mark.parametrize("name", sorted(LINEAR))
def test_linear_results_scale_with_the_data(name):
    func = LINEAR[name]
    unit = func(X)

    @settings(max_examples=10, deadline=None, derandomize=True)
    @given(scale=scales)
    def check(scale):
        np.testing.assert_allclose(func(scale * X) / scale, unit, rtol=1e-9, atol=1e-12)

    check()


@FAST
@given(exponent=st.integers(-150, 150))
def test_decimal_scales_give_the_unit_answer(exponent):
    # 10**k is not exact in binary: equal up to rounding, never NaN or overflow
    scale = 10.0 ** exponent
    np.testing.assert_allclose(corr.autocorrelation(scale * X, 10),
                               corr.autocorrelation(X, 10), rtol=1e-9, atol=1e-12)
    assert math.isclose(validation.spectrum_distance(scale * X, scale * Y, nperseg=64).distance,
                        validation.spectrum_distance(X, Y, nperseg=64).distance, rel_tol=1e-9)


@FAST
@given(dtype=st.sampled_from([np.float32, np.int64, np.int32, np.int16]),
       amplitude=st.integers(50, 20_000))
def test_float32_and_int_input_equal_float64_of_the_same_values(dtype, amplitude):
    x = (X * amplitude).astype(dtype)
    ref = x.astype(np.float64)
    np.testing.assert_array_equal(corr.autocorrelation(x, 10), corr.autocorrelation(ref, 10))
    assert (validation.histogram_distance(x, ref[::-1], bins=10).distance
            == validation.histogram_distance(ref, ref[::-1], bins=10).distance)
    np.testing.assert_array_equal(spacetime.space_time(x, 4), spacetime.space_time(ref, 4))


@FAST
@given(position=st.integers(0, N - 1), bad=st.sampled_from([np.nan, np.inf, -np.inf]),
       func=st.sampled_from(["autocorrelation", "false_nearest_neighbors", "histogram_distance",
                             "space_time", "correlation_sum"]))
def test_nan_anywhere_is_reported_with_its_index(position, bad, func):
    x = X.copy()
    x[position] = bad
    calls = {
        "autocorrelation": lambda: corr.autocorrelation(x, 5),
        "false_nearest_neighbors": lambda: classic.false_nearest_neighbors(x, max_dim=2),
        "histogram_distance": lambda: validation.histogram_distance(x, Y),
        "space_time": lambda: spacetime.space_time(x, 5),
        "correlation_sum": lambda: classic.correlation_sum(x, 2),
    }
    with pytest.raises(ValueError, match=rf"1 NaN or infinite values \(first at index "
                                         rf"{position}\); remove or interpolate"):
        calls[func]()


@FAST
@given(length=st.integers(0, 4))
def test_too_short_series_say_how_many_samples_are_needed(length):
    with pytest.raises(ValueError, match=rf"has {length} samples but at least 5 are needed"):
        spacetime.space_time(X[:length], 2)


@FAST
@given(bins=st.one_of(st.integers(max_value=0), st.integers(MAX_BINS + 1, 10**12)))
def test_bin_counts_out_of_range(bins):
    with pytest.raises(ValueError, match=rf"bins must be an integer in \[1, {MAX_BINS}\], "
                                         rf"got {bins}"):
        validation.value_histogram(X, bins=bins)


@FAST
@given(bins=st.integers(1, 200))
def test_valid_bin_counts_give_a_density(bins):
    edges, density = validation.value_histogram(X, bins=bins)
    assert edges.size == bins + 1
    assert math.isclose(float(np.sum(density * np.diff(edges))), 1.0, rel_tol=1e-12)


@FAST
@given(value=st.one_of(st.floats(max_value=0.0), st.just(math.nan), st.just(math.inf)))
def test_non_positive_or_non_finite_tolerances_are_refused(value):
    expected = re.escape(f"rtol must be a finite number in (0, inf), got {value!r};")
    with pytest.raises(ValueError, match=expected):
        classic.false_nearest_neighbors(X, max_dim=2, rtol=value)


@FAST
@given(value=st.one_of(st.floats(max_value=-1e-300), st.just(math.nan), st.just(-math.inf)))
def test_negative_or_nan_ridge_is_refused(value):
    with pytest.raises(ValueError, match=r"ridge must be a finite number in \[0, inf\)"):
        validation.cross_prediction_error(X, m=2, tau=2, n_neighbors=8, ridge=value)


@FAST
@given(seed=st.one_of(st.integers(max_value=-1), st.integers(min_value=2**32),
                      st.text(max_size=3), st.floats(allow_nan=True)))
def test_bad_random_states_are_refused(seed):
    error = ValueError if isinstance(seed, int) else TypeError
    with pytest.raises(error, match="random_state must be"):
        classic.correlation_sum(X, 2, random_state=seed)


@FAST
@given(n_jobs=st.just(0) | st.sampled_from([0.5, "2", True]))
def test_bad_n_jobs_are_refused(n_jobs):
    error = ValueError if n_jobs == 0 and not isinstance(n_jobs, bool) else TypeError
    with pytest.raises(error, match="n_jobs must be"):
        validation.cross_prediction_error(X, m=2, tau=2, n_jobs=n_jobs)


@FAST
@given(step_ms=st.integers(1, 10_000), n=st.integers(3, 50),
       jitter_at=st.one_of(st.none(), st.integers(1, 49)))
def test_sample_dt_from_a_time_index(step_ms, n, jitter_at):
    pd = pytest.importorskip("pandas")
    stamps = np.arange(n, dtype=np.int64) * step_ms
    if jitter_at is not None and jitter_at < n:
        stamps[jitter_at:] += 1  # one millisecond: far above the microsecond tolerance
        with pytest.raises(ValueError, match="the time index is irregular"):
            sample_dt_from_index(pd.Series(np.zeros(n), index=pd.to_datetime(stamps, unit="ms")))
        return
    index = pd.to_datetime(stamps, unit="ms")
    assert sample_dt_from_index(pd.Series(np.zeros(n), index=index)) == step_ms / 1000
