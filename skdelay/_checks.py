"""Input checks shared by every public entry point.

Each check raises a ``ValueError`` (or ``TypeError``) whose message says what
was wrong *and* what to do about it, so users never have to read the source.
"""

from __future__ import annotations

import numbers

import numpy as np


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
