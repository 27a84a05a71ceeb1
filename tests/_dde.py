"""Tiny private Mackey-Glass integrator used only by the core tests.

The real simulators live in :mod:`skdelay.systems`; this file keeps the core
tests independent of them.  Heun's method with ``substeps`` steps per sample,
so the delay is an exact multiple of the integration step and delayed values
are read from the grid without interpolation.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _mg_heun(n_out, delay, substeps, a, b, power, transient, x0):
    h = 1.0 / substeps
    d = delay * substeps
    n_steps = (n_out + transient) * substeps
    x = np.empty(n_steps + d + 1)
    for i in range(d + 1):
        x[i] = x0
    for i in range(d, d + n_steps):
        xd0 = x[i - d]
        xd1 = x[i - d + 1]
        f0 = a * xd0 / (1.0 + xd0**power) - b * x[i]
        xp = x[i] + h * f0
        f1 = a * xd1 / (1.0 + xd1**power) - b * xp
        x[i + 1] = x[i] + 0.5 * h * (f0 + f1)
    out = np.empty(n_out)
    start = d + transient * substeps
    for k in range(n_out):
        out[k] = x[start + k * substeps]
    return out


def mackey_glass(n_samples, delay=17, *, a=0.2, b=0.1, power=10.0, substeps=10,
                 transient=2000, x0=1.2):
    """Sample Mackey-Glass at step 1 (integer ``delay`` in samples)."""
    return _mg_heun(int(n_samples), int(delay), int(substeps), float(a), float(b),
                    float(power), int(transient), float(x0))


def observe(x, *, noise=0.0, bits=None, random_state=None):
    """Normalise, add Gaussian noise (std relative to the signal's) and quantise."""
    rng = np.random.default_rng(random_state)
    y = (x - x.mean()) / x.std()
    if noise:
        y = y + noise * rng.standard_normal(y.size)
    if bits:
        lo, hi = y.min(), y.max()
        levels = 2**bits - 1
        y = np.round((y - lo) / (hi - lo) * levels) / levels * (hi - lo) + lo
    return y


def measured_mackey_glass(n_samples, delay, *, noise=0.005, bits=12, seed=0):
    """Measured Mackey-Glass series (a=0.2, b=0.1, n=10, sample step 1).

    Uses ``skdelay.systems`` (RK4, delay an exact multiple of the step) when it
    is importable, else the Heun integrator above.
    """
    try:
        from skdelay.systems import MackeyGlass, measure
    except ImportError:  # pragma: no cover - the systems helper is not there yet
        x = mackey_glass(n_samples, delay)
        return observe(x, noise=noise, bits=bits, random_state=seed)
    x = MackeyGlass(tau=float(delay)).simulate(n_samples, random_state=seed)
    return measure(x, noise=noise, bits=bits, random_state=seed)
