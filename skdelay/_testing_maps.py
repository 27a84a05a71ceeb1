"""Small reference systems without delay (Hénon map, Lorenz flow).

Private: used by the tests and benchmarks of the classic (Takens-style) tools,
whose textbook values are known for exactly these systems (Hénon D2 ≈ 1.21,
Lorenz lambda_1 ≈ 0.906 per time unit).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._checks import check_positive_int, check_random_state


@njit(cache=True)
def _henon_loop(n, a, b, x, y, transient):
    out = np.empty(n)
    for i in range(n + transient):
        x, y = 1.0 - a * x * x + y, b * x
        if i >= transient:
            out[i - transient] = x
    return out


def henon(n_samples, *, a=1.4, b=0.3, transient=1000, random_state=None):
    """``x`` component of the Hénon map ``x' = 1 - a x^2 + y, y' = b x``.

    Examples
    --------
    >>> from skdelay._testing_maps import henon
    >>> henon(3, random_state=0).shape
    (3,)
    """
    n = check_positive_int(n_samples, name="n_samples")
    rng = check_random_state(random_state)
    x0, y0 = rng.uniform(-0.1, 0.1, size=2)
    return _henon_loop(n, float(a), float(b), x0, y0, int(transient))


@njit(cache=True)
def _lorenz_rhs(u, sigma, rho, beta):
    return np.array(
        [sigma * (u[1] - u[0]), u[0] * (rho - u[2]) - u[1], u[0] * u[1] - beta * u[2]]
    )


@njit(cache=True)
def _lorenz_loop(n, h, n_sub, u, sigma, rho, beta, transient):
    out = np.empty(n)
    for i in range(n + transient):
        for _ in range(n_sub):
            k1 = _lorenz_rhs(u, sigma, rho, beta)
            k2 = _lorenz_rhs(u + 0.5 * h * k1, sigma, rho, beta)
            k3 = _lorenz_rhs(u + 0.5 * h * k2, sigma, rho, beta)
            k4 = _lorenz_rhs(u + h * k3, sigma, rho, beta)
            u = u + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        if i >= transient:
            out[i - transient] = u[0]
    return out


def lorenz(n_samples, *, sample_dt=0.02, sigma=10.0, rho=28.0, beta=8.0 / 3.0,
           transient=2000, random_state=None):
    """``x`` component of the Lorenz flow, RK4 with step <= 0.005, sampled every ``sample_dt``.

    Examples
    --------
    >>> from skdelay._testing_maps import lorenz
    >>> lorenz(5, random_state=0).shape
    (5,)
    """
    n = check_positive_int(n_samples, name="n_samples")
    rng = check_random_state(random_state)
    n_sub = max(1, int(np.ceil(sample_dt / 0.005)))
    u0 = np.array([1.0, 1.0, 20.0]) + rng.normal(scale=0.1, size=3)
    return _lorenz_loop(n, sample_dt / n_sub, n_sub, u0, float(sigma), float(rho),
                        float(beta), int(transient))
