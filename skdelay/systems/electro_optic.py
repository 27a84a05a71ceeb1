"""Electro-optic oscillator: band-pass delayed feedback with an Ikeda nonlinearity."""

from __future__ import annotations

import math

from ._base import DelaySystem


def _eo_rhs(x, xd, p, out):
    beta, phi, eps = p[0], p[1], p[2]
    c = math.cos(xd + phi)
    out[0] = -x[0] - x[1] + beta * c * c
    out[1] = eps * x[0]


def _eo_jac(x, xd, p, jx, jd):
    beta, phi, eps = p[0], p[1], p[2]
    jx[0, 0] = -1.0
    jx[0, 1] = -1.0
    jx[1, 0] = eps
    jx[1, 1] = 0.0
    jd[0] = -beta * math.sin(2.0 * (xd + phi))
    jd[1] = 0.0


class ElectroOpticOscillator(DelaySystem):
    r"""Band-pass electro-optic delay oscillator (Larger / Chembo Kouomou model).

    In units of the fast response time ``tau_H`` of the band-pass filter::

        dx/dt = -x - y + beta cos^2(x(t - tau) + phi)
        dy/dt = eps x

    which is ``x + tau_H dx/dt + (1/theta) int x dt = beta cos^2(x(t-T) + phi)``
    with ``eps = tau_H / theta`` (low cut-off ``1/theta``) and ``tau = T/tau_H``.
    ``x`` is the (normalised) modulator voltage, fed back and observed.

    Parameters
    ----------
    tau : float, default=20.0
        Delay in units of ``tau_H``.
    beta : float, default=5.0
        Normalised feedback gain.
    phi : float, default=-pi/4
        Offset phase of the Mach-Zehnder modulator.
    eps : float, default=0.02
        Ratio of the high and low cut-off times, ``tau_H / theta``.

    Notes
    -----
    References: Y. Chembo Kouomou, P. Colet, L. Larger and N. Gastaud,
    Phys. Rev. Lett. 95, 203903 (2005); L. Larger, Phil. Trans. R. Soc. A 371,
    20120464 (2013).  The experimental ratios (``eps ~ 1e-5``,
    ``tau ~ 1000``) give attractors of very high dimension; the defaults are
    a small-delay setting that is already hyperchaotic (largest exponents
    ~0.02-0.03 per unit time, more than six of them positive).  Default integration step
    ``max_dt = 0.02``.

    Examples
    --------
    >>> from skdelay.systems import ElectroOpticOscillator
    >>> x = ElectroOpticOscillator().simulate(1000, sample_dt=0.5, random_state=0)
    >>> x.shape
    (1000,)
    """

    name = "electro_optic"
    dim = 2
    feedback_index = 0
    max_dt = 0.02
    transient_time = 500.0
    qr_interval = 0.5
    spectrum_duration = 5_000.0
    noise_scale = (1.0, 0.0)
    _rhs = staticmethod(_eo_rhs)
    _jac = staticmethod(_eo_jac)

    def __init__(self, tau=20.0, beta=5.0, phi=-math.pi / 4, eps=0.02):
        super().__init__(tau=tau, beta=beta, phi=phi, eps=eps)

    def _check_params(self, params):
        if params["eps"] < 0:
            raise ValueError(f"eps = tau_H / theta must be >= 0, got {params['eps']}.")

    def _amplitude(self, params):
        # band-pass filter of a forcing in [0, beta]: |x| stays within a few beta
        return abs(params["beta"]) + 1.0

    def _initial_state(self, rng, times, params):
        x0 = [rng.uniform(-1.0, 1.0), 0.0]
        hist = x0[0] + 0.1 * rng.standard_normal(times.size)
        return x0, hist
