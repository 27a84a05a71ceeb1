"""Signatures that effects leave in data, read off to get initial parameter guesses.

Pure numpy/scipy on the measured series and clean simulated observations:
a spectral line (hum frequency and amplitude), the set of distinct values
(ADC step), piled-up extreme values (saturation), isolated spikes (outliers),
the high-frequency floor (white noise), the roll-off (detector bandwidth) and
the spectral centroid (time base).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage, optimize, signal


def mean_std(x):
    """Mean and standard deviation of ``x`` at any scale.

    ``np.std`` squares the values: data of order 1e-200 underflow to a zero
    standard deviation (and would look constant), data of order 1e200
    overflow to inf.  Dividing by the largest magnitude (a power of two, so
    exactly) first keeps every intermediate near 1.
    """
    x = np.asarray(x, dtype=float)
    big = float(np.max(np.abs(x))) if x.size else 0.0
    if not (big > 0 and np.isfinite(big)):
        return (float(np.mean(x)) if x.size else 0.0), 0.0
    unit = 2.0 ** np.frexp(big)[1]
    y = x / unit
    return float(y.mean() * unit), float(y.std() * unit)


def zscore(x):
    """``(x - mean) / std`` at any scale (gain and offset are nuisance everywhere here)."""
    x = np.asarray(x, dtype=float)
    big = float(np.max(np.abs(x))) if x.size else 0.0
    if big > 0 and np.isfinite(big):
        x = x / 2.0 ** np.frexp(big)[1]  # exact; see mean_std
    c = x - x.mean()
    sd = c.std()
    return c / (sd if sd > 0 else 1.0)


def welch_psd(x, sample_dt, nperseg=1024):
    """One-sided Welch PSD of the z-scored series (frequencies in cycles per time unit)."""
    x = zscore(x)
    nperseg = int(min(nperseg, max(16, len(x) // 4)))
    f, p = signal.welch(x, fs=1.0 / sample_dt, nperseg=nperseg, detrend="constant")
    return f, p


def ensemble_psd(sims, sample_dt, n, nperseg=1024):
    """Mean Welch PSD of the first ``n`` samples of every simulated run."""
    psds = [welch_psd(s[:n], sample_dt, nperseg)[1] for s in np.atleast_2d(sims)]
    f = welch_psd(np.atleast_2d(sims)[0][:n], sample_dt, nperseg)[0]
    return f, np.mean(psds, axis=0)


def spectral_line(real, sims, sample_dt, nperseg=1024):
    """Strongest narrow line of ``real`` absent from ``sims``.

    Lines are sought in the Welch spectrum and, below its second bin (a
    mains hum in a fast recording is a very slow oscillation), in the
    full-length periodogram.  Returns ``(frequency, amplitude, phase,
    prominence)``: frequency refined on the full-length zero-padded DFT (far
    finer than one Welch bin), amplitude of the sinusoid in standard units of
    the real series, phase at t = 0 (sine convention) and the line's height
    over the simulated spectrum (log10 units).
    """
    n = len(real)
    f, pr = welch_psd(real, sample_dt, nperseg)
    _, ps = ensemble_psd(sims, sample_dt, n, nperseg)
    ratio = np.log10(pr[1:] + 1e-300) - np.log10(ps[1:] + 1e-300)
    # narrowness: excess over the running median of the ratio itself
    excess = ratio - _running_median(ratio, 9)
    k = int(np.argmax(excess)) + 1
    centre, width, prominence = f[k], 1.5 * (f[1] - f[0]), float(excess[k - 1])
    z = zscore(real)
    window = np.hanning(n)
    full = np.abs(np.fft.rfft(z * window)) ** 2
    ffull = np.fft.rfftfreq(n, d=sample_dt)
    low = np.flatnonzero((ffull > 1.5 / (n * sample_dt)) & (ffull < 2 * f[1]))
    if low.size:
        ref = np.mean([np.abs(np.fft.rfft(zscore(x[:n]) * window)) ** 2
                       for x in np.atleast_2d(sims)], axis=0)
        ref = _running_median(ref, 7)
        lr = np.log10(full[low] + 1e-300) - np.log10(ref[low] + 1e-300)
        i = int(np.argmax(lr))
        if lr[i] > max(prominence + 0.5, 1.5):
            centre, width, prominence = ffull[low[i]], 1.5 * ffull[1], float(lr[i])
    pad = 8
    spec = np.abs(np.fft.rfft(z * window, pad * n))
    fgrid = np.fft.rfftfreq(pad * n, d=sample_dt)
    inside = np.flatnonzero(np.abs(fgrid - centre) <= width)
    j = int(inside[np.argmax(spec[inside])])
    freq = float(fgrid[j])
    if 0 < j < spec.size - 1:  # parabolic interpolation of the log magnitude
        a, b, c = np.log(spec[j - 1: j + 2] + 1e-300)
        den = a - 2 * b + c
        if den < 0:
            freq += float(0.5 * (a - c) / den) * (fgrid[1] - fgrid[0])
    t = np.arange(n) * sample_dt
    coef = _dft(z * window, t, [freq])[0]
    amp = float(2.0 * np.abs(coef) / window.sum())
    c0 = _dft(z, t, [freq])[0]
    phase = float(np.angle(c0) + np.pi / 2.0) % (2.0 * np.pi)
    return freq, amp, phase, prominence


def _dft(x, t, freqs):
    return np.array([np.exp(-2j * np.pi * f * t) @ x for f in np.atleast_1d(freqs)])


def _running_median(y, width):
    half = width // 2
    padded = np.pad(y, half, mode="edge")
    view = np.lib.stride_tricks.sliding_window_view(padded, width)
    return np.median(view, axis=1)


def quantization_step(real):
    """``(step, phase)`` of the value grid in standard units, or ``(None, 0)`` if continuous.

    ``step`` is the spacing of the distinct values divided by the series'
    std; ``phase`` in [0, 1) places the grid relative to the series' mean.
    """
    x = np.asarray(real, dtype=float)
    values = np.unique(x)
    if values.size > 0.5 * x.size or values.size < 2:
        return None, 0.0
    gaps = np.diff(values)
    tiny = 1e-9 * (values[-1] - values[0])
    gaps = gaps[gaps > tiny]
    step = float(np.min(gaps))
    multiples = gaps / step
    if np.mean(np.abs(multiples - np.round(multiples)) < 0.05) < 0.9:
        return None, 0.0
    mean, sd = mean_std(x)
    phase = float(((values[0] - mean) / step) % 1.0)
    return step / sd, phase


def pile_ups(real, *, min_fraction=5e-4, min_count=5):
    """Fractions of samples piled up at the minimum and at the maximum value."""
    x = np.asarray(real, dtype=float)
    span = x.max() - x.min()
    tol = 1e-9 * span
    n = x.size
    lo = np.count_nonzero(x <= x.min() + tol)
    hi = np.count_nonzero(x >= x.max() - tol)
    frac_lo = lo / n if (lo >= min_count and lo / n >= min_fraction) else 0.0
    frac_hi = hi / n if (hi >= min_count and hi / n >= min_fraction) else 0.0
    return frac_lo, frac_hi


def spikes(real, sims, *, threshold=1.25, details=False):
    """``(rate, size)`` of isolated spikes in ``real``; ``size`` is the median spike height
    in units of the std of ``real`` without its spikes.

    A sample is a spike when its deviation from the 5-point running median is
    larger than ``threshold`` times the largest deviation seen in the clean
    simulations (so the dynamics' own sharp features do not count) and than
    half a standard deviation, and it is the largest deviation within two samples
    (the median's window: a spike's neighbours deviate too).
    ``details=True`` returns a dict with ``rate``, ``size``, the detection
    threshold ``cut`` and the 95th percentile ``upper`` of the detected
    heights (units of ``size``): spikes below ``cut`` are missed, which biases
    ``rate`` low and ``size`` high.
    """
    x = zscore(real)  # every output is relative to the std: work in standard units
    med = _running_median(x, 5)
    dev = np.abs(x - med)
    ref = [np.abs(zscore(s) - _running_median(zscore(s), 5)) for s in np.atleast_2d(sims)[:2]]
    scale = max(float(np.max(np.concatenate(ref))), 1e-6) * x.std()
    cut = max(threshold * scale, 0.5 * x.std())
    hits = _spike_hits(dev, cut)
    if not np.any(hits):
        out = {"rate": 0.0, "size": 0.0, "cut": float(cut / x.std()), "upper": 0.0}
        return out if details else (0.0, 0.0)
    clean_std = np.where(hits, med, x).std()
    out = {"rate": float(np.mean(hits)), "size": float(np.median(dev[hits]) / clean_std),
           "cut": float(cut / clean_std),
           "upper": float(np.quantile(dev[hits], 0.95) / clean_std)}
    return out if details else (out["rate"], out["size"])


def _spike_hits(dev, cut):
    """Which samples :func:`spikes` counts, given their deviations from the running median.

    A spike also moves the running median of its four neighbours (by about one local
    increment), and on a steep signal that shadow can clear the threshold: only the
    largest deviation within the median's window counts.  Electro-optic oscillator at
    step 0.25 (benchmarks/gap_few_spikes.py): two spikes of 3.2 and 4.5 std cast three
    shadows of 0.72-0.80 std beside a threshold of 0.67, and the rate read 5 / 6000.
    (Two spikes within two samples of each other count as one.)
    """
    return (dev > cut) & (dev >= ndimage.maximum_filter1d(dev, size=5, mode="nearest"))


#: Spacing (samples) of the spikes :func:`spike_efficiency` injects: wider than the
#: running median's window and the local-maximum rule (5 samples), so no injected spike
#: shadows another.
_INJECT_EVERY = 12


def spike_efficiency(sims, size, cut):
    """Fraction of spikes of height ``size * U(0.5, 1.5)`` (signal std, random sign)
    that :func:`spikes` finds at the threshold ``cut`` (the same units): measured by
    adding them to the clean runs ``sims`` and detecting them there.

    Where the signal is rough the deviation from the running median is the spike's
    height plus the signal's own deviation, so heights above ``cut`` are missed and
    heights below it are found: the fraction seen is not the share of heights above
    the threshold.  The runs have that roughness; the injection is deterministic
    (evenly spread heights, alternating signs, every :data:`_INJECT_EVERY` samples).
    """
    size, cut = float(size), float(cut)
    seen = total = 0
    for s in np.atleast_2d(sims)[:2]:
        z = zscore(s)
        at = np.arange(_INJECT_EVERY // 2, z.size - _INJECT_EVERY // 2, _INJECT_EVERY)
        if at.size == 0:
            continue
        # heights spread evenly over U(0.5, 1.5) in a scrambled order (golden-ratio steps)
        u = 0.5 + (np.arange(at.size) * 0.6180339887498949) % 1.0
        sign = np.where(np.arange(at.size) % 2 == 0, 1.0, -1.0)
        y = z.copy()
        y[at] += size * u * sign
        dev = np.abs(y - _running_median(y, 5))
        seen += int(np.count_nonzero(_spike_hits(dev, cut)[at]))
        total += at.size
    return seen / total if total else 1.0


def white_floor(real, sims, sample_dt, nperseg=1024):
    """Variance (standard units of ``real``) of white noise explaining the high-frequency excess."""
    n = len(real)
    f, pr = welch_psd(real, sample_dt, nperseg)
    _, ps = ensemble_psd(sims, sample_dt, n, nperseg)
    top = f >= 0.75 * f[-1]
    excess = np.median(np.maximum(pr[top] - ps[top], 0.0))
    return float(excess / (2.0 * sample_dt))


def centroid(x, sample_dt, nperseg=1024):
    """Spectral centroid (cycles per time unit) of the z-scored series."""
    f, p = welch_psd(x, sample_dt, nperseg)
    return float(np.sum(f * p) / np.sum(p))


def onepole_gain2(f, cutoff, sample_dt):
    """Power gain of the discrete one-pole low-pass ``y += (1 - a) (x - y)``.

    ``a = exp(-2 pi fc dt)``.
    """
    a = np.exp(-2 * np.pi * cutoff * sample_dt)
    return (1 - a) ** 2 / (1 - 2 * a * np.cos(2 * np.pi * f * sample_dt) + a**2)


def roll_off(real, sims, sample_dt, nperseg=1024, floor=False):
    """Cut-off frequency of a one-pole low-pass that best explains the spectral ratio.

    ``floor=True``: the real spectrum is read as ``c |H(f)|^2 S(f) + n0``, a filtered
    model plus a white floor (noise added after the detector), with ``c, n0 >= 0``
    fitted by non-negative least squares in relative error at every trial cut-off.
    Without the floor, such a record's flat high-frequency end reads as no roll-off at
    all.
    """
    n = len(real)
    f, pr = welch_psd(real, sample_dt, nperseg)
    _, ps = ensemble_psd(sims, sample_dt, n, nperseg)
    f, pr, ps = f[1:], pr[1:], ps[1:]
    keep = (ps > 1e-12 * ps.max()) & (pr > 0)
    f, pr, ps = f[keep], pr[keep], ps[keep]
    ratio = np.log(pr / ps)
    weights = np.sqrt(ps / ps.max())
    best, best_err = f[-1], np.inf
    for fc in np.geomspace(f[0], f[-1] * 2, 80):
        gain = onepole_gain2(f, fc, sample_dt)
        if floor:
            # relative error of c g S + n0 against the real power: linear in (c, n0)
            a = np.column_stack([gain * ps / pr, 1.0 / pr]) * np.sqrt(weights)[:, None]
            coef, _ = optimize.nnls(a, np.sqrt(weights))
            model = coef[0] * gain * ps + coef[1]
            if not np.all(model > 0):
                continue
            err = np.sum(weights * np.log(pr / model) ** 2)
        else:
            model = np.log(gain)
            c = np.sum(weights * (ratio - model)) / np.sum(weights)
            err = np.sum(weights * (ratio - model - c) ** 2)
        if err < best_err:
            best, best_err = fc, err
    return float(best)
