"""Matplotlib figures of the analysis (optional dependency: ``pip install skdelay[plot]``).

Every function draws into ``ax`` when given (so several results can share
one axes) or into a new figure, and returns the :class:`matplotlib.figure.Figure`.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "plot_correlation_dimension",
    "plot_divergence",
    "plot_forecast_error",
    "plot_histograms",
    "plot_lyapunov_spectrum",
    "plot_power_spectra",
    "plot_space_time",
]


def _axes(ax, figsize=(6.0, 4.0)):
    try:
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "skdelay.plotting needs matplotlib; install it with `pip install skdelay[plot]`."
        ) from exc
    if ax is None:
        fig, ax = plt.subplots(figsize=figsize, layout="constrained")
        return fig, ax
    return ax.figure, ax


def _as_mapping(series, default_label):
    if isinstance(series, dict):
        if not series:
            raise ValueError("nothing to plot: the dict of series is empty.")
        return series
    return {default_label: series}


def plot_forecast_error(curve, *, ax=None, logy=False):
    """Forecast error ``sigma_m(tau)``: one line per ``m``.

    Parameters
    ----------
    curve : pandas.DataFrame
        Index ``tau``, one column per ``m`` (from ``forecast_error_curve`` or
        ``DelaySelectorCV.forecast_error_``).
    ax : matplotlib Axes, optional
    logy : bool, default=False

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import pandas as pd
    >>> from skdelay.plotting import plot_forecast_error
    >>> curve = pd.DataFrame({2: [0.3, 0.1, 0.3], 3: [0.2, 0.05, 0.2]},
    ...                      index=pd.Index([16, 17, 18], name="tau"))
    >>> fig = plot_forecast_error(curve)
    >>> len(fig.axes[0].lines)
    2
    """
    import pandas as pd

    if not isinstance(curve, pd.DataFrame):
        raise TypeError(f"curve must be a pandas DataFrame with one column per m (index tau), "
                        f"got {type(curve).__name__}; pass forecast_error_curve(...) or "
                        "DelaySelectorCV(...).fit(X, y).forecast_error_.")
    if curve.shape[1] == 0:
        raise ValueError("curve has no columns; give one column of errors per m.")
    fig, ax = _axes(ax)
    for col in curve.columns:
        ax.plot(curve.index, curve[col], marker=".", label=f"m = {col}")
    ax.set_xlabel("tau (samples)")
    ax.set_ylabel("normalised forecast error")
    if logy:
        ax.set_yscale("log")
    ax.legend()
    return fig


def plot_power_spectra(series, *, sample_dt=1.0, nperseg=1024, ax=None):
    """Welch power spectra of data and model trajectories on one log axis.

    Parameters
    ----------
    series : array-like or dict of str -> array-like
        One series, or ``{"data": x, "m = 3": y3, ...}``.
    sample_dt : float, default=1.0
    nperseg : int, default=1024
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.plotting import plot_power_spectra
    >>> rng = np.random.default_rng(0)
    >>> fig = plot_power_spectra({"a": rng.normal(size=2000), "b": rng.normal(size=2000)})
    >>> len(fig.axes[0].lines)
    2
    """
    from .validation import power_spectrum

    fig, ax = _axes(ax)
    for label, s in _as_mapping(series, "series").items():
        f, p = power_spectrum(s, sample_dt=sample_dt, nperseg=nperseg)
        ax.semilogy(f[1:], p[1:], label=str(label))
    ax.set_xlabel("frequency (cycles per time unit)")
    ax.set_ylabel("power spectral density")
    ax.legend()
    return fig


def plot_histograms(series, *, bins=50, ax=None):
    """Value distributions (1-D projection of the invariant measure) on common bins.

    Parameters
    ----------
    series : array-like or dict of str -> array-like
    bins : int, default=50
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.plotting import plot_histograms
    >>> fig = plot_histograms(np.random.default_rng(0).normal(size=1000), bins=20)
    >>> len(fig.axes[0].lines)
    1
    """
    from .validation import value_histogram

    data = _as_mapping(series, "series")
    arrays = [np.asarray(v, dtype=float) for v in data.values()]
    rng = (min(a.min() for a in arrays), max(a.max() for a in arrays))
    fig, ax = _axes(ax)
    for label, s in zip(data, arrays):
        edges, dens = value_histogram(s, bins=bins, range=rng)
        ax.step(0.5 * (edges[1:] + edges[:-1]), dens, where="mid", label=str(label))
    ax.set_xlabel("value")
    ax.set_ylabel("probability density")
    ax.legend()
    return fig


def plot_lyapunov_spectrum(spectra, *, tau=None, rescaled=False, ax=None):
    """Lyapunov spectra, raw (``lambda_i`` vs ``i``) or rescaled (``lambda_i tau`` vs ``i / tau``).

    For long delays the rescaled spectra of different delays collapse onto
    one curve (Buenner et al., Fig. 15).

    Parameters
    ----------
    spectra : LyapunovSpectrum, array-like or dict of str -> either
        Exponents per time unit.
    tau : float or dict of str -> float, optional
        Delay(s) in time units; required for ``rescaled=True``.
    rescaled : bool, default=False
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from skdelay.plotting import plot_lyapunov_spectrum
    >>> fig = plot_lyapunov_spectrum({"tau=50": [0.2, 0.0, -0.1, -0.4]}, tau={"tau=50": 50},
    ...                              rescaled=True)
    >>> fig.axes[0].get_xlabel()
    'i / tau'
    """
    from ._spectrum import rescale_spectrum

    data = _as_mapping(spectra, "spectrum")
    exponents = {}
    for label, spec in data.items():
        try:
            lam = np.asarray(getattr(spec, "exponents", spec), dtype=float).reshape(-1)
        except (TypeError, ValueError):
            lam = np.array([np.nan])
        if lam.size == 0 or not np.all(np.isfinite(lam)):
            raise ValueError(f"spectrum {label!r} must hold finite exponents (a "
                             f"LyapunovSpectrum or an array of numbers), got {spec!r:.60}.")
        exponents[label] = np.sort(lam)[::-1]
    fig, ax = _axes(ax)
    for label, lam in exponents.items():
        if rescaled:
            t = tau.get(label) if isinstance(tau, dict) else tau
            if t is None:
                raise ValueError(f"rescaled=True needs the delay tau of {label!r} "
                                 "(a number, or a dict label -> tau).")
            x, y = rescale_spectrum(lam, t)
        else:
            x, y = np.arange(1, lam.size + 1), lam
        ax.plot(x, y, marker="o", ms=3, label=str(label))
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xlabel("i / tau" if rescaled else "i")
    ax.set_ylabel("lambda_i * tau" if rescaled else "lambda_i (per time unit)")
    ax.legend()
    return fig


def plot_space_time(series, period=None, *, ax=None, cmap="viridis", vmin=None, vmax=None):
    """Space-time image: delay units ``theta`` down, ``sigma`` across.

    Parameters
    ----------
    series : array-like
        A 1-D series (then ``period`` is required) or a 2-D array from
        :func:`skdelay.spacetime.space_time`.
    period : float, optional
    ax : matplotlib Axes, optional
    cmap : str, default="viridis"
    vmin, vmax : float, optional
        Colour scale limits (give the same to panels that are compared).

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.plotting import plot_space_time
    >>> fig = plot_space_time(np.sin(np.arange(1000) / 5.0), period=31.4)
    >>> len(fig.axes[0].images)
    1
    """
    from .spacetime import space_time

    arr = np.asarray(series, dtype=float)
    if arr.ndim == 1:
        if period is None:
            raise ValueError("a 1-D series needs period= (tau_1 in samples).")
        arr = space_time(arr, period)
    elif arr.ndim != 2:
        raise ValueError(f"expected a 1-D series or a 2-D space-time array, got shape {arr.shape}.")
    fig, ax = _axes(ax)
    width = period if period is not None else arr.shape[1]
    im = ax.imshow(arr, aspect="auto", origin="upper", cmap=cmap, interpolation="nearest",
                   extent=(0.0, width, arr.shape[0] - 0.5, -0.5), vmin=vmin, vmax=vmax)
    ax.set_xlabel("sigma (samples)")
    ax.set_ylabel("theta (delay units)")
    fig.colorbar(im, ax=ax)
    return fig


def plot_correlation_dimension(result, *, ax=None):
    """Local slopes ``d log C / d log r`` per embedding dimension, with the D2 estimate.

    Parameters
    ----------
    result : skdelay.classic.CorrelationDimension
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from skdelay.datasets import henon
    >>> from skdelay.classic import correlation_dimension
    >>> from skdelay.plotting import plot_correlation_dimension
    >>> res = correlation_dimension(henon(3000, random_state=0), dims=[1, 2, 3], random_state=0)
    >>> fig = plot_correlation_dimension(res)
    >>> len(fig.axes[0].lines) >= 3
    True
    """
    from .classic import CorrelationDimension

    if not isinstance(result, CorrelationDimension):
        raise TypeError(f"result must be a CorrelationDimension, got {type(result).__name__}; "
                        "pass skdelay.classic.correlation_dimension(series, ...).")
    fig, ax = _axes(ax)
    slopes = result.local_slopes
    for col in slopes.columns:
        ax.semilogx(slopes.index, slopes[col], lw=1, label=f"d = {col}")
    ax.axvspan(*result.scaling_range, color="0.85", zorder=0)
    ax.axhline(result.dimension, color="k", ls="--", lw=1,
               label=f"D2 = {result.dimension:.2f}")
    ax.set_xlabel("r")
    ax.set_ylabel("local slope d log C / d log r")
    ax.legend(fontsize="small", ncol=2)
    return fig


def plot_divergence(result, *, ax=None):
    """Kantz divergence curve ``S(t)`` with the fitted line of the maximal exponent.

    Parameters
    ----------
    result : skdelay.classic.MaximalLyapunovExponent
    ax : matplotlib Axes, optional

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from skdelay.datasets import henon
    >>> from skdelay.classic import maximal_lyapunov_exponent
    >>> from skdelay.plotting import plot_divergence
    >>> res = maximal_lyapunov_exponent(henon(3000, random_state=0), dim=2, max_steps=10,
    ...                                 fit_range=(0, 5), random_state=0)
    >>> len(plot_divergence(res).axes[0].lines)
    2
    """
    from .classic import MaximalLyapunovExponent

    if not isinstance(result, MaximalLyapunovExponent):
        raise TypeError(f"result must be a MaximalLyapunovExponent, got "
                        f"{type(result).__name__}; pass "
                        "skdelay.classic.maximal_lyapunov_exponent(series, dim=...).")
    fig, ax = _axes(ax)
    S = result.divergence
    ax.plot(S.index, S.to_numpy(), marker=".", label="S(t)")
    t = np.linspace(*result.fit_range, 20)
    ax.plot(t, result.intercept + result.exponent * t, "k--",
            label=f"lambda_1 = {result.exponent:.4g}")
    ax.set_xlabel("t (time units)")
    ax.set_ylabel("S(t) = <ln distance>")
    ax.legend()
    return fig
