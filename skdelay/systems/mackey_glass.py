"""Mackey-Glass delay equation (blood-cell production model)."""

from __future__ import annotations

from ._base import DelaySystem
from ._integrate import ipow


def _mg_rhs(x, xd, p, out):
    a, b, n = p[0], p[1], p[2]
    out[0] = a * xd / (1.0 + ipow(xd, n)) - b * x[0]


def _mg_jac(x, xd, p, jx, jd):
    a, b, n = p[0], p[1], p[2]
    q = ipow(xd, n)
    jx[0, 0] = -b
    jd[0] = a * (1.0 + (1.0 - n) * q) / ((1.0 + q) * (1.0 + q))


class MackeyGlass(DelaySystem):
    r"""Mackey-Glass equation ``dx/dt = a x(t-tau) / (1 + x(t-tau)^n) - b x(t)``.

    With ``a=0.2, b=0.1, n=10`` the attractor is chaotic for ``tau > ~16.8``;
    its Lyapunov dimension grows about linearly with ``tau`` (Farmer 1982:
    ``D_KY ~ 2.1, 2.8, 3.6`` at ``tau = 17, 23, 30``).

    Parameters
    ----------
    tau : float, default=17.0
        Delay (dimensionless time units).
    a, b, n : float
        Production rate, decay rate and Hill exponent.

    Notes
    -----
    Default integration step ``max_dt = 0.05``; initial history: a random
    constant in [0.5, 1.5] plus 1 % jitter.  References: M. C. Mackey and
    L. Glass, Science 197, 287 (1977); J. D. Farmer, Physica D 4, 366 (1982).

    Examples
    --------
    >>> from skdelay.systems import MackeyGlass
    >>> x = MackeyGlass(tau=17.0).simulate(1000, random_state=0)
    >>> x.shape, bool(0.2 < x.min() < x.max() < 1.5)
    ((1000,), True)
    """

    name = "mackey_glass"
    dim = 1
    feedback_index = 0
    max_dt = 0.05
    transient_time = 1000.0
    qr_interval = 1.0
    spectrum_duration = 20_000.0
    noise_scale = (1.0,)
    _rhs = staticmethod(_mg_rhs)
    _jac = staticmethod(_mg_jac)

    def __init__(self, tau=17.0, a=0.2, b=0.1, n=10.0):
        super().__init__(tau=tau, a=a, b=b, n=n)

    def _check_params(self, params):
        if params["b"] <= 0 or params["a"] <= 0:
            raise ValueError(
                f"MackeyGlass needs a > 0 and b > 0, got a={params['a']}, b={params['b']}."
            )
        if params["n"] <= 0:
            # n <= 0 turns the saturating feedback into a growing one (x^(1-n) for x >> 1)
            raise ValueError(
                f"MackeyGlass needs a positive Hill exponent n (default 10), got n={params['n']}."
            )

    def _amplitude(self, params):
        # x a / (1 + x^n) <= a max(1, x) for n >= 1, so x stays below max(a / b, history)
        return max(1.5, params["a"] / params["b"])

    def _initial_state(self, rng, times, params):
        level = 0.5 + rng.uniform()
        hist = level * (1.0 + 0.01 * rng.standard_normal(times.size))
        return [level], hist
