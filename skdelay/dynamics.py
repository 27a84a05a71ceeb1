"""Dynamics of a fitted two-window model: free runs, Lyapunov spectra, faithfulness.

A fitted ``Pipeline(TwoWindowEmbedding(m, tau), LocalLinearDelayMap)`` is a
delay map ``s_{n+1} = g(v_n)`` on the state ``(s_n, ..., s_{n-D+1})`` with
``D = required_lags(m, tau)`` (``tau + m // 2`` for the centred second window,
i.e. about the paper's ``tau + m``).  This module

* iterates it (:func:`iterate`), also with a delay other than the fitted one
  (the map itself does not depend on the delay, Buenner et al. sec. V);
* computes its ``D`` largest Lyapunov exponents from the Jacobians ``a_n`` of
  the local linear maps along a trajectory (:func:`lyapunov_spectrum`);
* finds the smallest faithful window length (:func:`minimal_embedding`);
* re-exports the spectrum summaries :func:`kaplan_yorke_dimension`,
  :func:`ks_entropy`, :func:`dimension_density`, :func:`rescale_spectrum`.
"""

from __future__ import annotations

from ._faithful import FaithfulnessResult, FreeRunOptions, SpectrumOptions, minimal_embedding
from ._iterate import (
    ModelEscapeError,
    ModelEscapeWarning,
    OffSupportWarning,
    Trajectory,
    iterate,
)
from ._lyapunov import lyapunov_spectrum
from ._spectrum import (
    LyapunovSpectrum,
    dimension_density,
    kaplan_yorke_dimension,
    ks_entropy,
    rescale_spectrum,
)

__all__ = [
    "FaithfulnessResult",
    "FreeRunOptions",
    "LyapunovSpectrum",
    "ModelEscapeError",
    "ModelEscapeWarning",
    "OffSupportWarning",
    "SpectrumOptions",
    "Trajectory",
    "dimension_density",
    "iterate",
    "kaplan_yorke_dimension",
    "ks_entropy",
    "lyapunov_spectrum",
    "minimal_embedding",
    "rescale_spectrum",
]
