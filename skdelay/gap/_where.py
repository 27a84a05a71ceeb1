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


def localise(problem, evaluation=None, lacking=None):
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
                "indicator": "spectrum" if name in ("spectral_line", "band_spectrum") else name,
                "feature": "spectral line" if name == "spectral_line" else labels[k],
                "low": float(max(lo[a], 0.0)) if unit == "Hz" else float(lo[a]),
                "high": float(hi[b - 1]), "peak": _centre(lo[k], hi[k]), "unit": unit,
                "excess": float(np.sum(np.square(seg) - 1.0) / z.size), "z": float(z[k]),
                "real_value": float(real[k]), "sim_value": float(ev.mean[name][k]),
                "sim_std": float(ev.std[name][k]), "note": _note(name, z[k], labels[k]),
            })
    if evaluation is None and problem.lines and "spectral_line" in ev.z:
        # a line's share of the gap is what removing it removes: a slow hum also shifts the
        # segment means and the forecast errors, and those rows are its consequences
        share = problem.line_contribution()
        for row in rows:
            if row["feature"] == "spectral line":
                row["excess"] = max(row["excess"], share)
        # a line found by its own test is a localised discrepancy even where its bin of the
        # line indicator stays under Z_WHERE (a slow hum over a continuum that varies from
        # run to run: electro-optic oscillator, 0.36 std at 3.6 cycles per record, line z
        # 2.7; the top row was then one of its consequences, the forecast error)
        ind = problem.indicators["spectral_line"]
        factor, unit = user_units(problem, ind.unit)
        z = ev.z["spectral_line"]
        for k, line in enumerate(problem.lines):
            if k >= z.size or abs(z[k]) >= Z_WHERE:
                continue
            rows.append({
                "indicator": "spectrum", "feature": "spectral line",
                "low": float(max(line.frequency - line.half_width, 0.0) * factor),
                "high": float((line.frequency + line.half_width) * factor),
                "peak": float(line.frequency * factor), "unit": unit,
                "excess": share if k == 0 else float((z[k] ** 2 - 1.0) / z.size),
                "z": float(z[k]), "real_value": float(problem.real_features["spectral_line"][k]),
                "sim_value": float(ev.mean["spectral_line"][k]),
                "sim_std": float(ev.std["spectral_line"][k]),
                "note": _note("spectral_line", z[k], ""),
            })
    if evaluation is None:
        rows.extend(_dip_rows(problem, ev, problem.second_dips, shift=True))
    elif lacking:
        # after the effects: only the second dips that simulator + effects still lack
        rows.extend(_dip_rows(problem, ev, lacking, shift=False))
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


#: the delay's dip is sought within this many samples of the model's delay, or ...
DIP_WINDOW_MIN = 6.0
#: ... this fraction of it when larger: as wide as a delay mismatch the fit considers (a
#: strong hum makes a deeper dip of its own at a quarter of its period, which is not the
#: delay's)
DIP_WINDOW_FRACTION = 0.25


def dip_window(delay_samples):
    """Half-width (samples) of the delays around the model's delay where its dip is sought
    and, when the real data's dip cannot be placed, where a delay mismatch is searched."""
    return float(max(DIP_WINDOW_MIN, DIP_WINDOW_FRACTION * float(delay_samples)))


#: the real dip differs from the model's when the centres are this many of their combined
#: standard errors apart (bootstrap errors of the centres and the runs' scatter) ...
DIP_Z = 3.0
#: ... and at least this many samples (a sub-sample shift is within the dip's resolution)
DIP_MIN_SHIFT = 0.75


#: ... and the real dip is at least this fraction of the model's relative depth: noise fills
#: a dip from below and skews it (4 % measurement noise on Mackey-Glass leaves a dip 14 %
#: deep instead of 63 %, its minimum one sample late), so its position is not comparable
DIP_DEPTH_RATIO = 0.5


def dip_comparable(problem):
    """Are the real and simulated dips alike enough in depth to compare their positions?"""
    if problem.dip is None or not problem.sim_dips:
        return False
    rel_real = problem.dip.depth / problem.dip.baseline
    rel_sim = np.mean([d.depth / d.baseline for d in problem.sim_dips])
    return bool(problem.dip.significant and rel_real >= DIP_DEPTH_RATIO * rel_sim)


#: a delay agrees with the data's dip when the shift it makes differs from the dips' shift by
#: at most this many samples or DIP_Z of the dips' combined standard errors
DELAY_TOL = 1.0


def delay_tolerance(problem):
    """Samples by which a fitted delay may move the dip away from where the real data put it
    (the consistency check of a delay mismatch, and the range its fit searches)."""
    return float(max(DELAY_TOL, DIP_Z * problem.dip_spread))


#: a timebase factor agrees with the data when the dip and the spectral features move by it
#: within this (relative) tolerance or three of their standard errors: a 1.08 factor on
#: Mackey-Glass moves the dip by 1.3 samples, whose centre is good to ~0.2 samples (1 %)
TB_TOL = 0.02


def dip_factor(problem):
    """``(factor, tolerance)``: the timebase factor by which the model's forecast-error dip
    must be stretched to reach the real data's (``dip_sim / dip_real``: real samples are
    ``factor`` nominal steps apart), and how far a factor may differ from it (``TB_TOL``
    or ``DIP_Z`` standard errors of the ratio); None when the dips do not compare."""
    if not dip_comparable(problem):
        return None
    ratio = problem.dip_sim / problem.dip_real
    se = ratio * problem.dip_spread / problem.dip_real
    return float(ratio), float(max(TB_TOL, DIP_Z * se))


def dip_shift_significant(problem):
    """Does the real data's forecast-error dip sit elsewhere than the model's?"""
    if not dip_comparable(problem):
        return False
    shift = abs(problem.dip_real - problem.dip_sim)
    return bool(shift >= max(DIP_MIN_SHIFT, DIP_Z * problem.dip_spread))


def _dip_rows(problem, ev, second, shift=True):
    """Rows for the forecast-error dips: the real dip shifted from the model's (``shift``),
    and the dips ``second`` of the real data that the simulator lacks (a second delay)."""
    if problem.dip is None or "forecast_error" not in ev.z:
        return []
    rows = []
    dt = problem.sample_dt
    _, unit = user_units(problem, problem.indicators["forecast_error"].unit)
    d_real, d_sim = problem.dip_real, problem.dip_sim
    tu = unit.replace(" (delay)", "")
    if shift and dip_shift_significant(problem):
        rows.append({
            "indicator": "forecast_error", "feature": "dip position",
            "low": min(d_real, d_sim) * dt, "high": max(d_real, d_sim) * dt,
            "peak": d_real * dt, "unit": unit, "excess": float(ev.gaps["forecast_error"]),
            "z": float((d_real - d_sim) / max(problem.dip_spread, 0.25)),
            "real_value": d_real * dt, "sim_value": d_sim * dt,
            "sim_std": problem.dip_spread * dt,
            "note": f"forecast-error dip at {d_real * dt:.4g} (real) vs {d_sim * dt:.4g} "
                    f"(simulated) {tu}: the delay differs",
        })
    for dip in second:
        rows.append({
            "indicator": "forecast_error", "feature": "second dip",
            "low": (dip.centre - dip.half_width) * dt, "high": (dip.centre + dip.half_width) * dt,
            "peak": dip.centre * dt, "unit": unit,
            "excess": float(max(ev.gaps["forecast_error"], 1.0)),
            "z": float(dip.z), "real_value": dip.min_error, "sim_value": np.nan,
            "sim_std": np.nan,
            "note": f"the real data have a forecast-error dip at {dip.centre * dt:.4g} {tu} "
                    "that the simulator lacks: a second feedback delay?",
        })
    return rows
