"""Input checks shared by every public entry point.

Each check raises a ``ValueError`` (or ``TypeError``) whose message says what
was wrong *and* what to do about it, so users never have to read the source.
"""

from __future__ import annotations

import numbers

import numpy as np

#: time stamps may be stored rounded to the microsecond; more jitter than that is irregular
_INDEX_JITTER_NS = 1_000


def check_series(series, *, name="series", min_length=2, allow_constant=False):
    """Return ``series`` as a 1-D float64 array after checking it is usable.

    Rejects non-numeric input, arrays that are not 1-D (a single column of
    shape (n, 1) is accepted and flattened), NaN/inf, series shorter than
    ``min_length`` and (unless ``allow_constant``) constant series.  No copy
    is made when ``series`` is already a contiguous float64 array.
    """
    try:
        arr = np.asarray(series)
    except Exception as exc:  # pragma: no cover - exotic input
        raise TypeError(f"{name} must be array-like of numbers; got {type(series).__name__}.") from exc
    if arr.dtype == object or not (
        np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.bool_)
    ):
        raise TypeError(
            f"{name} must hold numbers, got dtype {arr.dtype}; convert it with "
            f"np.asarray({name}, dtype=float)."
        )
    if np.iscomplexobj(arr):
        raise TypeError(f"{name} is complex; pass its real part or magnitude.")
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)
    if arr.ndim != 1:
        raise ValueError(
            f"{name} must be a 1-D time series, got an array of shape {arr.shape}; "
            "select one column (e.g. data[:, 0]) or flatten it."
        )
    arr = np.ascontiguousarray(arr, dtype=np.float64)
    if arr.shape[0] < min_length:
        raise ValueError(
            f"{name} has {arr.shape[0]} samples but at least {min_length} are needed; "
            "record a longer series or ask for smaller m / tau / lags."
        )
    if not np.all(np.isfinite(arr)):
        bad = np.flatnonzero(~np.isfinite(arr))
        raise ValueError(
            f"{name} contains {bad.size} NaN or infinite values (first at index {bad[0]}); "
            "remove or interpolate them before the analysis."
        )
    if not allow_constant and np.ptp(arr) == 0.0:
        raise ValueError(
            f"{name} is constant (every sample equals {arr[0]!r}); a delay system cannot be "
            "analysed from a constant signal - check the recording channel."
        )
    return arr


def check_positive_int(value, *, name, minimum=1, maximum=None):
    """Return ``value`` as int after checking ``minimum <= value <= maximum``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer, got {value!r}.")
    value = int(value)
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}.")
    if maximum is not None and value > maximum:
        raise ValueError(f"{name} must be <= {maximum}, got {value}.")
    return value


def check_random_state(random_state):
    """Thin alias of :func:`sklearn.utils.check_random_state` (one import site)."""
    from sklearn.utils import check_random_state as _crs

    return _crs(random_state)


def sample_dt_from_index(series):
    """Sampling step in seconds of a pandas Series with a time index (None otherwise).

    Parameters
    ----------
    series : pandas.Series or pandas.Index
        A Series indexed by a ``DatetimeIndex`` or ``TimedeltaIndex`` (or such
        an index itself).  Any other index (e.g. the default ``RangeIndex``)
        carries no time step: the function returns None and the caller keeps
        its ``sample_dt``.

    Returns
    -------
    float or None
        The common spacing in seconds.

    Raises
    ------
    ValueError
        Fewer than 2 time stamps, time stamps that are not strictly
        increasing, or irregular spacing (the methods need a uniform grid).

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> from skdelay._checks import sample_dt_from_index
    >>> s = pd.Series(np.arange(4.0), index=pd.date_range("2024", periods=4, freq="10ms"))
    >>> sample_dt_from_index(s)
    0.01
    """
    import pandas as pd

    index = series if isinstance(series, pd.Index) else getattr(series, "index", None)
    if not isinstance(index, (pd.DatetimeIndex, pd.TimedeltaIndex)):
        return None
    if index.size < 2:
        raise ValueError(f"the time index has {index.size} time stamp(s); at least 2 are "
                         "needed to know the sampling step.")
    # integer nanoseconds (whatever the index's unit): exact, no float round-off
    ns = index.as_unit("ns").asi8
    steps = np.diff(ns)
    if np.any(steps <= 0):
        first = int(np.flatnonzero(steps <= 0)[0])
        raise ValueError(f"the time index is not increasing (at position {first + 1}: "
                         f"{index[first]} then {index[first + 1]}); sort the series with "
                         ".sort_index() and drop duplicate time stamps.")
    step = int(np.median(steps))
    bad = np.flatnonzero(np.abs(steps - step) > _INDEX_JITTER_NS)
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"the time index is irregular: the step is {pd.Timedelta(step, unit='ns')} but "
            f"{bad.size} gap(s) differ (first: {pd.Timedelta(int(steps[i]), unit='ns')} after "
            f"{index[i]}); resample to a uniform grid (e.g. series.resample(...).mean()"
            ".interpolate()) first."
        )
    return step / 1e9  # exact for whole seconds (step * 1e-9 is not)
