"""Observation model: measurement noise, ADC quantisation, normalisation."""

from __future__ import annotations

import numbers

import numpy as np

from .._checks import check_random_state, check_series


def measure(x, *, noise=0.0, bits=None, normalise=True, random_state=None):
    """Turn a simulated signal into a "measured" one.

    Steps, in the order of a real acquisition chain: additive white Gaussian
    measurement noise with standard deviation ``noise * std(x)``; quantisation
    by an ADC with ``bits`` bits whose full range spans the noisy signal
    (levels ``0 .. 2**bits - 1``); normalisation to mean 0 and mean square 1
    (as the paper does with its 12-bit laser data).

    Parameters
    ----------
    x : array-like of shape (n_samples,)
        Clean signal.
    noise : float, default=0.0
        Measurement noise level, relative to the standard deviation of ``x``
        (0.005 = 0.5 %).
    bits : int or None, default=None
        ADC resolution; None = no quantisation.
    normalise : bool, default=True
        Return ``(y - mean) / std``; otherwise ADC counts (with ``bits``) or
        signal units.
    random_state : int, RandomState instance or None
        Seed of the measurement noise.

    Returns
    -------
    ndarray of shape (n_samples,), float64

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.systems import measure
    >>> y = measure(np.sin(np.linspace(0, 20, 1000)), noise=0.01, bits=12, random_state=0)
    >>> round(float(y.mean()), 12), round(float((y ** 2).mean()), 12)
    (0.0, 1.0)
    """
    x = check_series(x, name="x")
    if not isinstance(noise, numbers.Real) or not np.isfinite(noise) or noise < 0:
        raise ValueError(f"noise must be a non-negative number (relative std), got {noise!r}.")
    y = x.copy()
    if noise > 0:
        rng = check_random_state(random_state)
        y += float(noise) * x.std() * rng.standard_normal(y.size)
    if bits is not None:
        if isinstance(bits, (bool, np.bool_)) or not isinstance(bits, numbers.Integral) \
                or not 1 <= bits <= 32:
            raise ValueError(f"bits must be an integer between 1 and 32, got {bits!r}.")
        lo, hi = y.min(), y.max()
        levels = 2 ** int(bits) - 1
        y = np.rint((y - lo) / (hi - lo) * levels)
        if not normalise:
            return y
    if normalise:
        y = y - y.mean()
        y /= np.sqrt(np.mean(y * y))
    return y
