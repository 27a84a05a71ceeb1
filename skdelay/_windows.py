"""Lag matrices: the one place where a time series becomes sklearn rows."""

from __future__ import annotations

import numpy as np

from skdelay._checks import check_positive_int, check_series

__all__ = ["lagged_windows"]


def lagged_windows(series, n_lags, *, horizon=1):
    """Lag matrix of a series as a read-only zero-copy view, plus aligned targets.

    Row ``i`` holds the ``n_lags`` most recent samples up to time
    ``t = i + n_lags - 1``, newest first, and the target is the sample
    ``horizon`` steps later::

        X[i] = (s[t], s[t-1], ..., s[t-n_lags+1]),   y[i] = s[t + horizon]

    so ``n_rows = len(series) - n_lags - horizon + 1`` (the alignment of
    ``statsmodels.tsa.lagmat`` with ``trim="both"``, columns reversed).  ``X``
    is a strided view of the series (no copy, even for ``n_lags = 500`` and
    10^6 samples); select the columns a model needs with
    :class:`~skdelay.TwoWindowEmbedding`.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        Finite, non-constant scalar time series, sampled at step 1.
    n_lags : int
        Number of lag columns, ``1 <= n_lags < n_samples``.  A two-window
        model with ``(m, tau)`` needs ``required_lags(m, tau)`` of them.
    horizon : int, default=1
        Forecast horizon of the target in samples (``>= 1``).

    Returns
    -------
    X : ndarray of shape (n_rows, n_lags)
        Read-only view into the series (float64).
    y : ndarray of shape (n_rows,)
        Read-only view of the targets.

    Raises
    ------
    ValueError
        If the series is not 1-D, holds NaN/inf, is constant, or is too short
        for ``n_lags + horizon``.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay import lagged_windows
    >>> X, y = lagged_windows(np.arange(6.0), n_lags=3)
    >>> X
    array([[2., 1., 0.],
           [3., 2., 1.],
           [4., 3., 2.]])
    >>> y
    array([3., 4., 5.])
    >>> X.flags.writeable
    False
    """
    n_lags = check_positive_int(n_lags, name="n_lags")
    horizon = check_positive_int(horizon, name="horizon")
    s = check_series(series, name="series", min_length=2)
    if n_lags >= s.size:
        raise ValueError(
            f"n_lags={n_lags} must be smaller than the series length {s.size}; "
            "use fewer lags (smaller tau or m) or a longer series."
        )
    n_rows = s.size - n_lags - horizon + 1
    if n_rows < 1:
        raise ValueError(
            f"series of length {s.size} leaves no rows for n_lags={n_lags} and "
            f"horizon={horizon}; it needs at least {n_lags + horizon} samples."
        )
    view = np.lib.stride_tricks.sliding_window_view(s, n_lags)[:n_rows, ::-1]
    y = s[n_lags - 1 + horizon:].view()
    y.flags.writeable = False
    return view, y


def series_from_lagged(X, y, *, chunk_values=1 << 22):
    """Recover the 1-D series behind ``lagged_windows(s, n_lags)`` (horizon 1).

    Returns ``s`` such that ``X[i, j] == s[i + n_lags - 1 - j]`` and
    ``y[i] == s[i + n_lags]``, or None if ``X``/``y`` are not such a lag
    matrix (e.g. shuffled rows or other features).  The check runs in row
    blocks, so it never allocates anything of the size of ``X``.
    """
    n, n_lags = X.shape
    if n < 1 or n_lags < 1 or y is None or len(y) != n:
        return None
    col = X[:, 0]
    if n > 1 and not np.array_equal(y[:-1], col[1:]):
        return None
    s = np.concatenate([X[0, :0:-1], col, y[-1:]]).astype(np.float64)
    view = np.lib.stride_tricks.sliding_window_view(s[:-1], n_lags)[:, ::-1]
    step = max(1, chunk_values // n_lags)
    for lo in range(0, n, step):
        if not np.array_equal(X[lo:lo + step], view[lo:lo + step]):
            return None
    return s
