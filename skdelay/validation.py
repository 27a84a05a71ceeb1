"""Global validation of delay models: cross-prediction, histograms, spectra, correlations.

A small one-step forecast error is necessary but not sufficient for a good
model (Buenner et al., Sec. IV).  A model trajectory ``Y`` is compared with
the data ``X`` globally:

* the cross-prediction error ``chi(X, Y)`` -- predict every point of ``X``
  from neighbours found in ``Y`` (``Y`` is the database); ``chi(X, X)`` is
  the ordinary forecast error and ``chi(X, Y) ~ chi(X, X)`` when both follow
  the same dynamics.  :func:`cross_prediction_by_region` says *where* in
  state space ``Y`` fails;
* the one-dimensional projection of the invariant measure (histograms),
  the power spectrum and the autocorrelation function, each as a distance
  plus a table of where the two differ most (:class:`Comparison`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.signal import welch

from ._checks import (
    Interval,
    Options,
    check_interval,
    check_params,
    check_positive_int,
    check_random_state,
    check_series,
    standardise,
)
from ._correlation import autocorrelation, mutual_information, revival_peak
from ._embedding import required_lags, two_window_columns
from ._local_linear import LocalLinearDelayMap
from ._selection import theiler_from
from ._windows import lagged_windows

__all__ = [
    "Comparison",
    "SupportReference",
    "autocorrelation",
    "autocorrelation_distance",
    "cross_prediction_by_region",
    "cross_prediction_error",
    "histogram_distance",
    "mutual_information",
    "power_spectrum",
    "revival_peak",
    "spectrum_distance",
    "support_distance",
    "value_histogram",
]

_WHERE_COLUMNS = ["low", "high", "x_value", "y_value", "excess"]


@dataclass(frozen=True)
class Comparison:
    """Distance between two series in one profile, and where they differ.

    Attributes
    ----------
    distance : float
        Scalar distance (0 = identical profiles).
    where : pandas.DataFrame
        One row per bin/band with columns ``low``, ``high`` (bounds in the
        profile's units: values in the units of ``x``, frequency in cycles per
        time unit, lag in time units), ``x_value``, ``y_value`` (the two
        profiles there) and ``excess`` (``x_value - y_value``), sorted by
        ``|excess|``, largest first.
    """

    distance: float
    where: pd.DataFrame


def _where(low, high, xv, yv):
    df = pd.DataFrame({"low": low, "high": high, "x_value": xv, "y_value": yv,
                       "excess": np.asarray(xv) - np.asarray(yv)}, columns=_WHERE_COLUMNS)
    order = np.argsort(-np.abs(df["excess"].to_numpy()), kind="stable")
    return df.iloc[order].reset_index(drop=True)


#: smallest normal float64: a power below it has lost its precision
_TINY = float(np.finfo(np.float64).tiny)
#: most quantile bins per axis of cross_prediction_by_region (2500 cells)
MAX_REGIONS = 50
_REGIONS = Interval("int", 1, MAX_REGIONS,
                    hint="the number of quantile bins per axis (each of the n_regions^2 cells "
                         "needs points of its own; 2..5 is typical)")


# --------------------------------------------------------------------------- cross prediction
def _cross_residuals(x, y, *, m, tau, order, n_neighbors, theiler_window, n_queries,
                     random_state, ridge, radius, n_jobs):
    """Rows of x that were predicted, x's lag matrix and the residuals."""
    m = check_positive_int(m, name="m")
    tau = check_positive_int(tau, name="tau")
    k = check_positive_int(n_neighbors, name="n_neighbors")
    check_params(ridge=ridge, radius=radius, random_state=random_state, n_jobs=n_jobs)
    n_lags = required_lags(m, tau)
    cols = two_window_columns(m, tau)
    sx = check_series(x, name="x", min_length=n_lags + 2)
    # neighbour searches and local fits square the data: work in units of x's std (the
    # same affine map for x and y, so chi does not change) and map back where reported
    sx, centre, scale = standardise(sx)
    radius = None if radius is None else radius / scale
    Xx, tx = lagged_windows(sx, n_lags)
    Vx = Xx[:, cols]
    n_rows = Vx.shape[0]
    rng = check_random_state(random_state)
    if n_queries is not None:
        n_queries = check_positive_int(n_queries, name="n_queries")
    if n_queries is not None and n_queries < n_rows:
        rows = np.sort(rng.choice(n_rows, size=n_queries, replace=False))
    else:
        rows = np.arange(n_rows)
    model = LocalLinearDelayMap(k, radius=radius, order=order, ridge=ridge, n_jobs=n_jobs)
    if y is None:
        w = theiler_from(sx, theiler_window)
        if n_rows - (2 * w + 1) < k:
            raise ValueError(
                f"theiler_window={w} leaves fewer than n_neighbors={k} neighbours among the "
                f"{n_rows} vectors of x; use a smaller Theiler window, fewer neighbours or a "
                "longer series."
            )
        model.set_params(theiler_window=w).fit(Vx, tx)
        pred = model.predict(Vx[rows], query_index=rows)
    else:
        sy = (check_series(y, name="y", min_length=n_lags + k + 1) - centre) / scale
        Xy, ty = lagged_windows(sy, n_lags)
        model.fit(Xy[:, cols], ty)
        pred = model.predict(Vx[rows])
    # residuals in units of std(x); Xx stays standardised (no copy of the lag matrix),
    # (centre, scale) maps it back to the units of x
    return rows, Xx, pred - tx[rows], (centre, scale)


def cross_prediction_error(x, y=None, *, m, tau, order=0, n_neighbors=30,
                           theiler_window="auto", n_queries=None, ridge=1e-3, radius=None,
                           random_state=None, n_jobs=None):
    r"""Cross-prediction error ``chi(X, Y)`` (Buenner et al., eq. cross-def).

    Every two-window vector ``v_n(m, tau)`` of ``x`` is predicted with a local
    (constant or linear) map fitted on its nearest neighbours among the
    vectors of ``y`` (the database), and

    .. math:: \chi(X, Y) = \sqrt{\langle (\tilde x_{n+1}(Y) - x_{n+1})^2 \rangle} / \sigma(X).

    With ``y=None`` the database is ``x`` itself with neighbours closer than
    ``theiler_window`` in time excluded: ``chi(X, X)`` is then exactly the
    forecast error of :func:`skdelay.forecast_error_curve` (``search="exact"``)
    for the same ``m, tau, order, n_neighbors, theiler_window`` and queries.
    ``chi(X, Y) ~ chi(X, X)`` when ``Y`` follows the dynamics of ``X``.

    Parameters
    ----------
    x : array-like of shape (n_samples,)
        The series to predict (e.g. the measured data).
    y : array-like of shape (n_samples_y,), optional
        The database (e.g. a model trajectory).  None: ``x`` itself.
    m, tau : int
        Window length and delay (samples) of the two-window vectors.
    order : {0, 1}, default=0
        0: local constant (neighbour mean, as in the paper's table); 1: local linear.
    n_neighbors : int, default=30
    theiler_window : int or "auto", default="auto"
        Only for ``y=None``; "auto" = 1/e decorrelation time of ``x``.
    n_queries : int, optional
        Predict only this many random points of ``x`` (same choice as
        ``forecast_error_curve`` for the same ``random_state``).
    ridge, radius : float
        As in :class:`skdelay.LocalLinearDelayMap`.
    random_state : int, RandomState or None
    n_jobs : int, optional
        Threads of the k-d tree queries.

    Returns
    -------
    float

    Examples
    --------
    >>> from skdelay.systems import MackeyGlass
    >>> from skdelay.validation import cross_prediction_error
    >>> mg = MackeyGlass(tau=17.0)
    >>> x = mg.simulate(3000, random_state=0)
    >>> y = mg.simulate(3000, random_state=1)
    >>> chi_xx = cross_prediction_error(x, m=3, tau=17, random_state=0)
    >>> chi_xy = cross_prediction_error(x, y, m=3, tau=17, random_state=0)
    >>> bool(abs(chi_xy / chi_xx - 1) < 0.3)
    True
    """
    _, _, resid, _ = _cross_residuals(
        x, y, m=m, tau=tau, order=order, n_neighbors=n_neighbors, theiler_window=theiler_window,
        n_queries=n_queries, random_state=random_state, ridge=ridge, radius=radius,
        n_jobs=n_jobs)
    return float(np.sqrt(np.mean(resid ** 2)))  # residuals are in units of std(x)


def cross_prediction_by_region(x, y, *, m, tau, order=0, n_neighbors=30, theiler_window="auto",
                               n_regions=3, n_queries=None, ridge=1e-3, radius=None,
                               random_state=None, n_jobs=None):
    """Where in state space ``y`` fails to predict ``x``.

    The plane of the current value ``s_n`` and the delayed value
    ``s_{n+1-tau}`` of ``x`` is cut into ``n_regions x n_regions`` cells at the
    quantiles of ``x`` (equal-count cells, no clustering).  In each cell the
    cross-prediction error of ``x`` from ``y`` is compared with that of ``x``
    from itself (Theiler-excluded), both normalised by the std of ``x``.

    Parameters
    ----------
    x, y : array-like
        Data and database (e.g. measured series and model trajectory).
    m, tau, order, n_neighbors, theiler_window, n_queries, ridge, radius, random_state, n_jobs
        As in :func:`cross_prediction_error`.
    n_regions : int, default=3
        Quantile bins per axis, at most ``MAX_REGIONS`` (50: 2500 cells, more
        than any series fills with enough points for an error estimate).

    Returns
    -------
    pandas.DataFrame
        Columns ``low``, ``high`` (bounds of ``s_n``), ``delayed_low``,
        ``delayed_high`` (bounds of ``s_{n+1-tau}``), all in the units of ``x``;
        ``count``, ``chi`` (of ``x`` from ``y``), ``chi_self`` (from ``x``) and
        ``excess = chi - chi_self``; sorted by ``excess``, largest first.

    Examples
    --------
    >>> from skdelay.systems import MackeyGlass
    >>> from skdelay.validation import cross_prediction_by_region
    >>> x = MackeyGlass(tau=17.0).simulate(3000, random_state=0)
    >>> y = MackeyGlass(tau=23.0).simulate(3000, random_state=1)
    >>> where = cross_prediction_by_region(x, y, m=3, tau=17, n_regions=2, random_state=0)
    >>> list(where.columns[:4]), len(where)
    (['low', 'high', 'delayed_low', 'delayed_high'], 4)
    """
    if y is None:
        raise ValueError("cross_prediction_by_region compares x with a database y; pass y "
                         "(for the error of x alone use cross_prediction_error(x)).")
    n_regions = check_params(n_regions=(n_regions, _REGIONS))
    kw = {"m": m, "tau": tau, "order": order, "n_neighbors": n_neighbors,
          "theiler_window": theiler_window, "n_queries": n_queries, "ridge": ridge,
          "radius": radius, "n_jobs": n_jobs}
    rows, Xx, resid, scale = _cross_residuals(x, y, random_state=random_state, **kw)
    _, _, resid_self, _ = _cross_residuals(x, None, random_state=random_state, **kw)
    col_now, col_del = Xx[:, 0], Xx[:, int(tau) - 1]  # s_n and s_{n+1-tau}
    now, delayed = col_now[rows], col_del[rows]
    q = np.linspace(0.0, 1.0, n_regions + 1)
    e_now, e_del = np.quantile(col_now, q), np.quantile(col_del, q)
    centre, unit = scale
    scale = 1.0  # residuals are in units of std(x)
    i_now = np.clip(np.searchsorted(e_now, now, side="right") - 1, 0, n_regions - 1)
    i_del = np.clip(np.searchsorted(e_del, delayed, side="right") - 1, 0, n_regions - 1)
    # one pass over the rows for all cells (a loop over cells costs n_regions^2 passes)
    cell = i_now * n_regions + i_del
    n_cells = n_regions * n_regions
    count = np.bincount(cell, minlength=n_cells)
    with np.errstate(invalid="ignore", divide="ignore"):
        chi = np.sqrt(np.bincount(cell, resid ** 2, minlength=n_cells) / count) / scale
        chi_self = np.sqrt(np.bincount(cell, resid_self ** 2, minlength=n_cells) / count) / scale
    a, b = np.divmod(np.arange(n_cells), n_regions)
    e_now, e_del = e_now * unit + centre, e_del * unit + centre  # units of x
    df = pd.DataFrame({"low": e_now[a], "high": e_now[a + 1], "delayed_low": e_del[b],
                       "delayed_high": e_del[b + 1], "count": count, "chi": chi,
                       "chi_self": chi_self})
    df["excess"] = df["chi"] - df["chi_self"]
    return df.sort_values("excess", ascending=False, na_position="last").reset_index(drop=True)


def support_distance(x, y, *, m, tau, factor=5.0, quantile=0.99, n_probe=2000,
                     random_state=None):
    """Fraction of the two-window vectors of ``y`` that lie off the support of ``x``.

    A vector of ``y`` is off the support of ``x`` when its nearest vector of
    ``x`` is farther than ``factor`` times the ``quantile`` of the distances
    between the vectors of ``x`` and their nearest other vector of ``x``
    (the guard of :func:`skdelay.dynamics.iterate`).  Both series are
    standardised by ``x``'s mean and std.  0 when every state of ``y`` is one
    that ``x`` visits; a model run that wanders where the data never go scores
    more than pairs of data segments of its length do.

    Parameters
    ----------
    x, y : array-like of shape (n_samples,)
        Database (e.g. a data segment) and the series judged (e.g. a model run).
    m, tau : int
        Window length and delay (samples) of the two-window vectors.
    factor : float, default=5.0
    quantile : float, default=0.99
    n_probe : int, default=2000
        Vectors of ``x`` whose nearest-neighbour distances set the scale.
    random_state : int, RandomState or None

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.validation import support_distance
    >>> t = np.arange(4000)
    >>> x, y = np.sin(t / 7.0), np.sin(t / 7.0 + 1.0)
    >>> support_distance(x, y, m=2, tau=5), support_distance(x, 3 * y, m=2, tau=5) > 0.5
    (0.0, True)
    """
    return SupportReference(x, m=m, tau=tau, factor=factor, quantile=quantile,
                            n_probe=n_probe, random_state=random_state).off_fraction(y)


class SupportReference:
    """The support of one series ``x``, built once, to judge many series against it.

    :func:`support_distance` builds the k-d tree of ``x``'s two-window vectors and
    its off-support limit on every call.  Comparing many series (model runs) with
    the same ``x`` (a data segment), build them once here and call
    :meth:`off_fraction` per series: it returns what ``support_distance(x, y, ...)``
    returns with the same arguments, at the cost of ``y``'s queries alone.

    Parameters
    ----------
    x : array-like of shape (n_samples,)
        The database series (e.g. a data segment).
    m, tau : int
        Window length and delay (samples) of the two-window vectors.
    factor : float, default=5.0
    quantile : float, default=0.99
    n_probe : int, default=2000
        As in :func:`support_distance`.
    random_state : int, RandomState or None
        Seeds the probes; the same seed gives :func:`support_distance`'s limit.

    Attributes
    ----------
    limit : float
        Distance (in units of ``x``'s standard deviation) beyond which a vector is
        off the support.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.validation import SupportReference, support_distance
    >>> t = np.arange(4000)
    >>> ref = SupportReference(np.sin(t / 7.0), m=2, tau=5, random_state=0)
    >>> y = 3 * np.sin(t / 7.0 + 1.0)
    >>> ref.off_fraction(y) == support_distance(np.sin(t / 7.0), y, m=2, tau=5,
    ...                                         random_state=0)
    True
    """

    def __init__(self, x, *, m, tau, factor=5.0, quantile=0.99, n_probe=2000,
                 random_state=None):
        from scipy.spatial import cKDTree

        m = check_positive_int(m, name="m")
        tau = check_positive_int(tau, name="tau")
        self._n_lags = required_lags(m, tau)
        self._cols = two_window_columns(m, tau)
        sx = check_series(x, name="x", min_length=self._n_lags + 2)
        sx, self._centre, self._scale = standardise(sx)
        Vx = np.ascontiguousarray(lagged_windows(sx, self._n_lags)[0][:, self._cols])
        self._tree = cKDTree(Vx)
        rng = check_random_state(random_state)
        probe = rng.choice(Vx.shape[0], size=min(Vx.shape[0], int(n_probe)), replace=False)
        own = self._tree.query(Vx[probe], k=2)[0][:, 1]
        self.limit = float(factor) * float(np.quantile(own, quantile))

    def off_fraction(self, y):
        """Fraction of ``y``'s two-window vectors farther than :attr:`limit` from ``x``'s.

        Parameters
        ----------
        y : array-like of shape (n_samples,)
            The series judged, in the units of ``x``.

        Returns
        -------
        float
        """
        sy = check_series(y, name="y", min_length=self._n_lags + 1)
        if not self.limit > 0:
            return 0.0
        Vy = np.ascontiguousarray(
            lagged_windows((sy - self._centre) / self._scale, self._n_lags)[0][:, self._cols])
        d = self._tree.query(Vy, k=1, distance_upper_bound=self.limit)[0]
        return float(np.mean(~np.isfinite(d)))


# --------------------------------------------------------------------------- profiles
def power_spectrum(x, *, sample_dt=1.0, nperseg=1024):
    """Welch power spectral density.

    Parameters
    ----------
    x : array-like of shape (n_samples,)
    sample_dt : float, default=1.0
        Sampling step; frequencies are in cycles per time unit.
    nperseg : int, default=1024
        Segment length (clipped to the series length).

    Returns
    -------
    freqs : ndarray
    psd : ndarray
        Power per unit frequency (squared units of ``x`` times time units).

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.validation import power_spectrum
    >>> t = np.arange(4096) * 0.5
    >>> f, p = power_spectrum(np.sin(2 * np.pi * 0.1 * t), sample_dt=0.5, nperseg=512)
    >>> round(float(f[np.argmax(p)]), 3)
    0.102
    """
    s = check_series(x, name="x", min_length=8)
    sample_dt = check_params(sample_dt=sample_dt)
    nperseg = min(check_positive_int(nperseg, name="nperseg", minimum=8), s.size)
    # welch squares the data: compute on x / c and scale back, so that only a power
    # that float64 cannot hold (not an intermediate) is a problem
    c = float(np.max(np.abs(s)))
    f, psd = welch(s / c, fs=1.0 / sample_dt, nperseg=nperseg, detrend="constant")
    with np.errstate(over="ignore", under="ignore"):
        power = c * c
    if not _TINY <= power < np.inf:
        raise ValueError(
            f"the power spectrum of x (amplitude ~{c:.3g}) is outside float64 (power ~ x^2 "
            f"= {c:.1e}^2); rescale x (e.g. x / x.std()) or use spectrum_distance, which "
            "compares spectra at any scale."
        )
    psd = psd * power
    return f, psd


def value_histogram(x, *, bins=50, range=None):
    """One-dimensional projection of the invariant measure: a density histogram.

    Parameters
    ----------
    x : array-like of shape (n_samples,)
    bins : int or array-like, default=50
        Number of equal-width bins or the bin edges.
    range : (float, float), optional
        Histogram range (default: min and max of ``x``).

    Returns
    -------
    edges : ndarray of shape (n_bins + 1,)
    density : ndarray of shape (n_bins,)
        Integrates to 1 over ``edges``.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.validation import value_histogram
    >>> edges, dens = value_histogram(np.random.default_rng(0).uniform(size=10000), bins=4)
    >>> np.round(dens, 1)
    array([1., 1., 1., 1.])
    """
    s = check_series(x, name="x", allow_constant=range is not None)
    bins, range = check_params(bins=bins, range=(range, check_interval))
    density, edges = np.histogram(s, bins=bins, range=range, density=True)
    return edges, density


def _standardise(s, normalise):
    return standardise(s)[0] if normalise else s


def histogram_distance(x, y, *, bins=50, range=None, normalise=False, metric="hellinger"):
    """Distance between the value distributions of two series.

    Both histograms use the same bins (over the joint range, or ``range``).

    Parameters
    ----------
    x, y : array-like
    bins : int, default=50
    range : (float, float), optional
        In the units of the compared values (standardised units if ``normalise``).
    normalise : bool, default=False
        Standardise each series (zero mean, unit variance) first, so gain and
        offset do not count.  ``where`` bounds are still given in x's units.
    metric : {"hellinger", "total_variation"}, default="hellinger"
        Hellinger distance ``sqrt(sum (sqrt p - sqrt q)^2 / 2)`` or total
        variation ``sum |p - q| / 2`` of the bin probabilities; both in [0, 1].

    Returns
    -------
    Comparison
        ``where``: one row per bin, ``x_value``/``y_value`` are densities.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.validation import histogram_distance
    >>> rng = np.random.default_rng(0)
    >>> same = histogram_distance(rng.normal(size=20000), rng.normal(size=20000), bins=20)
    >>> shifted = histogram_distance(rng.normal(size=20000), rng.normal(1, 1, 20000), bins=20)
    >>> bool(same.distance < 0.05 < shifted.distance)
    True
    """
    bins, range, metric = check_params(
        bins=bins, range=(range, check_interval),
        metric=(metric, Options("hellinger", "total_variation")))
    sx = check_series(x, name="x")
    sy = check_series(y, name="y")
    ax, ay = _standardise(sx, normalise), _standardise(sy, normalise)
    if range is None:
        range = (min(ax.min(), ay.min()), max(ax.max(), ay.max()))
    edges = np.histogram_bin_edges(ax, bins=bins, range=range)
    p = np.histogram(ax, bins=edges)[0] / ax.size
    q = np.histogram(ay, bins=edges)[0] / ay.size
    if metric == "hellinger":
        dist = np.sqrt(0.5 * np.sum((np.sqrt(p) - np.sqrt(q)) ** 2))
    else:
        dist = 0.5 * np.sum(np.abs(p - q))
    width = np.diff(edges)
    bounds = edges * sx.std() + sx.mean() if normalise else edges
    return Comparison(float(dist), _where(bounds[:-1], bounds[1:], p / width, q / width))


def _bands(n_items, n_bands):
    n_bands = min(check_positive_int(n_bands, name="n_bands"), n_items)
    return np.array_split(np.arange(n_items), n_bands)


def spectrum_distance(x, y, *, sample_dt=1.0, nperseg=1024, normalise=True, n_bands=16,
                      max_frequency=None):
    """Rms distance between the log power spectra of two series (in decades).

    Parameters
    ----------
    x, y : array-like
    sample_dt : float, default=1.0
        Common sampling step; frequencies in cycles per time unit.
    nperseg : int, default=1024
        Welch segment length (clipped to the shorter series).
    normalise : bool, default=True
        Divide each spectrum by its total power (compare shapes: gain does
        not count).
    n_bands : int, default=16
        Equal-width frequency bands of the ``where`` table.
    max_frequency : float, optional
        Ignore frequencies above this one (e.g. beyond an anti-alias filter).

    Returns
    -------
    Comparison
        ``distance`` = rms over frequencies (f > 0) of ``log10 Px - log10 Py``;
        ``where``: one row per band, ``x_value``/``y_value`` the ``log10``
        of the power in the band (a fraction of the total if ``normalise``),
        ``excess`` their difference (> 0: ``x`` has more power there).

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.validation import spectrum_distance
    >>> t = np.arange(20000)
    >>> rng = np.random.default_rng(0)
    >>> x = np.sin(2 * np.pi * 0.05 * t) + 0.1 * rng.normal(size=t.size)
    >>> y = np.sin(2 * np.pi * 0.12 * t) + 0.1 * rng.normal(size=t.size)
    >>> cmp = spectrum_distance(x, y, nperseg=256)
    >>> round(cmp.distance, 2)
    0.71
    >>> cmp.where[["low", "high", "excess"]].head(2).round(3)   # x's peak, then y's
         low   high  excess
    0  0.033  0.064   2.903
    1  0.096  0.127  -2.876
    """
    sx = check_series(x, name="x", min_length=16)
    sy = check_series(y, name="y", min_length=16)
    nperseg = min(check_positive_int(nperseg, name="nperseg", minimum=8), sx.size, sy.size)
    sample_dt, n_bands, max_frequency = check_params(
        sample_dt=sample_dt, n_bands=n_bands, max_frequency=max_frequency)
    # powers go as x^2: at |x| ~ 1e200 they overflow.  Compare the spectra of x / c and
    # y / c (the log distance does not change) and shift the reported levels back.
    c = max(np.max(np.abs(sx)), np.max(np.abs(sy)))
    f, px = power_spectrum(sx / c, sample_dt=sample_dt, nperseg=nperseg)
    _, py = power_spectrum(sy / c, sample_dt=sample_dt, nperseg=nperseg)
    shift = 0.0 if normalise else 2.0 * float(np.log10(c))
    keep = f > 0
    if max_frequency is not None:
        keep &= f <= max_frequency
    if keep.sum() < 2:
        raise ValueError("fewer than 2 frequencies left; raise max_frequency or nperseg.")
    f, px, py = f[keep], px[keep], py[keep]
    if normalise:
        px, py = px / px.sum(), py / py.sum()
    lx = np.log10(np.maximum(px, 1e-12 * px.max()))
    ly = np.log10(np.maximum(py, 1e-12 * py.max()))
    dist = np.sqrt(np.mean((lx - ly) ** 2))
    df = f[1] - f[0]
    bands = _bands(f.size, n_bands)
    low = [f[b[0]] - df / 2 for b in bands]
    high = [f[b[-1]] + df / 2 for b in bands]
    band_x = [np.log10(max(px[b].sum() * df, 1e-300)) + shift for b in bands]
    band_y = [np.log10(max(py[b].sum() * df, 1e-300)) + shift for b in bands]
    return Comparison(float(dist), _where(low, high, band_x, band_y))


def autocorrelation_distance(x, y, *, max_lag=100, sample_dt=1.0, n_bands=10):
    """Rms difference of the autocorrelation functions over lags ``1..max_lag``.

    Parameters
    ----------
    x, y : array-like
    max_lag : int, default=100
        Largest lag in samples (cover the delay and its first revival).
    sample_dt : float, default=1.0
        Lags of the ``where`` table in time units.
    n_bands : int, default=10
        Equal-width lag bands of the ``where`` table.

    Returns
    -------
    Comparison
        ``where``: one row per lag band, ``x_value``/``y_value`` the mean
        autocorrelation in the band.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.validation import autocorrelation_distance
    >>> t = np.arange(5000)
    >>> cmp = autocorrelation_distance(np.sin(t / 5.0), np.sin(t / 5.0 + 1.0), max_lag=50)
    >>> bool(cmp.distance < 0.01)
    True
    """
    sx = check_series(x, name="x")
    sy = check_series(y, name="y")
    max_lag = check_positive_int(max_lag, name="max_lag")
    sample_dt, n_bands = check_params(sample_dt=sample_dt, n_bands=n_bands)
    ax = autocorrelation(sx, max_lag)[1:]
    ay = autocorrelation(sy, max_lag)[1:]
    lags = np.arange(1, max_lag + 1) * float(sample_dt)
    bands = _bands(max_lag, n_bands)
    return Comparison(
        float(np.sqrt(np.mean((ax - ay) ** 2))),
        _where([lags[b[0]] for b in bands], [lags[b[-1]] for b in bands],
               [ax[b].mean() for b in bands], [ay[b].mean() for b in bands]))
