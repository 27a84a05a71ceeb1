"""Linear and nonlinear correlation versus lag, and their delay revivals."""

from __future__ import annotations

import numpy as np
from scipy.signal import find_peaks

from skdelay._checks import Interval, check_params, check_positive_int, check_series, standardise

__all__ = ["autocorrelation", "mutual_information", "revival_peak"]

#: the joint histogram has n_bins^2 int64 cells: 4096 bins = 128 MiB, and a series
#: fills such fine bins only with > 1e8 samples
MAX_MI_BINS = 4096
_MI_BINS = Interval("int", 2, MAX_MI_BINS, hint="bins per axis (16..64 is typical)")


def _check_lag(max_lag, n):
    max_lag = check_positive_int(max_lag, name="max_lag", minimum=0)
    if max_lag >= n:
        raise ValueError(
            f"max_lag={max_lag} must be smaller than the series length {n}; "
            "use a smaller max_lag or a longer series."
        )
    return max_lag


def autocorrelation(series, max_lag):
    """Autocorrelation function up to ``max_lag`` (FFT, biased estimator).

    ``acf[l] = sum_t (s_t - mean)(s_{t+l} - mean) / (n var)``, so ``acf[0] = 1``.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        Finite, non-constant time series.
    max_lag : int
        Largest lag, ``0 <= max_lag < n_samples``.

    Returns
    -------
    acf : ndarray of shape (max_lag + 1,)

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay import autocorrelation
    >>> acf = autocorrelation(np.sin(np.arange(1000) * 2 * np.pi / 50), 50)
    >>> round(float(acf[0]), 3), round(float(acf[25]), 2), round(float(acf[50]), 2)
    (1.0, -0.97, 0.95)
    """
    s = check_series(series, name="series")
    max_lag = _check_lag(max_lag, s.size)
    # standardised: the products below would overflow (|s| ~ 1e200) or underflow (1e-200)
    x = standardise(s)[0]
    nfft = 1 << int(np.ceil(np.log2(2 * s.size - 1)))
    f = np.fft.rfft(x, nfft)
    acov = np.fft.irfft(f * np.conj(f), nfft)[: max_lag + 1]
    return acov / acov[0]


def mutual_information(series, max_lag, *, n_bins=16):
    """Time-delayed mutual information ``I(s_t; s_{t+lag})`` in nats.

    Histogram estimator on ``n_bins`` equal-width bins spanning the range of
    the series (the same bins for every lag, Fraser-Swinney style).

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        Finite, non-constant time series.
    max_lag : int
        Largest lag, ``0 <= max_lag < n_samples``.
    n_bins : int, default=16
        Bins per axis (``>= 2``).

    Returns
    -------
    mi : ndarray of shape (max_lag + 1,)
        ``mi[0]`` is the entropy of the binned series.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay import mutual_information
    >>> s = np.random.default_rng(0).normal(size=20000)
    >>> mi = mutual_information(s, 3, n_bins=8)
    >>> bool(mi[0] > 1.0 and mi[1:].max() < 0.01)
    True
    """
    s = check_series(series, name="series")
    max_lag = _check_lag(max_lag, s.size)
    n_bins = check_params(n_bins=(n_bins, _MI_BINS))
    lo, hi = s.min(), s.max()
    idx = np.minimum(((s - lo) / (hi - lo) * n_bins).astype(np.intp), n_bins - 1)
    out = np.empty(max_lag + 1)
    for lag in range(max_lag + 1):
        a, b = idx[: s.size - lag], idx[lag:]
        joint = np.bincount(a * n_bins + b, minlength=n_bins * n_bins).reshape(n_bins, n_bins)
        pxy = joint / a.size
        px, py = pxy.sum(1), pxy.sum(0)
        nz = pxy > 0
        out[lag] = np.sum(pxy[nz] * np.log(pxy[nz] / np.outer(px, py)[nz]))
    return out


def revival_peak(curve, *, min_lag=1, prominence=None):
    """Lag of the first revival: the first local maximum after the first local minimum.

    Used on :func:`autocorrelation` or :func:`mutual_information` curves,
    whose first revival lies near -- typically somewhat beyond -- the feedback
    delay (the offset is the system's response time).

    Parameters
    ----------
    curve : array-like of shape (n_lags,)
        Values at lags ``0, 1, ...``.
    min_lag : int, default=1
        Ignore lags below this one.
    prominence : float, default=None
        Extrema must stand out by this much to count (``scipy.signal.find_peaks``
        prominence); None means 2% of the curve's range beyond ``min_lag``, which
        ignores estimator jitter.

    Returns
    -------
    lag : int

    Raises
    ------
    ValueError
        If the curve has no minimum followed by a maximum (compute it up to a
        larger lag).

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay import autocorrelation, revival_peak
    >>> acf = autocorrelation(np.sin(np.arange(1000) * 2 * np.pi / 50), 80)
    >>> revival_peak(acf)
    50
    """
    c = np.asarray(curve, dtype=np.float64)
    if c.ndim != 1 or not np.all(np.isfinite(c)):
        raise ValueError("curve must be a finite 1-D array (values at lags 0, 1, ...).")
    min_lag = check_positive_int(min_lag, name="min_lag", minimum=0)
    prominence = check_params(prominence=prominence)
    tail = c[min_lag:]
    if tail.size < 3:
        raise ValueError(f"curve needs at least 3 values beyond min_lag={min_lag}.")
    if prominence is None:
        prominence = 0.02 * float(np.ptp(tail))
    minima, _ = find_peaks(-tail, prominence=prominence)
    if minima.size:
        maxima, _ = find_peaks(tail, prominence=prominence)
        later = maxima[maxima > minima[0]]
        if later.size:
            return int(later[0] + min_lag)
    raise ValueError(
        f"no revival peak (a local minimum followed by a local maximum) up to lag "
        f"{c.size - 1}; compute the curve up to a larger lag."
    )
