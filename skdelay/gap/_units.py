"""Physical time units of a record: ``sample_dt`` with a unit, frequencies in Hz."""

from __future__ import annotations

import math
import re

#: seconds per time unit (the simulator's time unit is the record's)
SECONDS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "ns": 1e-9, "ps": 1e-12,
           "min": 60.0, "h": 3600.0}

_DT = re.compile(r"\s*([-+0-9.eE]+)\s*([a-zµ]+)\s*")


def parse_sample_dt(sample_dt, time_unit=None):
    """``(step, unit)``: the sampling step in the simulator's time unit and that unit's name.

    ``sample_dt`` is a number (time unit ``time_unit``, None = unknown), a
    string such as ``"1 us"`` or a ``(value, unit)`` pair; a unit given with
    the step is the simulator's time unit too.

    >>> parse_sample_dt("1 us")
    (1.0, 'us')
    >>> parse_sample_dt(0.5)
    (0.5, None)
    """
    if isinstance(sample_dt, str):
        m = _DT.fullmatch(sample_dt)
        if not m:
            raise ValueError(f"sample_dt={sample_dt!r} is not a step with a unit such as "
                             f"'1 us'; units: {sorted(SECONDS)}.")
        value, unit = m.group(1), m.group(2)
    elif isinstance(sample_dt, tuple) and len(sample_dt) == 2:
        value, unit = sample_dt
    else:
        value, unit = sample_dt, time_unit
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"sample_dt must be a positive time step, got {sample_dt!r}.") from None
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"sample_dt must be a positive time step, got {sample_dt!r}.")
    if time_unit is not None and unit != time_unit:
        raise ValueError(f"sample_dt has unit {unit!r} but time_unit={time_unit!r}; give one.")
    if unit is not None and unit not in SECONDS:
        raise ValueError(f"unknown time unit {unit!r}; use one of {sorted(SECONDS)}.")
    return value, unit


def frequency_unit(time_unit):
    """``(factor, name)``: cycles per time unit times ``factor`` is a frequency in ``name``."""
    if time_unit is None:
        return 1.0, "cycles per time unit"
    return 1.0 / SECONDS[time_unit], "Hz"


def time_unit_name(time_unit):
    """Name of the time unit for tables and axes."""
    return "time units" if time_unit is None else time_unit


def format_frequency(f, time_unit):
    """A frequency in the user's units (Hz with an SI prefix when the time unit is known)."""
    factor, name = frequency_unit(time_unit)
    value = f * factor
    if name == "Hz":
        for scale, prefix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
            if abs(value) >= scale:
                return f"{value / scale:.4g} {prefix}Hz"
        return f"{value:.4g} Hz"
    return f"{value:.4g} {name}"
