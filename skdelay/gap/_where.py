"""Localised discrepancies: runs of bins whose z-score against the sim ensemble is large."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ._units import frequency_unit, time_unit_name

#: a bin is discrepant when |z| exceeds this (z is against the sim-vs-sim spread)
Z_WHERE = 4.0

COLUMNS = ["indicator", "feature", "low", "high", "peak", "unit", "excess", "z", "real_value",
           "sim_value", "sim_std", "note"]


def _runs(mask, labels):
    """(start, stop) index pairs of consecutive True entries with equal labels."""
    out, start = [], None
    for i, flag in enumerate(mask):
        if flag and start is not None and labels[i] != labels[start]:
            out.append((start, i))
            start = None
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            out.append((start, i))
            start = None
    if start is not None:
        out.append((start, len(mask)))
    return out


def localise(problem, evaluation=None):
    """DataFrame of localised discrepancies between real and simulated data, largest first.

    ``peak`` is the centre of the run's most discrepant bin.  ``excess`` is
    the run's contribution to the gap (sum of ``z**2 - 1`` over
    its bins divided by the indicator's number of bins), so the rows of an
    indicator add up to about its share of ``gap_before``.
    """
    ev = problem.before if evaluation is None else evaluation
    rows = []
    for name, z in ev.z.items():
        ind = problem.indicators[name]
        lo, hi = ind.bounds()
        factor, unit = user_units(problem, ind.unit)
        lo, hi = lo * factor, hi * factor
        labels = ind.labels()
        real = problem.real_features[name]
        for a, b in _runs(np.abs(z) >= Z_WHERE, labels):
            seg = z[a:b]
            k = a + int(np.argmax(np.abs(seg)))
            rows.append({
                "indicator": "spectrum" if name == "spectral_line" else name,
                "feature": "spectral line" if name == "spectral_line" else labels[k],
                "low": float(lo[a]),
                "high": float(hi[b - 1]), "peak": _centre(lo[k], hi[k]), "unit": unit,
                "excess": float(np.sum(np.square(seg) - 1.0) / z.size), "z": float(z[k]),
                "real_value": float(real[k]), "sim_value": float(ev.mean[name][k]),
                "sim_std": float(ev.std[name][k]), "note": _note(name, z[k], labels[k]),
            })
    rows.extend(_dip_rows(problem, ev))
    df = pd.DataFrame(rows, columns=COLUMNS)
    return df.sort_values("excess", ascending=False, kind="stable").reset_index(drop=True)


def user_units(problem, unit):
    """``(factor, unit)`` that turn an indicator's bounds into the user's units.

    With a known time unit frequencies are given in Hz and times / lags in
    that unit; otherwise in cycles per time unit and time units.
    """
    time_unit = getattr(problem, "time_unit", None)
    if unit == "cycles per time unit":
        return frequency_unit(time_unit)
    if unit.startswith("time units"):
        return 1.0, unit.replace("time units", time_unit_name(time_unit), 1)
    return 1.0, unit


def _centre(lo, hi):
    if not np.isfinite(lo):
        return float(hi)
    if not np.isfinite(hi):
        return float(lo)
    return float(0.5 * (lo + hi))


def _note(name, z, label):
    if name == "spectral_line":
        return ("a spectral line in the real data that the simulator lacks (harmonic F-test "
                "and the ensemble's continuum): periodic interference such as mains hum")
    word = "higher" if z > 0 else "lower"
    return f"real {label} {word} than simulated"


def _dip_rows(problem, ev):
    """A row when the forecast-error dip of the real data sits elsewhere than the model's."""
    if "forecast_error" not in ev.z:
        return []
    fe = problem.indicators["forecast_error"]
    dips = np.array([fe.dip(f) for f in problem.base_features["forecast_error"][0]])
    spread = float(dips.std(ddof=1)) if dips.size > 1 else 0.0
    d_real, d_sim = problem.dip_real, float(dips.mean())
    if abs(d_real - d_sim) < max(0.75, 3 * spread):
        return []
    dt = problem.sample_dt
    return [{
        "indicator": "forecast_error", "feature": "dip position",
        "low": min(d_real, d_sim) * dt, "high": max(d_real, d_sim) * dt, "peak": d_real * dt,
        "unit": fe.unit, "excess": float(ev.gaps["forecast_error"]),
        "z": float((d_real - d_sim) / max(spread, 0.25)), "real_value": d_real * dt,
        "sim_value": d_sim * dt, "sim_std": spread * dt,
        "note": f"forecast-error dip at {d_real * dt:.4g} (real) vs {d_sim * dt:.4g} "
                "(simulated) time units: the delay differs",
    }]
