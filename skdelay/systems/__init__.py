"""Simulators of systems with delayed feedback, their exact Lyapunov spectra, and measurement.

Every system is ``dx/dt = f(x(t), x_l(t - tau))`` with one fed-back component,
integrated by one numba RK4 engine (:mod:`._integrate`) and with an exact
tangent-space Lyapunov spectrum (:mod:`._tangent`):

- :class:`MackeyGlass` -- ``a x(t-tau) / (1 + x(t-tau)^n) - b x``
- :class:`Ikeda` -- ``-x + mu sin^2(x(t-tau) - x0)``
- :class:`ElectroOpticOscillator` -- band-pass electro-optic oscillator
- :class:`CO2LaserFeedback` -- CO2 laser with delayed feedback on the losses

``SYSTEMS`` maps names to classes, :func:`get_system` builds one by name, and
:func:`measure` adds measurement noise, ADC quantisation and normalisation.
"""

from __future__ import annotations

from ._base import DelaySystem, DivergenceError
from ._observation import measure
from .co2_laser import CO2LaserFeedback
from .electro_optic import ElectroOpticOscillator
from .ikeda import Ikeda
from .mackey_glass import MackeyGlass

#: name -> system class (the names ``skdelay simulate NAME`` accepts)
SYSTEMS = {
    cls.name: cls for cls in (MackeyGlass, Ikeda, ElectroOpticOscillator, CO2LaserFeedback)
}


def get_system(name, **params):
    """Build a delay system by name.

    Parameters
    ----------
    name : str
        One of ``SYSTEMS`` (``mackey_glass``, ``ikeda``, ``electro_optic``,
        ``co2_laser``); case and ``-`` / ``_`` are ignored, and the class name
        is accepted too.
    **params
        Parameter values (see the class); unknown names are rejected.

    Returns
    -------
    DelaySystem

    Examples
    --------
    >>> from skdelay.systems import get_system
    >>> get_system("mackey-glass", tau=30)
    MackeyGlass(tau=30.0, a=0.2, b=0.1, n=10.0)
    """
    if not isinstance(name, str):
        raise TypeError(f"system name must be a string, got {name!r}.")
    key = name.strip().lower().replace("-", "_")
    by_class = {cls.__name__.lower(): cls for cls in SYSTEMS.values()}
    cls = SYSTEMS.get(key) or by_class.get(key.replace("_", ""))
    if cls is None:
        raise ValueError(
            f"unknown system {name!r}; valid names: {', '.join(sorted(SYSTEMS))}."
        )
    valid = cls.param_names()
    unknown = sorted(set(params) - set(valid))
    if unknown:
        raise ValueError(
            f"{cls.__name__} has no parameter(s) {', '.join(map(repr, unknown))}; "
            f"valid parameters: {', '.join(valid)}."
        )
    return cls(**params)


__all__ = [
    "SYSTEMS",
    "CO2LaserFeedback",
    "DelaySystem",
    "DivergenceError",
    "ElectroOpticOscillator",
    "Ikeda",
    "MackeyGlass",
    "get_system",
    "measure",
]
