"""Sim-to-real gap diagnosis: where real data differ from a simulator, which effect explains it.

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
