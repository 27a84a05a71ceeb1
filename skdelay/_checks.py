"""Input checks shared by every public entry point.

Each check raises a ``ValueError`` (or ``TypeError``) whose message says what
was wrong *and* what to do about it, so users never have to read the source.
"""

from __future__ import annotations

import math
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


def check_random_state(random_state, *, name="random_state"):
    """:func:`sklearn.utils.check_random_state` that also takes a numpy ``Generator``.

    The value is checked first (:data:`PARAM_RULES`, a message naming ``name``); a
    ``Generator`` seeds a new ``RandomState`` from its next draw, so the same generator
    state gives the same result (scikit-learn's helper refuses generators, which the
    public docstrings promise).
    """
    from sklearn.utils import check_random_state as _crs

    random_state = _RandomState()(name, random_state)
    if isinstance(random_state, np.random.Generator):
        return np.random.RandomState(int(random_state.integers(MAX_SEED + 1)))
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


# --------------------------------------------------------------- declarative checks
#: largest histogram/bin count any estimator here accepts: beyond it memory, not
#: resolution, is the limit (an int64 joint histogram of 1e6 x 1e6 cells is 8 TB)
MAX_BINS = 1_000_000
#: numpy's legacy seeding (sklearn's check_random_state) takes 0 <= seed < 2**32
MAX_SEED = 2**32 - 1


class Interval:
    """A rule: a real (or integer) number in an interval, optionally None.

    Parameters
    ----------
    kind : {"real", "int"}
    low, high : float or None
        Bounds (None: unbounded).
    closed : {"both", "left", "right", "neither"}, default="both"
    allow_none : bool, default=False
    hint : str, default=""
        What the value means or how to choose it, appended to the message.
    """

    def __init__(self, kind, low=None, high=None, *, closed="both", allow_none=False, hint=""):
        if kind not in ("real", "int"):
            raise ValueError(f"kind must be 'real' or 'int', got {kind!r}.")
        self.kind, self.low, self.high, self.closed = kind, low, high, closed
        self.allow_none, self.hint = allow_none, hint

    def describe(self):
        what = "an integer" if self.kind == "int" else "a finite number"
        # an infinite end is never included: the values must be finite
        left = "[" if self.closed in ("both", "left") and self.low is not None else "("
        right = "]" if self.closed in ("both", "right") and self.high is not None else ")"
        fmt = "d" if self.kind == "int" else "g"  # 1000000, not 1e+06, for counts
        low = "-inf" if self.low is None else format(self.low, fmt)
        high = "inf" if self.high is None else format(self.high, fmt)
        if self.low is not None or self.high is not None:
            what += f" in {left}{low}, {high}{right}"
        return what + (" or None" if self.allow_none else "")

    def __call__(self, name, value):
        if value is None and self.allow_none:
            return None
        bad_type = isinstance(value, (bool, np.bool_)) or not isinstance(
            value, numbers.Integral if self.kind == "int" else numbers.Real)
        if bad_type:
            raise TypeError(_message(name, value, self.describe(), self.hint))
        value = int(value) if self.kind == "int" else float(value)
        ok = math.isfinite(value)
        if ok and self.low is not None:
            ok = value >= self.low if self.closed in ("both", "left") else value > self.low
        if ok and self.high is not None:
            ok = value <= self.high if self.closed in ("both", "right") else value < self.high
        if not ok:
            raise ValueError(_message(name, value, self.describe(), self.hint))
        return value


class Options:
    """A rule: one of a fixed set of strings (or None when ``allow_none``)."""

    def __init__(self, *options, allow_none=False, hint=""):
        self.options, self.allow_none, self.hint = options, allow_none, hint

    def __call__(self, name, value):
        if value is None and self.allow_none:
            return None
        if not isinstance(value, str) or value not in self.options:
            allowed = " or ".join(repr(o) for o in self.options)
            raise ValueError(_message(name, value, f"one of {allowed}", self.hint))
        return value


class _RandomState:
    """A rule: None, a seed in [0, 2**32 - 1] or a numpy RandomState/Generator."""

    def __call__(self, name, value):
        if value is None or isinstance(value, (np.random.RandomState, np.random.Generator)):
            return value
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
            raise TypeError(_message(name, value, "None, an integer seed or a "
                                     "numpy.random.RandomState", "it makes results reproducible"))
        if not 0 <= int(value) <= MAX_SEED:
            raise ValueError(_message(name, value, f"a seed in [0, {MAX_SEED}]", ""))
        return value


class _Workers:
    """A rule: a joblib ``n_jobs`` / scipy ``workers`` count: None, -1, -2, ... or >= 1."""

    def __init__(self, allow_none=True):
        self.allow_none = allow_none

    def __call__(self, name, value):
        if value is None and self.allow_none:
            return None
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
            raise TypeError(_message(name, value, "an integer number of workers", ""))
        if int(value) == 0:
            raise ValueError(_message(name, value, "a non-zero integer",
                                      "use 1 (serial), J > 1 workers or -1 for all cores"))
        return int(value)


class Bins:
    """A rule: a bin count in [1, MAX_BINS] or a 1-D array of increasing finite edges."""

    def __call__(self, name, value):
        if isinstance(value, (numbers.Integral, np.integer)) and not isinstance(value, bool):
            return Interval("int", 1, MAX_BINS, hint="the number of histogram bins")(name, value)
        if isinstance(value, str):
            raise TypeError(_message(name, value, "a number of bins or an array of bin edges",
                                     "numpy's bin-selection strings are not supported"))
        try:
            edges = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise TypeError(_message(name, value, "a number of bins or an array of bin edges",
                                     "")) from None
        if edges.ndim != 1 or edges.size < 2 or not np.all(np.isfinite(edges)) or not np.all(
                np.diff(edges) > 0):
            raise ValueError(_message(name, value, "at least 2 finite, strictly increasing "
                                      "bin edges (or a number of bins)", ""))
        return edges


def _message(name, value, expected, hint):
    shown = repr(value)
    if len(shown) > 60:
        shown = shown[:57] + "..."
    text = f"{name} must be {expected}, got {shown}"
    return text + (f"; {hint}." if hint else ".")


#: rules for the parameter names that mean the same thing across the package; a
#: function checks its arguments with ``check_params(name=value, ...)`` and may pass
#: ``(value, rule)`` for a name it constrains differently
PARAM_RULES = {
    "random_state": _RandomState(),
    "n_jobs": _Workers(allow_none=True),
    "workers": _Workers(allow_none=False),
    "ridge": Interval("real", 0, None, hint="the relative ridge of the local fits (1e-3 "
                                             "is typical, 1e-2..1e-1 for noisy data)"),
    "radius": Interval("real", 0, None, closed="neither", allow_none=True,
                       hint="a neighbourhood radius in the units of the series"),
    "sample_dt": Interval("real", 0, None, closed="neither", hint="the sampling step"),
    "rtol": Interval("real", 0, None, closed="neither",
                     hint="the distance-growth threshold (Kennel et al. use 10 to 15)"),
    "atol": Interval("real", 0, None, closed="neither",
                     hint="the size threshold in units of the attractor std (typically 2)"),
    "prominence": Interval("real", 0, None, allow_none=True,
                           hint="how much an extremum must stand out, in data units"),
    "end_weight": Interval("real", 0, None, closed="neither",
                           hint="the weight of the first/last coordinates (default 1000)"),
    "bins": Bins(),
    "n_bins": Interval("int", 2, MAX_BINS, hint="bins per axis of the histogram"),
    "n_bands": Interval("int", 1, MAX_BINS, hint="the number of frequency/lag bands"),
    "min_pairs": Interval("int", 1, None, hint="pairs needed for a radius to count"),
    "max_frequency": Interval("real", 0, None, closed="neither", allow_none=True,
                              hint="in cycles per time unit"),
}


def check_params(**params):
    """Check keyword arguments against :data:`PARAM_RULES`; return them checked, in order.

    Parameters
    ----------
    **params
        ``name=value`` (rule from :data:`PARAM_RULES`) or ``name=(value, rule)``
        (a rule such as :class:`Interval` for this call).

    Returns
    -------
    value or tuple
        The checked (converted) value for one parameter, a tuple for several.

    Raises
    ------
    ValueError, TypeError
        With a message naming the parameter, what it must be and what it got.

    Examples
    --------
    >>> from skdelay._checks import check_params, Interval
    >>> check_params(ridge=1e-3, n_regions=(3, Interval("int", 1, 50)))
    (0.001, 3)
    >>> check_params(n_jobs=0)
    Traceback (most recent call last):
    ...
    ValueError: n_jobs must be a non-zero integer, got 0; use 1 (serial), J > 1 workers or -1 ...
    """
    out = []
    for name, value in params.items():
        if isinstance(value, tuple) and len(value) == 2 and callable(value[1]):
            value, rule = value
        else:
            rule = PARAM_RULES[name]
        out.append(rule(name, value))
    return out[0] if len(out) == 1 else tuple(out)


def standardise(series):
    """Return ``((s - mean) / std, mean, std)`` without overflow or underflow.

    ``s.std()`` squares the data: it is ``inf`` for ``|s| ~ 1e200`` and ``0``
    for ``|s| ~ 1e-200``.  Dividing by ``max |s|`` first keeps every
    intermediate near 1, so estimators that standardise internally give the
    same answer at any scale that float64 can hold.

    Parameters
    ----------
    series : ndarray of shape (n_samples,)
        Finite, non-constant (see :func:`check_series`).

    Returns
    -------
    z : ndarray
        Zero mean, unit standard deviation.
    mean, std : float
        In the units of ``series`` (``series = z * std + mean``).

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._checks import standardise
    >>> z, mean, std = standardise(np.array([1.0, 3.0]) * 1e200)
    >>> np.round(z, 12).tolist(), float(mean), round(float(std) / 1e200, 12)
    ([-1.0, 1.0], 2e+200, 1.0)
    """
    s = np.asarray(series, dtype=np.float64)
    c = float(np.max(np.abs(s)))
    z = s / c
    mean, std = z.mean(), z.std()
    if not std > 0:
        raise ValueError("the series is constant to float64 precision; nothing to standardise "
                         "- check the recording channel.")
    return (z - mean) / std, mean * c, std * c


def resolve_sample_dt(series, sample_dt=None):
    """The sampling step to use: ``sample_dt`` if given, else the series' time index, else 1.

    Parameters
    ----------
    series : array-like or pandas.Series
        A Series with a ``DatetimeIndex``/``TimedeltaIndex`` carries its step
        (in seconds, see :func:`sample_dt_from_index`).
    sample_dt : float or None
        An explicit step (any time unit) wins over the index.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        ``sample_dt`` is not a positive finite number, or (when it is None)
        the time index is irregular.

    Examples
    --------
    >>> import pandas as pd
    >>> from skdelay._checks import resolve_sample_dt
    >>> s = pd.Series(range(5), index=pd.timedelta_range(0, periods=5, freq="2s"))
    >>> resolve_sample_dt(s), resolve_sample_dt(s, 0.5), resolve_sample_dt([1, 2, 3])
    (2.0, 0.5, 1.0)
    """
    if sample_dt is not None:
        return PARAM_RULES["sample_dt"]("sample_dt", sample_dt)
    from_index = sample_dt_from_index(series) if hasattr(series, "index") else None
    return 1.0 if from_index is None else from_index


def check_interval(name, value, *, nonnegative=False):
    """Rule for a ``(low, high)`` range (radii, times, values): None, or finite with
    ``low < high`` (and ``0 <= low`` when ``nonnegative``); use with :func:`check_params`.
    """
    if value is None:
        return None
    try:
        low, high = (float(v) for v in value)
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be None or a (low, high) pair of numbers, got "
                        f"{value!r}.") from None
    ok = np.isfinite(low) and np.isfinite(high) and low < high and (low >= 0 or not nonnegative)
    if not ok:
        rule = "0 <= low < high" if nonnegative else "low < high"
        raise ValueError(f"{name} must be a finite (low, high) pair with {rule}, got "
                         f"{value!r}; or None to choose it automatically.")
    return low, high
