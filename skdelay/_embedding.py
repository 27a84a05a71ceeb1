"""Two-window delay vectors as a stateless column selector."""

from __future__ import annotations

import numbers
from typing import ClassVar

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.utils._param_validation import Interval
from sklearn.utils.validation import _check_feature_names_in, validate_data

from skdelay._checks import check_positive_int

__all__ = ["TwoWindowEmbedding", "required_lags", "two_window_columns"]


def _second_window_start(m, tau):
    return max(tau - 1 - (m - 1) // 2, 0)


second_window_start = _second_window_start  # internal-public name for the scan kernels


def two_window_columns(m, tau):
    """Lag-column indices of the two-window vector ``v_n(m, tau)``.

    See :class:`TwoWindowEmbedding` for the convention.

    Parameters
    ----------
    m : int
        Window length (``>= 1``).
    tau : int
        Delay in samples (``>= 1``).

    Returns
    -------
    columns : ndarray of shape (2 * m,)
        ``0..m-1`` (first window) followed by the ``m`` second-window lags.

    Examples
    --------
    >>> from skdelay import two_window_columns
    >>> two_window_columns(2, 17).tolist()
    [0, 1, 16, 17]
    >>> two_window_columns(5, 17).tolist()
    [0, 1, 2, 3, 4, 14, 15, 16, 17, 18]
    """
    m = check_positive_int(m, name="m")
    tau = check_positive_int(tau, name="tau")
    start = _second_window_start(m, tau)
    return np.r_[0:m, start:start + m].astype(np.intp)


def required_lags(m, tau):
    """Number of lag columns (``n_lags``) that ``v_n(m, tau)`` needs.

    This is also the dimension of the state ``(s_n, ..., s_{n-n_lags+1})`` of
    the iterated two-window map: ``max(tau + m // 2, m)``.

    Examples
    --------
    >>> from skdelay import required_lags
    >>> required_lags(2, 17), required_lags(5, 17)
    (18, 19)
    """
    return int(two_window_columns(m, tau)[-1]) + 1


class TwoWindowEmbedding(TransformerMixin, BaseEstimator):
    """Select the two-window delay vector from a lag matrix.

    Maps rows of a lag matrix ``X[i] = (s_t, s_{t-1}, ...)`` (see
    :func:`~skdelay.lagged_windows`) to ``v_t(m, tau)``: a first window of
    the ``m`` newest samples and a second window of ``m`` samples around the
    delay.  Stateless: every row is kept, ``fit`` only checks the input, so it
    works in ``Pipeline``/``GridSearchCV`` with any splitter.

    **Delay convention.**  The second window is centred on the delayed pair
    ``(s_{t+1-tau}, s_{t-tau})`` that a delay equation
    ``dx/dt = f(x(t), x(t - tau0))`` needs to go from ``s_t`` to ``s_{t+1}``::

        v_t(m, tau) = (s_t, ..., s_{t-m+1},  s_{t-c}, ..., s_{t-c-m+1}),
        c = max(tau - 1 - (m - 1) // 2, 0)

    i.e. lag columns ``0..m-1`` and ``c..c+m-1`` (:func:`two_window_columns`).
    For ``m = 2`` this is ``(s_t, s_{t-1}, s_{t+1-tau}, s_{t-tau})``; larger
    windows grow on both sides, odd ones by one more newer sample.  With this
    choice ``tau`` *is* the physical delay in samples: for data from a delay
    system with ``tau0 = T0 * sample_dt`` the windows that hold the delayed
    pair form the bottom of the one-step forecast-error dip, which is centred
    on ``tau = T0`` for every ``m >= 2`` (half a sample later for odd ``m``,
    which :func:`~skdelay.locate_dips` takes into account), so
    ``DelaySelectorCV.delay_`` is ``T0`` within one sample -- checked on
    Mackey-Glass data with ``T0 = 17, 30, 50, 100`` and ``m = 2..5``.  (A
    second window that only grows into the past, the paper's
    ``s_{n-T}, ..., s_{n-T-m+1}``, has its dip bottom at ``T0-m+2 .. T0``:
    its centre would drift by ``(m-2)/2`` samples with ``m``.)  For
    ``tau <= (m - 1) // 2 + 1`` the second window starts at lag 0, i.e. it
    repeats the first window.  The vector needs
    ``n_lags >= required_lags(m, tau) = max(tau + m // 2, m)`` lag columns,
    which is also the state dimension of the iterated map.

    Parameters
    ----------
    m : int, default=2
        Length of each window (``>= 1``).
    tau : int, default=1
        Delay in samples (``>= 1``).

    Attributes
    ----------
    n_features_in_ : int
        Number of lag columns seen in ``fit``.
    feature_names_in_ : ndarray of shape (``n_features_in_``,)
        Column names, when ``X`` is a DataFrame.

    See Also
    --------
    lagged_windows : build the lag matrix ``X``.
    LocalLinearDelayMap : the regressor usually placed after this step.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay import TwoWindowEmbedding, lagged_windows
    >>> X, y = lagged_windows(np.arange(10.0), n_lags=4)
    >>> TwoWindowEmbedding(m=2, tau=3).fit_transform(X)[:2]
    array([[3., 2., 1., 0.],
           [4., 3., 2., 1.]])
    """

    _parameter_constraints: ClassVar[dict] = {
        "m": [Interval(numbers.Integral, 1, None, closed="left")],
        "tau": [Interval(numbers.Integral, 1, None, closed="left")],
    }

    def __init__(self, m=2, tau=1):
        self.m = m
        self.tau = tau

    def _columns(self, n_features):
        cols = two_window_columns(self.m, self.tau)
        needed = int(cols[-1]) + 1
        if n_features < needed:
            raise ValueError(
                f"X has {n_features} feature(s) (lag columns) but TwoWindowEmbedding"
                f"(m={self.m}, tau={self.tau}) needs at least {needed}; build X with "
                f"lagged_windows(series, n_lags={needed}) or more lags."
            )
        return cols

    def fit(self, X, y=None):
        """Check ``X`` has enough lag columns; nothing is learned.

        Parameters
        ----------
        X : array-like of shape (n_rows, n_lags)
            Lag matrix.
        y : None
            Ignored.

        Returns
        -------
        self : TwoWindowEmbedding
        """
        self._validate_params()
        X = validate_data(self, X, dtype=[np.float64, np.float32])
        self._columns(X.shape[1])
        return self

    def transform(self, X):
        """Return the two-window vectors, shape (n_rows, 2 * m).

        Parameters
        ----------
        X : array-like of shape (n_rows, n_lags)
            Lag matrix with at least ``required_lags(m, tau)`` columns.

        Returns
        -------
        V : ndarray of shape (n_rows, 2 * m)
        """
        X = validate_data(self, X, dtype=[np.float64, np.float32], reset=False)
        return X[:, self._columns(X.shape[1])]

    def get_feature_names_out(self, input_features=None):
        """Names of the selected lag columns.

        Parameters
        ----------
        input_features : array-like of str, default=None
            Input column names; ``x0, x1, ...`` when omitted and unknown.

        Returns
        -------
        names : ndarray of str, shape (2 * m,)
        """
        names = _check_feature_names_in(self, input_features)
        return np.asarray(names, dtype=object)[self._columns(len(names))]

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.requires_fit = False
        tags.transformer_tags.preserves_dtype = ["float64", "float32"]
        return tags
