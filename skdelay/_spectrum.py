"""Lyapunov spectra as a value type, and the quantities derived from them.

Shared by the exact spectra of the simulators (:mod:`skdelay.systems`) and the
data-driven spectra of fitted models (:mod:`skdelay.dynamics`), so both report
the same thing in the same units: exponents per *time unit*, natural log.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd


def _as_exponents(exponents):
    lam = np.asarray(exponents, dtype=float).reshape(-1)
    if lam.size == 0:
        raise ValueError("the Lyapunov spectrum is empty; ask for at least one exponent.")
    if not np.all(np.isfinite(lam)):
        raise ValueError(
            "the Lyapunov spectrum contains NaN/inf; the underlying model or trajectory diverged."
        )
    return np.sort(lam)[::-1]


def kaplan_yorke_dimension(exponents):
    """Kaplan–Yorke (Lyapunov) dimension of a spectrum.

    ``D_KY = k + (lambda_1 + ... + lambda_k) / |lambda_{k+1}|`` where ``k`` is
    the largest index with a non-negative partial sum.  If every partial sum
    is non-negative the spectrum is too short to close the sum and ``D_KY``
    is returned as the number of exponents (a lower bound) — ask for more
    exponents in that case.

    Parameters
    ----------
    exponents : array-like of float
        Lyapunov exponents in any order and any (common) unit.

    Returns
    -------
    float

    Examples
    --------
    >>> from skdelay.dynamics import kaplan_yorke_dimension
    >>> round(kaplan_yorke_dimension([0.9, 0.0, -14.6]), 3)  # Lorenz
    2.062
    """
    lam = _as_exponents(exponents)
    partial = np.cumsum(lam)
    if partial[0] < 0:
        return 0.0
    k = int(np.flatnonzero(partial >= 0)[-1]) + 1
    if k == lam.size:
        return float(k)
    return float(k + partial[k - 1] / abs(lam[k]))


def ks_entropy(exponents):
    """Kolmogorov–Sinai entropy from the Pesin identity: the sum of positive exponents.

    Examples
    --------
    >>> from skdelay.dynamics import ks_entropy
    >>> ks_entropy([0.2, 0.1, -0.5])
    0.30000000000000004
    """
    lam = _as_exponents(exponents)
    return float(lam[lam > 0].sum())


def dimension_density(d_ky, tau):
    """Kaplan–Yorke dimension per unit of delay, ``D_KY / tau``.

    For long delays this is delay independent (the paper finds about 64 per ms
    for the CO2 laser, i.e. one more degree of freedom per 16 microseconds).

    Examples
    --------
    >>> from skdelay.dynamics import dimension_density
    >>> round(dimension_density(23.8, 400.0), 4)
    0.0595
    """
    tau = float(tau)
    if not tau > 0:
        raise ValueError(f"tau must be a positive delay, got {tau}.")
    return float(d_ky) / tau


def rescale_spectrum(exponents, tau):
    """Rescale a spectrum for the long-delay collapse: ``(i / tau, lambda_i * tau)``.

    Spectra of the same delay system at different delays fall onto one curve
    in these coordinates (Giacomelli, Lepri & Politi 1995).

    Parameters
    ----------
    exponents : array-like of float
        Exponents per time unit.
    tau : float
        The delay, in the same time unit.

    Returns
    -------
    index : ndarray
        ``i / tau`` for ``i = 1, ..., n``.
    scaled : ndarray
        ``lambda_i * tau`` (dimensionless), in descending order.

    Examples
    --------
    >>> from skdelay.dynamics import rescale_spectrum
    >>> x, y = rescale_spectrum([0.02, 0.01, -0.03], tau=100)
    >>> x.tolist(), y.tolist()
    ([0.01, 0.02, 0.03], [2.0, 1.0, -3.0])
    """
    tau = float(tau)
    if not tau > 0:
        raise ValueError(f"tau must be a positive delay, got {tau}.")
    lam = _as_exponents(exponents)
    return np.arange(1, lam.size + 1) / tau, lam * tau


@dataclass(frozen=True)
class LyapunovSpectrum:
    """A Lyapunov spectrum with its uncertainty.

    Attributes
    ----------
    exponents : ndarray
        Exponents per time unit (natural log), descending.
    spread : ndarray
        Standard error of each exponent, estimated from its spread over
        independent blocks of the run (same unit).
    sample_dt : float
        Time unit per step of the map the spectrum was computed from.
    n_steps : int
        Number of steps the estimate averages over.
    """

    exponents: np.ndarray
    spread: np.ndarray
    sample_dt: float = 1.0
    n_steps: int = 0
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self):
        lam = np.asarray(self.exponents, dtype=float).reshape(-1)
        spread = np.broadcast_to(np.asarray(self.spread, dtype=float), lam.shape).copy()
        order = np.argsort(lam)[::-1]
        object.__setattr__(self, "exponents", lam[order])
        object.__setattr__(self, "spread", spread[order])

    def __len__(self):
        return self.exponents.size

    @property
    def per_step(self):
        """Exponents per step of the map (``exponents * sample_dt``)."""
        return self.exponents * self.sample_dt

    @property
    def n_positive(self):
        """Number of exponents significantly above zero (by more than their spread)."""
        return int(np.sum(self.exponents > np.maximum(self.spread, 0.0)))

    @property
    def kaplan_yorke_dimension(self):
        """Kaplan–Yorke dimension, see :func:`kaplan_yorke_dimension`."""
        return kaplan_yorke_dimension(self.exponents)

    @property
    def ks_entropy(self):
        """KS entropy per time unit (sum of positive exponents)."""
        return ks_entropy(self.exponents)

    def to_frame(self):
        """The spectrum as a DataFrame (index i = 1..n; columns exponent, spread)."""
        idx = pd.RangeIndex(1, len(self) + 1, name="i")
        return pd.DataFrame({"exponent": self.exponents, "spread": self.spread}, index=idx)
