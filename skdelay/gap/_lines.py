"""Spectral lines: narrow sinusoids (mains hum, pick-up) anywhere from a few cycles per record
up to Nyquist, judged against the simulator ensemble's own spectrum.

A Welch spectrum with 1024-sample segments cannot see a 50 Hz hum sampled at
1 MHz (period 20 000 samples: it falls below the first Welch bin).  Here the
whole record is analysed at once with a multitaper estimate (Thomson 1982:
``K`` orthogonal DPSS tapers of time-bandwidth ``NW``; every bin of width
``1 / (n dt)`` is resolved) and two questions are asked per bin:

* does the real power stand out of its own local continuum (running median)
  more than the simulator runs' power does at that bin, in units of the
  ensemble's spread (not a fixed factor: a chaotic peak the simulator has
  too is not a line, broadband noise lifts a bin and its neighbours alike),
  and
* is it a *line*: Thomson's harmonic F-test (a sinusoid has the same complex
  amplitude under every taper; broadband power does not).

The z threshold is the larger of a Bonferroni bound over the scanned bins and
the largest z that a simulator run reaches against the other runs
(leave-one-out), so the simulator's own variability calibrates it.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, signal, special, stats

from ._signature import zscore

#: time-bandwidth product and number of tapers.  NW = 3 keeps a line within +-3 bins (a
#: hum of 3 cycles per record stays clear of zero frequency); K = 2 NW - 1 = 5 tapers give
#: 10 degrees of freedom per bin (log-power spread 0.2 decades) and an F(2, 8) test.
NW = 3.0
K = 5
#: lowest bin scanned (cycles per record): below it a line cannot be told from a trend.
MIN_CYCLES = 2.5
#: family-wise false-line rate of the z test over the scanned bins (Bonferroni).
LINE_ALPHA = 0.01
#: p-value of the harmonic F-test below which the excess is a line (a coherent sinusoid).
#: F(2, 8) at 1e-3 is 18.5: a broadband bump that the z test lets through (a chaotic peak
#: that one run lacks) has F near 1, a line 5 % of the std in 4e4 samples has F > 100.
F_ALPHA = 1e-3
#: The two tests are also combined (Fisher): under the null the excess power (a sum of
#: taper powers) and the F ratio (how that power splits between the line's direction and
#: the rest) are independent (ratio and sum of independent chi-squares), so
#: ``p_z * p_F`` has ``P(U1 U2 < c) = c (1 - ln c)``.  A bin passes when that product is
#: family-wise significant at LINE_ALPHA -- provided both tests point the same way on their
#: own (gates below): a 1 % hum in 15000 Mackey-Glass samples with 2.3 % noise reached
#: z = 3.4 (< 4.7, the z test's Bonferroni bound) and p_F = 6e-5 (> 1e-3 would pass, but
#: 15000 bins make it unremarkable alone), together p = 2e-8 against a bound of 4e-8.
#: The gates: the power must stand out of the ensemble at least this much (a coherent F in a
#: bin whose power the runs share is the continuum's own) ...
Z_GATE = 2.0
#: ... and the F-test alone must reach this p-value (a broadband bump that one run lacks
#: has F near 1, p ~ 0.4, however large its z).
F_GATE = 0.01
#: half-width (bins) of the neighbourhood that pools the ensemble's per-bin variance.
POOL = 16
#: zero-padding factor of the scan: the F-test assumes the line at the bin's frequency; a
#: line half a bin off leaks into the odd tapers and its F drops from >1e3 to ~3 (measured
#: on Mackey-Glass with a 1 % line at 19990.5 cycles per 4e4 samples); on a grid of a
#: quarter bin the offset is at most 1/8 bin.
PAD = 4


@dataclass(frozen=True)
class Line:
    """A spectral line of the real series that the simulator ensemble lacks.

    ``frequency`` in cycles per time unit (refined far below one bin),
    ``amplitude`` of the sinusoid in standard units of the real series,
    ``phase`` at t = 0 (sine convention), ``z`` the excess of its power over
    the ensemble in ensemble spreads, ``f_stat`` / ``p_value`` the harmonic
    F-test, ``bin_width`` = 1 / (n dt) and ``half_width`` = NW bins: the line
    occupies ``frequency +- half_width`` in the multitaper spectrum.
    """

    frequency: float
    amplitude: float
    phase: float
    z: float
    f_stat: float
    p_value: float
    bin_width: float
    half_width: float


@functools.lru_cache(maxsize=32)
def tapers(n):
    """The ``K`` DPSS tapers of length ``n`` (unit energy; cached: 0.3 s at n = 4e4)."""
    return np.asarray(signal.windows.dpss(n, NW, K), dtype=float)


def eigencoefficients(z, pad=PAD):
    """``(K, pad * n // 2 + 1)`` tapered DFTs of a (z-scored) series, zero-padded ``pad``-fold."""
    return np.fft.rfft(tapers(z.size) * z[None, :], n=pad * z.size, axis=1)


def log_power(coef):
    """log10 multitaper power per bin (mean over tapers)."""
    return np.log10(np.mean(np.abs(coef) ** 2, axis=0) + 1e-300)


def harmonic_f(coef, n):
    """Thomson's harmonic F statistic per bin and its p-value (F(2, 2K - 2))."""
    u0 = tapers(n).sum(axis=1)  # U_k(0); odd tapers sum to ~0 and carry no line
    mu = (u0[:, None] * coef).sum(axis=0) / np.sum(u0**2)
    resid = np.sum(np.abs(coef - mu[None, :] * u0[:, None]) ** 2, axis=0)
    f = (K - 1) * np.abs(mu) ** 2 * np.sum(u0**2) / np.maximum(resid, 1e-300)
    return f, stats.f.sf(f, 2, 2 * K - 2), mu


#: variance of log10 of a chi-square with 2K degrees of freedom divided by its mean: the
#: floor of the per-bin spread of the multitaper log power
LOG_VAR = (math.log10(math.e) ** 2) * float(special.polygamma(1, K))


def _pooled_var(logs):
    """Per-bin variance of the ensemble's log power, pooled over +-POOL bins, floored."""
    v = logs.var(axis=0, ddof=1) if logs.shape[0] > 1 else np.zeros(logs.shape[1])
    width = 2 * POOL * PAD + 1
    if v.size > width:
        v = ndimage.median_filter(v, size=width, mode="nearest")
    return np.maximum(v, LOG_VAR)


#: half-width of the local continuum, in line half-widths (NW bins): a line fills 1/12 of it
CONTINUUM = 12


#: the continuum of a bin leaves out its own +-GAP_W line half-widths (the line itself)
GAP_W = 3


def narrow_excess(log_power_):
    """log power over the median of its neighbourhood: what is narrow.

    The neighbourhood is the bins GAP_W..CONTINUUM line half-widths away on
    either side (on one side only near zero frequency and Nyquist, where the
    other side does not exist: a hum of 3 cycles per record sits next to the
    notch that removing the mean leaves at zero frequency).  Broadband
    differences (measurement noise lifting the high frequencies, a low-pass)
    lift a bin and its neighbourhood alike and cancel here; a line does not.
    """
    y = np.asarray(log_power_, dtype=float)
    g, far = int(GAP_W * NW * PAD), int(CONTINUUM * NW * PAD)
    size = far - g + 1
    if y.size <= 2 * far + 1:
        return y - np.median(y)
    # one-sided running medians: right[i] over y[i+g .. i+far], left[i] over y[i-far .. i-g]
    ahead = ndimage.median_filter(y, size=size, origin=-(size // 2), mode="nearest")
    behind = ndimage.median_filter(y, size=size, origin=size // 2, mode="nearest")
    right = np.full(y.size, np.nan)
    left = np.full(y.size, np.nan)
    right[: y.size - g] = ahead[g:]
    left[g:] = behind[: y.size - g]
    i = np.arange(y.size)
    right[i + far > y.size - 1] = np.nan
    left[i - far < 0] = np.nan
    continuum = np.where(np.isnan(left), right, np.where(np.isnan(right), left,
                                                         0.5 * (left + right)))
    return y - continuum


def _zmap(real_excess, excesses):
    k = excesses.shape[0]
    return ((real_excess - excesses.mean(axis=0))
            / np.sqrt(_pooled_var(excesses) * (1.0 + 1.0 / k)))


def joint_p(z, p_f):
    """Fisher's combination of the power excess (z, one-sided) and the F-test's p-value:
    ``P(U1 U2 <= p_z p_F) = c (1 - ln c)`` for independent uniform p-values."""
    c = np.maximum(stats.norm.sf(np.asarray(z, dtype=float)) * np.asarray(p_f), 1e-300)
    return c * (1.0 - np.log(c))


def find_lines(real, sims, sample_dt, *, max_lines=5):
    """Spectral lines of ``real`` that the simulated runs ``sims`` lack (strongest first):
    the first list of :func:`line_scan`."""
    return line_scan(real, sims, sample_dt, max_lines=max_lines)[0]


#: sub-threshold line candidates kept as starting points of a hum fit (:func:`line_scan`)
MAX_HINTS = 3


def line_scan(real, sims, sample_dt, *, max_lines=5):
    """``(lines, hints, start)``: the spectral lines of ``real`` that the simulated runs
    ``sims`` lack (strongest first), up to :data:`MAX_HINTS` sub-threshold candidates, and
    the record's most coherent bin (a starting point of a hum fit only).

    A hint passes both gates (power ``Z_GATE`` spreads above the ensemble, harmonic
    F-test below ``F_GATE``) but not the family-wise test; hints are ranked by the
    combined p-value.  They are not reported as lines: a hum fit may start from them
    and must then earn its place by the gap it removes.  A 0.33-std hum of 4 cycles per
    record on the electro-optic oscillator (6000 samples at step 0.25), where the
    oscillator's own low-frequency continuum is strong, reached z = 3.6 and p_F = 3e-3
    (combined 6e-6 against a family bound of 3e-6); no line was found, the hum was fitted
    elsewhere, and dynamical noise was named.  At the hum's frequency the gap fell from 13.3
    to 1.1.

    Parameters
    ----------
    real : ndarray (n,)
        The measured series (any gain and offset).
    sims : sequence of ndarray
        Clean simulator runs (at least 3, each at least ``n`` samples).
    sample_dt : float
        Sampling step in time units.
    max_lines : int, default=5
        At most this many lines are returned.

    Returns
    -------
    lines : list of Line
        Empty when no bin passes both the z test and the F-test.
    hints : list of Line
        Sub-threshold candidates away from the lines (may be empty).
    start : Line or None
        The bin with the smallest harmonic-F p-value among those whose narrow
        excess lies above the runs' mean there, when it is neither a line nor a
        hint, the F-test alone reaches the family-wise bound and the record's
        power there lies beyond the runs' (:func:`_beyond_runs`).  Not evidence of a
        line (the dynamics' own sharp peaks are as coherent): a hum that sits
        on one of them raises it only slightly above the runs', under every
        z gate.  Mackey-Glass (6000 samples, benchmark seed 16.7e6): a 0.60-std
        hum at 0.0100 cycles per sample, on the dynamics' subharmonic peak,
        reached z = 1.25 with p_F = 9e-8, the record's most coherent bin by a
        factor of 300 (the runs' own smallest p_F: 1.5e-9 to 2.5e-5); no line
        or hint was found, no hum was fitted there, and nothing was named.
    """
    z = zscore(real)
    n = z.size
    runs = [zscore(np.asarray(s, dtype=float)[:n]) for s in sims]
    if len(runs) < 3:
        return [], [], None
    coef = eigencoefficients(z)
    real_raw = log_power(coef)
    real_log = narrow_excess(real_raw)
    # each run's tapered DFTs once: its power and its F-test serve both families' calibration
    run_coefs = [eigencoefficients(r) for r in runs]
    raws = np.array([log_power(c) for c in run_coefs])
    run_pf = np.array([harmonic_f(c, n)[1] for c in run_coefs])
    del run_coefs
    logs = np.array([narrow_excess(raw) for raw in raws])
    f_stat, p_f, _ = harmonic_f(coef, n)
    lo = math.ceil(MIN_CYCLES * PAD)
    scan = np.arange(lo, real_log.size - PAD)  # the Nyquist bin carries no phase
    z_real = _zmap(real_log, logs)
    # calibration: how far does one simulator run stick out of the others, at bins that
    # also pass the F-test?  (a chaotic run's sharp peaks are the simulator's variability)
    null, null_joint = 0.0, np.inf
    for j in range(len(runs)):
        others = np.delete(logs, j, axis=0)
        zj = _zmap(logs[j], others)[scan]
        pj = run_pf[j]
        hit = pj[scan] < F_ALPHA
        if np.any(hit):
            null = max(null, float(np.max(zj[hit])))
        gate = (zj > Z_GATE) & (pj[scan] < F_GATE)
        if np.any(gate):
            null_joint = min(null_joint, float(np.min(joint_p(zj[gate], pj[scan][gate]))))
    # the padded grid is oversampled PAD-fold: scan.size / PAD independent bins
    family = LINE_ALPHA * PAD / scan.size
    threshold = max(float(stats.norm.isf(family)), null)
    joint = joint_p(z_real[scan], p_f[scan])
    both = (z_real[scan] > threshold) & (p_f[scan] < F_ALPHA)
    combined = ((z_real[scan] > Z_GATE) & (p_f[scan] < F_GATE)
                & (joint < min(family, null_joint)))
    low, z_low = _low_band(scan, real_raw, raws, run_pf, p_f)
    flagged = both | combined | low
    # a line found by the low band's test reports its power's excess (what found it)
    z_real = z_real.copy()
    z_real[scan[low]] = np.maximum(z_real[scan[low]], z_low[low])
    gated = (z_real[scan] > Z_GATE) & (p_f[scan] < F_GATE) & ~flagged
    df = 1.0 / (n * sample_dt)

    def clusters(cand):
        # one line per cluster of flagged bins (a line spreads over +-NW bins)
        groups, start = [], 0
        for i in range(1, cand.size + 1):
            if i == cand.size or cand[i] - cand[i - 1] > 2 * NW * PAD:
                groups.append(cand[start:i])
                start = i
        out = []
        for g in groups:
            k = int(g[np.argmax(f_stat[g])])
            freq = _refine(z, k / PAD, sample_dt)
            amp, phase = _amplitude(z, freq, sample_dt)
            out.append((float(joint[k - lo]), Line(
                frequency=freq, amplitude=amp, phase=phase, z=float(z_real[k]),
                f_stat=float(f_stat[k]), p_value=float(p_f[k]), bin_width=df,
                half_width=NW * df)))
        return out

    lines = [line for _, line in clusters(scan[flagged])]
    lines.sort(key=lambda line: -line.z)
    # hints away from the lines (a line's own flanks pass the gates too), best joint p first
    hints = [h for _, h in sorted(clusters(scan[gated]), key=lambda item: item[0])
             if all(abs(h.frequency - line.frequency) > 2 * NW * df for line in lines)]
    lines, hints = lines[:max_lines], hints[:MAX_HINTS]
    above = scan[z_real[scan] > 0]
    start = None
    if above.size:
        k = int(above[np.argmin(p_f[above])])
        freq = k / PAD * df
        if (p_f[k] < family and _beyond_runs(real_raw[k], raws[:, k])
                and all(abs(freq - ln.frequency) > 2 * NW * df for ln in lines + hints)):
            start = clusters(np.array([k]))[0][1]
    return lines, hints, start


#: The low band: bins whose narrow-excess continuum has one side only (closer to zero
#: frequency than CONTINUUM line half-widths, 36 cycles per record at NW = 3).  There a
#: slow hum's own skirt (+-NW bins) and the notch of the removed mean make up much of the
#: continuum, and a system whose low-frequency power varies from run to run (the electro-
#: optic band-pass near its low cut-off) leaves the narrow excess no contrast: a 0.36-std
#: hum of 3.6 cycles per record on the electro-optic oscillator (6000 samples at step 0.25,
#: benchmark seed 17.0e6) stood 0.75 decades above the runs' power (z 2.7 against their
#: spread) with p_F = 1.1e-3, but its narrow excess reached z = 2.1 only, and nothing was
#: named.  So the low band is also tested on the power itself against the runs' (the same
#: z map on the raw log power), combined with the F-test as in the main test, as a second
#: family with its own false-line rate LINE_ALPHA over the low band's bins and its own
#: leave-one-out calibration.  A broadband low-frequency change (a drift, a trend) lifts
#: the power there too but is not coherent: the F gate keeps it out.


def _low_band(scan, real_raw, raws, run_pf, p_f):
    """``(flags, z)`` over ``scan``: the bins the low-band test flags (see the notes above)
    and the z of their power against the runs' (NaN outside the low band)."""
    far = int(CONTINUUM * NW * PAD)
    low = scan < far
    out, z_out = np.zeros(scan.size, dtype=bool), np.full(scan.size, np.nan)
    if np.count_nonzero(low) < PAD or raws.shape[0] < 3:
        return out, z_out
    bins = scan[low]
    family = LINE_ALPHA * PAD / bins.size
    z_low = _zmap(real_raw, raws)[bins]
    # calibration as in the main test: how far one run's power sticks out of the others'
    null, null_joint = 0.0, np.inf
    for j in range(raws.shape[0]):
        zj = _zmap(raws[j], np.delete(raws, j, axis=0))[bins]
        pj = run_pf[j][bins]
        if np.any(pj < F_ALPHA):
            null = max(null, float(np.max(zj[pj < F_ALPHA])))
        gate = (zj > Z_GATE) & (pj < F_GATE)
        if np.any(gate):
            null_joint = min(null_joint, float(np.min(joint_p(zj[gate], pj[gate]))))
    threshold = max(float(stats.norm.isf(family)), null)
    pf = p_f[bins]
    hit = ((z_low > threshold) & (pf < F_ALPHA)) | (
        (z_low > Z_GATE) & (pf < F_GATE) & (joint_p(z_low, pf) < min(family, null_joint)))
    out[np.flatnonzero(low)[hit]] = True
    z_out[low] = z_low
    return out, z_out


def _beyond_runs(value, values):
    """Is ``value`` above the one-sided ``1 - LINE_ALPHA`` prediction bound of ``values``
    (Student t: the next of the runs would lie below it but for chance)?

    The test of the one bin :func:`line_scan` offers as a hum's start: the record's power
    there must exceed what the dynamics make, not only its coherence.  A hum on Mackey-
    Glass' peak at 0.01 cycles per sample lay 10-15 of the runs' spreads above them (the
    benchmark record of seed 16.7e6 and the test record); a tanh-compressed detector (seed
    16.8e6, a cause outside the library) 2.0 spreads above them at the main peak, where a
    0.94-std hum fitted from it then removed 75 % of the gap.
    """
    v = np.asarray(values, dtype=float)
    k = v.size
    if k < 3:
        return False
    bound = v.mean() + stats.t.ppf(1.0 - LINE_ALPHA, k - 1) * v.std(ddof=1) * math.sqrt(1 + 1 / k)
    return bool(value > bound)


def _refine(z, k, sample_dt, pad=16):
    """Line frequency to a small fraction of a bin: maximum of the harmonic F on a finer grid.

    The F statistic peaks at the line's frequency (the tapered DFTs are
    coherent there); it is evaluated on a grid of ``1 / pad`` bin within one
    bin of (fractional) bin ``k`` and refined by a parabola through the best
    three points.
    """
    n = z.size
    v = tapers(n)
    u0 = v.sum(axis=1)
    t = np.arange(n)
    grid = k + np.arange(-pad, pad + 1) / pad
    vals = np.empty(grid.size)
    tz = v * z[None, :]
    for i, b in enumerate(grid):
        c = tz @ np.exp(-2j * np.pi * b * t / n)
        mu = (u0 * c).sum() / np.sum(u0**2)
        resid = np.sum(np.abs(c - mu * u0) ** 2)
        vals[i] = np.abs(mu) ** 2 / max(resid, 1e-300)
    i = int(np.argmax(vals))
    best = grid[i]
    if 0 < i < grid.size - 1:
        a, b, c = np.log(vals[i - 1:i + 2] + 1e-300)
        den = a - 2 * b + c
        if den < 0:
            best += 0.5 * (a - c) / den / pad
    return float(best / (n * sample_dt))


def line_amplitude(x, freq, sample_dt):
    """Amplitude (standard units of ``x``) and phase of a sinusoid at ``freq`` in ``x``."""
    return _amplitude(zscore(np.asarray(x, dtype=float)), freq, sample_dt)


def _amplitude(z, freq, sample_dt):
    """Amplitude (standard units) and phase (sine convention, at t = 0) of the line at ``freq``.

    The taper-weighted mean complex amplitude: for ``A sin(2 pi f t + phi)``
    every tapered DFT at ``f`` is ``A / (2i) exp(i phi) U_k(0)``.
    """
    n = z.size
    v = tapers(n)
    u0 = v.sum(axis=1)
    t = np.arange(n) * sample_dt
    c = (v * z[None, :]) @ np.exp(-2j * np.pi * freq * t)
    mu = (u0 * c).sum() / np.sum(u0**2)
    return float(2.0 * np.abs(mu)), float((np.angle(mu) + np.pi / 2.0) % (2.0 * np.pi))


def without_lines(x, lines, sample_dt):
    """``x`` in standard units with the sinusoid of each line removed (amplitude and phase
    re-estimated on ``x`` itself): the dynamics' own spectrum, for checks that must not
    mistake a hum for one of its features."""
    z = zscore(np.asarray(x, dtype=float))
    t = np.arange(z.size) * sample_dt
    for line in lines:
        amp, phase = _amplitude(z, line.frequency, sample_dt)
        z = z - amp * np.sin(2.0 * np.pi * line.frequency * t + phase)
    return z


@functools.lru_cache(maxsize=16)
def _basis(n, frequencies, sample_dt):
    """``(cos, sin)`` matrices ``(n, m)`` at ``frequencies`` (cached: the line indicator
    evaluates the same frequencies on runs of the same length again and again).

    Real matrices: a real-by-complex matrix product misses the BLAS path and
    was 50 times slower (0.28 s per run of 4e4 samples).
    """
    phase = 2.0 * np.pi * np.outer(np.arange(n) * sample_dt, np.asarray(frequencies))
    return np.ascontiguousarray(np.cos(phase)), np.ascontiguousarray(np.sin(phase))


#: the line feature uses a prefix of the run whose length is a multiple of this: runs of
#: many slightly different lengths (a time-base factor resamples them) share tapers and bases
LENGTH_STEP = 512


def line_feature(z, frequency, sample_dt, n_ref):
    """log10 of the multitaper power at ``frequency`` over the local continuum.

    The continuum is the median power at 3..12 half-widths on either side.
    A line's excess grows with the record length, the continuum's does not:
    for a run of another length than the real record (``n_ref``) the excess
    is rescaled to ``n_ref`` so that runs of any length are comparable.  A
    ratio below 1 is a trough of the continuum, not a line, and is left as it
    is: rescaling it as an excess pushed it through zero.
    """
    n = z.size if z.size < LENGTH_STEP else (z.size // LENGTH_STEP) * LENGTH_STEP
    z = z[:n]
    df = 1.0 / (n * sample_dt)
    offsets = np.concatenate([-np.arange(3, 13), np.arange(3, 13)]) * NW * df
    freqs = np.concatenate([[frequency], frequency + offsets])
    freqs = freqs[(freqs > 0) & (freqs < 0.5 / sample_dt)]
    cos, sin = _basis(n, tuple(freqs), float(sample_dt))
    tz = tapers(n) * z[None, :]
    power = np.mean((tz @ cos) ** 2 + (tz @ sin) ** 2, axis=0)
    ratio = power[0] / max(float(np.median(power[1:])), 1e-300)
    # A hum of 13 cycles per 6000-sample Mackey-Glass record sits where the continuum is
    # 10x below its median over the flanks (ratio ~0.06 in clean runs); the run prefix of
    # 5632 samples rescaled that by 6000/5632 to below zero, one clean run read the floor
    # (log10 -3), and the inflated spread hid the hum's line (z 8.4) from the indicator.
    if ratio > 1.0:
        ratio = 1.0 + (ratio - 1.0) * (n_ref / n)
    return float(np.log10(max(ratio, 1e-3)))


def spectrum_view(real, sims, sample_dt, n_points=400):
    """Whole-record multitaper spectra on a log-frequency grid, for the report's figure.

    Returns ``(frequency, real, simulated)``: bin centres (cycles per time
    unit, from one cycle per record to Nyquist) and log10 power spectral
    densities (standard units squared per cycle per time unit) of the real
    series and the mean of the runs.  Each log bin keeps its highest value so
    that a line one bin wide survives the thinning.
    """
    n = len(real)
    df = 1.0 / (n * sample_dt)

    def binned(x):
        p = np.mean(np.abs(eigencoefficients(zscore(np.asarray(x, dtype=float)[:n]), pad=1))
                    ** 2, axis=0) * (2.0 * sample_dt)
        f = np.arange(p.size) * df
        edges = np.geomspace(df, f[-1], n_points + 1)
        idx = np.digitize(f, edges) - 1
        keep = (idx >= 0) & (idx < n_points)
        out = np.full(n_points, -np.inf)
        np.maximum.at(out, idx[keep], np.log10(p[keep] + 1e-300))
        return np.sqrt(edges[:-1] * edges[1:]), out

    f, r = binned(real)
    s = np.mean([binned(x)[1] for x in sims], axis=0)
    ok = np.isfinite(r) & np.isfinite(s)
    return f[ok], r[ok], s[ok]
