"""Small synthetic delay series for the CLI / report tests (fast, no integrator).

``s_{n+1} = 0.5 s_n + 2 s_{n+1-T} (1 - s_{n+1-T})`` (a delayed logistic map,
chaotic for these values) plus a little dynamical noise: with the package's
delay convention its forecast-error dip sits exactly at ``tau = T``.
"""

import numpy as np


def small_delay_series(n=4000, delay=12, noise=1e-3, seed=0):
    """Return (series, delay) of the delayed logistic map."""
    rng = np.random.default_rng(seed)
    n_total = n + 500
    s = np.empty(n_total)
    s[:delay] = 0.3 + 0.4 * rng.random(delay)
    kicks = noise * rng.standard_normal(n_total)
    for i in range(delay - 1, n_total - 1):
        d = s[i + 1 - delay]
        s[i + 1] = np.clip(0.5 * s[i] + 2.0 * d * (1.0 - d) + kicks[i], 0.0, 1.0)
    return s[500:], delay
