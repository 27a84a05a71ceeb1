"""skdelay: find, model and check systems with delayed feedback from time series.

The estimators follow the scikit-learn API, so the usual tools (``Pipeline``,
``GridSearchCV``, ``TimeSeriesSplit``) work unchanged::

    >>> import numpy as np
    >>> from skdelay import lagged_windows, TwoWindowEmbedding, LocalLinearDelayMap
    >>> from skdelay.systems import MackeyGlass
    >>> s = MackeyGlass(tau=17).simulate(3000, random_state=0)
    >>> X, y = lagged_windows(s, n_lags=25)
    >>> V = TwoWindowEmbedding(m=3, tau=17).fit_transform(X)
    >>> model = LocalLinearDelayMap(n_neighbors=20).fit(V, y)
    >>> model.score(V, y) > 0.99
    True

Public API
----------
Delay estimation and models (this namespace): :func:`lagged_windows`,
:class:`TwoWindowEmbedding`, :class:`LocalLinearDelayMap`,
:func:`forecast_error_curve`, :class:`DelaySelectorCV`, :func:`autocorrelation`,
:func:`mutual_information`, :func:`revival_peak`, :func:`locate_dips`, and the
whole analysis of a recording, :func:`analyze_series` (what ``skdelay analyze``
runs), with :func:`read_series` for data files.

Submodules: :mod:`skdelay.dynamics` (iterate, Lyapunov spectra, dimension,
entropy, minimal faithful model), :mod:`skdelay.validation` (cross-prediction,
distribution and spectrum distances), :mod:`skdelay.classic` (Takens tools),
:mod:`skdelay.spacetime`, :mod:`skdelay.systems` (simulators with exact
spectra), :mod:`skdelay.gap` (sim-to-real gap), :mod:`skdelay.datasets`,
:mod:`skdelay.plotting`.
"""

import importlib

from ._analysis import AnalysisResult, analyze_series
from ._correlation import autocorrelation, mutual_information, revival_peak
from ._dips import locate_dips
from ._embedding import TwoWindowEmbedding, required_lags, two_window_columns
from ._io import read_series
from ._local_linear import LocalLinearDelayMap
from ._selection import DelaySelectorCV, NoDipWarning, forecast_error_curve
from ._spectrum import LyapunovSpectrum
from ._windows import lagged_windows

__version__ = "0.1.0"

_SUBMODULES = (
    "classic",
    "datasets",
    "dynamics",
    "gap",
    "plotting",
    "spacetime",
    "systems",
    "validation",
)

__all__ = [
    "AnalysisResult",
    "DelaySelectorCV",
    "LocalLinearDelayMap",
    "LyapunovSpectrum",
    "NoDipWarning",
    "TwoWindowEmbedding",
    "analyze_series",
    "autocorrelation",
    "classic",
    "datasets",
    "dynamics",
    "forecast_error_curve",
    "gap",
    "lagged_windows",
    "locate_dips",
    "mutual_information",
    "plotting",
    "read_series",
    "required_lags",
    "revival_peak",
    "spacetime",
    "systems",
    "two_window_columns",
    "validation",
]


def __getattr__(name):
    # Submodules load on first use: ``import skdelay`` stays fast and does not
    # pull in numba kernels or matplotlib unless they are needed.
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module 'skdelay' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_SUBMODULES))
