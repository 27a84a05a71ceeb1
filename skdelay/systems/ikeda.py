"""Ikeda delay equation (ring cavity / electro-optic feedback, first order)."""

from __future__ import annotations

import math

from ._base import DelaySystem


def _ikeda_rhs(x, xd, p, out):
    mu, x0 = p[0], p[1]
    s = math.sin(xd - x0)
    out[0] = -x[0] + mu * s * s


def _ikeda_jac(x, xd, p, jx, jd):
    mu, x0 = p[0], p[1]
    jx[0, 0] = -1.0
    jd[0] = mu * math.sin(2.0 * (xd - x0))


class Ikeda(DelaySystem):
    r"""Ikeda equation ``dx/dt = -x(t) + mu sin^2(x(t - tau) - x0)``.

    The defaults ``mu=20, x0=pi/4, tau=5`` are the hyperchaotic test case of
    Vicente et al. (2005), whose five largest exponents are about
    0.211, 0.196, 0.178, 0.163, 0.152 per time unit.

    Parameters
    ----------
    tau : float, default=5.0
        Delay, in units of the response time.
    mu : float, default=20.0
        Feedback strength (bifurcation parameter).
    x0 : float, default=pi/4
        Phase offset of the nonlinearity.

    Notes
    -----
    Default integration step ``max_dt = 0.01`` (the nonlinearity has slopes up
    to ``mu``).  References: K. Ikeda, Opt. Commun. 30, 257 (1979);
    K. Ikeda and K. Matsumoto, Physica D 29, 223 (1987); R. Vicente, J. Daudén,
    P. Colet and R. Toral, IEEE J. Quantum Electron. 41, 541 (2005).

    Examples
    --------
    >>> from skdelay.systems import Ikeda
    >>> x = Ikeda().simulate(500, sample_dt=0.1, random_state=0)
    >>> bool(0.0 <= x.min() and x.max() <= 20.0)
    True
    """

    name = "ikeda"
    dim = 1
    feedback_index = 0
    max_dt = 0.01
    transient_time = 200.0
    qr_interval = 0.5
    spectrum_duration = 5_000.0
    noise_scale = (1.0,)
    _rhs = staticmethod(_ikeda_rhs)
    _jac = staticmethod(_ikeda_jac)

    def __init__(self, tau=5.0, mu=20.0, x0=math.pi / 4):
        super().__init__(tau=tau, mu=mu, x0=x0)

    def _amplitude(self, params):
        # 0 <= mu sin^2 <= mu: x relaxes into [min(0, mu), max(0, mu)] from the history
        return abs(params["mu"]) + 1.0

    def _initial_state(self, rng, times, params):
        level = rng.uniform(0.0, abs(params["mu"]))
        hist = level + 0.1 * rng.standard_normal(times.size)
        return [level], hist
