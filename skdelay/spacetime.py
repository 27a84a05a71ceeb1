"""Space-time representation of delayed dynamics (Buenner et al., eq. space-time, Fig. 1).

Time is written as ``t = sigma + theta * tau_1``: ``sigma in [0, tau_1)`` is a
space-like coordinate, ``theta`` counts delay units.  The delayed feedback
then couples neighbouring rows (``x(t - tau_1) = x(sigma, theta - 1)``), and
coherent structures propagate down the image when ``tau_1`` is chosen to
maximise the similarity of successive delay units -- slightly longer than
the delay itself (the response time of the system).
"""

from __future__ import annotations

import numbers

import numpy as np
import pandas as pd

from ._checks import Interval, check_params, check_series, standardise

#: columns per sample of the period beyond which space_time only adds interpolated points
MAX_COLUMNS_PER_SAMPLE = 16

__all__ = ["best_space_time_period", "space_time"]


def _check_period(period, n):
    if isinstance(period, (bool, np.bool_)) or not isinstance(period, numbers.Real):
        raise TypeError(f"period must be a number of samples, got {period!r}.")
    period = float(period)
    if not period >= 2.0:
        raise ValueError(f"period must be at least 2 samples, got {period}.")
    if 2.0 * period > n - 1:
        raise ValueError(
            f"period={period} samples leaves fewer than 2 delay units in a series of {n} "
            "samples; use a longer series or a shorter period."
        )
    return period


def space_time(series, period, *, n_columns=None, start=0.0):
    """Cut a series into successive delay units: rows ``theta``, columns ``sigma``.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        Series sampled at step 1.
    period : float
        ``tau_1`` in samples; may be non-integer (rows are then linearly
        interpolated at ``start + theta * period + sigma``).
    n_columns : int, optional
        Points per row, ``sigma = j * period / n_columns`` (default
        ``round(period)``, one column per sample).
    start : float, default=0.0
        Time (in samples) of the first row's first column.

    Returns
    -------
    ndarray of shape (n_rows, n_columns)
        Only complete delay units are kept.  For an integer ``period`` with
        the default columns and ``start=0`` this is exactly
        ``series[:n_rows * period].reshape(n_rows, period)``.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.spacetime import space_time
    >>> space_time(np.arange(10.0), 3)
    array([[0., 1., 2.],
           [3., 4., 5.],
           [6., 7., 8.]])
    >>> space_time(np.arange(10.0), 2.5)   # rows start at 0, 2.5, 5, 7.5
    array([[0.  , 1.25],
           [2.5 , 3.75],
           [5.  , 6.25],
           [7.5 , 8.75]])
    """
    s = check_series(series, min_length=5)
    period = _check_period(period, s.size)
    if n_columns is None:
        n_columns = max(1, round(period))
    n_columns = check_params(n_columns=(n_columns, Interval(
        "int", 1, MAX_COLUMNS_PER_SAMPLE * max(1, round(period)),
        hint=f"more than {MAX_COLUMNS_PER_SAMPLE} columns per sample only interpolate")))
    start = check_params(start=(start, Interval("real", 0, s.size - 1, closed="left")))
    sigma = np.arange(n_columns) * (period / n_columns)
    n_rows = int(np.floor((s.size - 1 - start - sigma[-1]) / period)) + 1
    if n_rows < 1:
        raise ValueError("the series is too short for one delay unit after start.")
    t = start + np.arange(n_rows)[:, None] * period + sigma[None, :]
    return np.interp(t.ravel(), np.arange(s.size, dtype=float), s).reshape(n_rows, n_columns)


def _unit_correlation(s, period):
    st = space_time(s, period)
    a, b = st[:-1].ravel(), st[1:].ravel()
    a, b = a - a.mean(), b - b.mean()
    den = np.sqrt((a * a).sum() * (b * b).sum())
    return float((a * b).sum() / den) if den > 0 else 0.0


def best_space_time_period(series, candidates):
    """The period ``tau_1`` that makes successive delay units most alike.

    The score of a candidate is the Pearson correlation between every row of
    :func:`space_time` and the next one (paper Fig. 1: ``tau_1 > tau_0``
    "chosen so as to optimize the coherence of the vertical structures").

    Parameters
    ----------
    series : array-like of shape (n_samples,)
    candidates : array-like of float
        Periods to try, in samples (non-integer allowed, e.g.
        ``np.arange(145, 165, 0.25)``).

    Returns
    -------
    period : float
        The best candidate.
    scores : pandas.Series
        Correlation per candidate (index ``period``).

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.spacetime import best_space_time_period
    >>> t = np.arange(6000)
    >>> s = np.exp(-((t % 37.3) - 12.0) ** 2 / 8.0)   # pulse train, period 37.3
    >>> period, scores = best_space_time_period(s, np.arange(35, 40, 0.1))
    >>> round(period, 1)
    37.3
    """
    s = check_series(series, min_length=5)
    # the scores multiply samples: standardise so that 1e200 data do not overflow
    s = standardise(s)[0]
    cand = np.asarray(candidates, dtype=float).reshape(-1)
    if cand.size == 0:
        raise ValueError("candidates is empty; pass the periods (in samples) to try.")
    scores = np.array([_unit_correlation(s, _check_period(p, s.size)) for p in cand])
    best = int(np.argmax(scores))
    return float(cand[best]), pd.Series(scores, index=pd.Index(cand, name="period"),
                                        name="correlation")
