"""Sim-to-real gap diagnosis: where real data differ from a simulator, which effect explains it.

:func:`diagnose_gap` compares a measured series with runs of a simulator on
indicators normalised by the sim-vs-sim spread (power spectrum, histogram,
increments, autocorrelation, per-segment statistics, distinct values,
forecast-error curve, cross-prediction per state-space region), localises
the discrepancies, fits every candidate effect of :data:`EFFECTS` (signature
guess + small bounded search) and ranks them by how much of the gap they
remove.  The result is a :class:`GapReport` (tables, lab-book summary,
figure, HTML).  Register new effects with :func:`register_effect`.

>>> from skdelay.gap import EFFECTS
>>> sorted(EFFECTS)[:3]
['clipping', 'delay_mismatch', 'dynamical_noise']
"""

from ._diagnose import diagnose_gap
from ._effects import EFFECTS, Effect, get_effect, register_effect, unregister_effect
from ._observation import (
    Clipping,
    Lowpass,
    MeasurementNoise,
    Outliers,
    PeriodicInterference,
    Quantization,
    TimebaseMismatch,
)
from ._report import GapReport
from ._simulation import DelayMismatch, DynamicalNoise, ParameterDrift

__all__ = [
    "EFFECTS",
    "Clipping",
    "DelayMismatch",
    "DynamicalNoise",
    "Effect",
    "GapReport",
    "Lowpass",
    "MeasurementNoise",
    "Outliers",
    "ParameterDrift",
    "PeriodicInterference",
    "Quantization",
    "TimebaseMismatch",
    "diagnose_gap",
    "get_effect",
    "register_effect",
    "unregister_effect",
]
