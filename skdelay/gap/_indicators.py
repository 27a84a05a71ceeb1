"""Indicators: profiles of a series that real and simulated data should share.

Every indicator turns a (z-scored, so gain and offset do not matter) series
into a vector of features, one per *bin* (a frequency band, a value range, a
lag, a time segment, ...).  The features of the simulator's ensemble (runs
with other seeds) give a mean and a spread per bin, and a real series is
compared through z-scores against that spread: "no gap" is a statistical
statement.  Bins know their bounds in physical units (frequency in cycles
per time unit, values in the units of the real data, lags and times in time
units) for the localisation table.

The ``fast`` indicators (spectrum, band_spectrum, histogram, increments, autocorrelation,
segment, levels, pile_ups) are cheap and drive the parameter searches; the ``full``
ones (forecast_error, cross_prediction) are computed once per fitted
candidate.
"""

from __future__ import annotations

import hashlib

import numpy as np
from scipy import signal

from .._memo import BoundedStore
from ._signature import mean_std, zscore

#: z-scores are capped at this value so that one bin cannot dominate a gap.
Z_CAP = 30.0


class Indicator:
    """Base class: ``setup`` once from real + simulated runs, then ``profile`` per series.

    ``profile(z)`` takes a z-scored series and returns ``(features, blocks)``:
    the feature vector of the whole series and, for indicators with
    ``blocks > 1``, the features of that many consecutive blocks (used for a
    stable estimate of the spread; None otherwise).
    """

    name = "indicator"
    tier = "fast"
    paired = False
    feature = ""
    unit = ""
    var_floor = 1e-8
    smooth = 0  # half-width of the running pool of bin variances (0: median per label)
    blocks = 0

    def setup(self, real, sims, sample_dt, delay_samples):
        """Fix the binning from the real series and the clean simulated runs."""
        self.sample_dt = float(sample_dt)
        self.real_mean, self.real_std = mean_std(real)

    def profile(self, z, blocks=False):
        """``(features, block_features or None)`` of a z-scored series."""
        raise TypeError("Indicator subclasses implement profile().")

    def compute(self, x):
        """Feature vector of a series (any gain and offset)."""
        return self.profile(zscore(x))[0]

    def bounds(self):
        """``(low, high)`` arrays: bin bounds in physical units."""
        raise TypeError("Indicator subclasses implement bounds().")

    def labels(self):
        """Per-bin feature label (default: the indicator's ``feature``)."""
        return [self.feature] * len(self.bounds()[0])


def _binned(idx, n_total, n_blocks):
    """Fractions per bin index of the whole array and of ``n_blocks`` consecutive blocks."""
    full = np.bincount(idx, minlength=n_total) / idx.size
    if n_blocks < 2:
        return np.sqrt(full), None
    parts = np.array_split(idx, n_blocks)
    blocks = np.array([np.bincount(p, minlength=n_total) / p.size for p in parts])
    return np.sqrt(full), np.sqrt(blocks)


class Spectrum(Indicator):
    """log10 Welch power spectral density (Hann, 50 % overlap) per frequency bin.

    Same estimate as :func:`skdelay.validation.power_spectrum` / ``scipy.signal.welch``,
    computed from one pass over the segment periodograms so that the block
    spectra (for the spread) come for free.
    """

    name = "spectrum"
    feature = "log10 power"
    unit = "cycles per time unit"
    var_floor = 0.02**2
    smooth = 8
    blocks = 4

    def setup(self, real, sims, sample_dt, delay_samples):
        super().setup(real, sims, sample_dt, delay_samples)
        n = len(real)
        self.nperseg = int(2 ** np.clip(np.floor(np.log2(n / 8)), 6, 10))
        self.window = signal.get_window("hann", self.nperseg)
        self.scale = 1.0 / ((self.window**2).sum() / self.sample_dt)
        self.freqs = np.fft.rfftfreq(self.nperseg, d=self.sample_dt)[1:]

    def profile(self, z, blocks=False):
        seg = np.lib.stride_tricks.sliding_window_view(z, self.nperseg)[:: self.nperseg // 2]
        seg = (seg - seg.mean(axis=1, keepdims=True)) * self.window
        p = np.abs(np.fft.rfft(seg, axis=1)[:, 1:]) ** 2 * (2 * self.scale)
        if self.nperseg % 2 == 0:
            p[:, -1] /= 2
        full = np.log10(p.mean(axis=0) + 1e-30)
        if not blocks or p.shape[0] < 2 * self.blocks:
            return full, None
        groups = np.array_split(p, self.blocks)
        return full, np.log10(np.array([g.mean(axis=0) for g in groups]) + 1e-30)

    def bounds(self):
        df = 1.0 / (self.nperseg * self.sample_dt)
        return self.freqs - df / 2, self.freqs + df / 2


#: bands of the band-averaged spectrum: log-spaced edges (in Welch bins), at least this many
#: bins per band
BAND_MIN_BINS = 4
#: ... and at most this many bands
N_BANDS = 24


class BandSpectrum(Spectrum):
    """log10 of the Welch power averaged over log-spaced frequency bands (the broadband view).

    A broadband change (white noise under a nearly white chaotic signal, a slightly
    different time scale) lifts or tilts hundreds of Welch bins by a few hundredths of a
    decade each: every bin scatters by 0.07-0.1 decades between runs (Ikeda, step 0.5,
    2e4 samples, 1024-sample segments), so each bin's z stays near 1 and the mean squared
    z of :class:`Spectrum` does not move (20 % measurement noise on that Ikeda record:
    spectrum gap 0.03).  Averaged over a band of ``b`` bins the scatter falls about as
    ``1 / sqrt(b)`` while the shift stays: the same excess reads as several spreads per
    band.  The spread comes from the ensemble as for every indicator.
    """

    name = "band_spectrum"
    feature = "band-averaged log10 power"
    var_floor = 0.003**2
    smooth = 2

    def setup(self, real, sims, sample_dt, delay_samples):
        super().setup(real, sims, sample_dt, delay_samples)
        n_bins = self.freqs.size
        edges = np.unique(np.round(np.geomspace(1, n_bins + 1, N_BANDS + 1)).astype(int)) - 1
        keep = [0]
        for e in edges[1:]:
            if e - keep[-1] >= BAND_MIN_BINS:
                keep.append(int(e))
        if keep[-1] != n_bins:
            if n_bins - keep[-1] < BAND_MIN_BINS and len(keep) > 1:
                keep[-1] = n_bins
            else:
                keep.append(n_bins)
        self.edges = np.array(keep)

    def _bands(self, logp):
        p = 10.0 ** np.asarray(logp)
        sums = np.add.reduceat(p, self.edges[:-1], axis=-1)
        return np.log10(sums / np.diff(self.edges) + 1e-30)

    def profile(self, z, blocks=False):
        full, blk = super().profile(z, blocks)
        return self._bands(full), (None if blk is None else self._bands(blk))

    def bounds(self):
        lo, hi = super().bounds()
        return lo[self.edges[:-1]], hi[self.edges[1:] - 1]


class Histogram(Indicator):
    """sqrt of the fraction of samples per value bin (z-scored), with two overflow bins."""

    name = "histogram"
    feature = "sqrt probability"
    unit = "units of real data"
    var_floor = 1e-4**2
    smooth = 3
    blocks = 4

    def setup(self, real, sims, sample_dt, delay_samples):
        super().setup(real, sims, sample_dt, delay_samples)
        zs = np.concatenate([zscore(s) for s in sims])
        lo, hi = float(zs.min()), float(zs.max())
        pad = 0.02 * (hi - lo)
        self.lo, self.hi = lo - pad, hi + pad
        self.n_bins = int(np.clip(len(real) // 400, 16, 48))
        self.var_floor = 0.25 / len(real)  # Poisson spread of sqrt(count / n)
        zr = zscore(real)
        self.zmin, self.zmax = min(float(zr.min()), self.lo), max(float(zr.max()), self.hi)

    def profile(self, z, blocks=False):
        width = (self.hi - self.lo) / self.n_bins
        idx = np.floor((z - self.lo) / width).astype(np.int64)
        idx = np.clip(idx, -1, self.n_bins) + 1
        return _binned(idx, self.n_bins + 2, self.blocks if blocks else 0)

    def bounds(self):
        edges = np.linspace(self.lo, self.hi, self.n_bins + 1)
        zl = np.concatenate([[self.zmin], edges[:-1], [self.hi]])
        zh = np.concatenate([[self.lo], edges[1:], [self.zmax]])
        return self.real_mean + self.real_std * zl, self.real_mean + self.real_std * zh


class Increments(Indicator):
    """Shape of the distribution of one-step increments (self-normalised), with overflow bins.

    Separates Gaussian measurement noise (Gaussian increments) from sparse
    spikes (heavy tails) and ADC steps (a comb) at equal spectral floor.
    """

    name = "increments"
    feature = "sqrt probability of increment"
    unit = "increment / its std"
    var_floor = 1e-4**2
    smooth = 2
    blocks = 4
    span = 6.0
    n_bins = 40

    def setup(self, real, sims, sample_dt, delay_samples):
        super().setup(real, sims, sample_dt, delay_samples)
        self.var_floor = 0.25 / len(real)  # Poisson spread of sqrt(count / n)

    def profile(self, z, blocks=False):
        d = np.diff(z)
        sd = d.std()
        d = d / (sd if sd > 0 else 1.0)
        width = 2 * self.span / self.n_bins
        idx = np.clip(np.floor((d + self.span) / width).astype(np.int64), -1, self.n_bins) + 1
        return _binned(idx, self.n_bins + 2, self.blocks if blocks else 0)

    def bounds(self):
        edges = np.linspace(-self.span, self.span, self.n_bins + 1)
        lo = np.concatenate([[-np.inf], edges[:-1], [self.span]])
        hi = np.concatenate([[-self.span], edges[1:], [np.inf]])
        return lo, hi


class Autocorrelation(Indicator):
    """Autocorrelation function at up to 150 lags spanning about three delays."""

    name = "autocorrelation"
    feature = "autocorrelation"
    unit = "time units (lag)"
    var_floor = 1e-3**2
    smooth = 5
    blocks = 4

    def setup(self, real, sims, sample_dt, delay_samples):
        super().setup(real, sims, sample_dt, delay_samples)
        n = len(real)
        span = 3 * delay_samples if delay_samples else 100
        self.max_lag = int(min(max(span, 60), n // 8))
        self.lags = np.unique(np.linspace(1, self.max_lag, min(self.max_lag, 150)).astype(int))

    def profile(self, z, blocks=False):
        from .._correlation import autocorrelation

        full = np.asarray(autocorrelation(z, self.max_lag))[self.lags]
        if not blocks:
            return full, None
        parts = [np.asarray(autocorrelation(b, self.max_lag))[self.lags]
                 for b in np.array_split(z, self.blocks)]
        return full, np.array(parts)

    def bounds(self):
        return (self.lags - 0.5) * self.sample_dt, (self.lags + 0.5) * self.sample_dt


class Segment(Indicator):
    """Per time segment: mean, log std and spectral centroid, relative to the first segment.

    Stationary data give zeros within sim-vs-sim spread; a drift shows up in
    the late segments.
    """

    name = "segment"
    unit = "time units"
    var_floor = 1e-3**2
    #: under the null (a stationary simulator) every segment's statistic relative to the
    #: first has the same spread: the spread of a statistic is pooled over its segments
    #: (3 x 5 degrees of freedom from 6 runs instead of 5).  A bin's own 5-dof variance
    #: came out small by chance on a no-effect Mackey-Glass control (6000 samples): one
    #: segment mean at z = 6.5 made the whole record "significant" (gap 7.5 > 7.0) and a
    #: delay change of 0.02 "explained" it (shrink 0.62).
    exchangeable = True
    stats = ("segment mean", "segment log std", "segment spectral centroid")

    def setup(self, real, sims, sample_dt, delay_samples):
        super().setup(real, sims, sample_dt, delay_samples)
        self.n = len(real)
        self.n_seg = 8 if self.n >= 8000 else 4

    def profile(self, z, blocks=False):
        n = (z.size // self.n_seg) * self.n_seg
        parts = z[:n].reshape(self.n_seg, -1)
        mean = parts.mean(axis=1)
        power = np.abs(np.fft.rfft(parts - mean[:, None], axis=1)) ** 2
        freq = np.fft.rfftfreq(parts.shape[1])
        rows = np.column_stack([mean, np.log(parts.std(axis=1) + 1e-12),
                                power @ freq / (power.sum(axis=1) + 1e-300)])
        rel = rows[1:] - rows[0]
        return rel.T.reshape(-1), None  # stat-major: every segment of stat 0, then stat 1, ...

    def bounds(self):
        edges = np.linspace(0, self.n, self.n_seg + 1)[1:] * self.sample_dt
        lo = np.tile(edges[:-1], len(self.stats))
        hi = np.tile(edges[1:], len(self.stats))
        return lo, hi

    def labels(self):
        return [s for s in self.stats for _ in range(self.n_seg - 1)]


class SpectralLines(Indicator):
    """Per spectral line found in the real record (:func:`find_lines`): log10 of the
    multitaper power at the line over the local continuum.

    Only set up when the real record has lines the simulator lacks; its bins
    are those lines, so a hum of a few cycles per record (invisible to the
    Welch spectrum) enters the gap, the fits and the localisation table.
    """

    name = "spectral_line"
    feature = "line power over the local continuum (log10)"
    unit = "cycles per time unit"

    def __init__(self, lines):
        self.lines = list(lines)

    def setup(self, real, sims, sample_dt, delay_samples):
        from ._lines import LOG_VAR

        super().setup(real, sims, sample_dt, delay_samples)
        self.n_ref = len(real)
        # a ratio of two multitaper estimates: twice the variance of one log power
        self.var_floor = 2.0 * LOG_VAR

    def profile(self, z, blocks=False):
        from ._lines import line_feature

        n = min(z.size, self.n_ref)
        return np.array([line_feature(z[:n], line.frequency, self.sample_dt, self.n_ref)
                         for line in self.lines]), None

    def bounds(self):
        f = np.array([line.frequency for line in self.lines])
        w = np.array([line.half_width for line in self.lines])
        return f - w, f + w


class Levels(Indicator):
    """log10 of the fraction of distinct values (ADC resolution)."""

    name = "levels"
    feature = "log10 fraction of distinct values"
    unit = "units of real data"
    var_floor = 0.02**2

    def setup(self, real, sims, sample_dt, delay_samples):
        super().setup(real, sims, sample_dt, delay_samples)
        self.range = (float(np.min(real)), float(np.max(real)))

    def profile(self, z, blocks=False):
        return np.array([np.log10(np.unique(z).size / z.size)]), None

    def bounds(self):
        return np.array([self.range[0]]), np.array([self.range[1]])


class PileUps(Indicator):
    """sqrt of the fraction of samples that sit exactly at the lowest and at the highest
    value (a clipped end: a detector or ADC saturating holds many samples at one value).

    A continuous simulator run reaches its extremes once (fraction 1 / n); a record
    clipped on 1 % of its samples holds 60 of 6000 at one value.  The histogram sees the
    same pile-up only as a little extra mass in one of its 16-48 bins: on 6000 Ikeda
    samples (step 0.5) clipped at 1.85-2.25 std the histogram's gap was 1.2-10 (just
    around the no-gap threshold) while the tie count was 30-75 against 1.  The spread is
    the Poisson floor of sqrt(count / n), as for the histogram, since clean runs never tie.
    """

    name = "pile_ups"
    feature = "sqrt fraction of samples at the extreme value"
    unit = "units of real data"

    def setup(self, real, sims, sample_dt, delay_samples):
        super().setup(real, sims, sample_dt, delay_samples)
        self.var_floor = 0.25 / len(real)
        self.range = (float(np.min(real)), float(np.max(real)))

    def profile(self, z, blocks=False):
        lo, hi = float(np.min(z)), float(np.max(z))
        tol = 1e-9 * (hi - lo)
        counts = np.array([np.count_nonzero(z <= lo + tol), np.count_nonzero(z >= hi - tol)])
        return np.sqrt(counts / z.size), None

    def bounds(self):
        ends = np.array(self.range)
        return ends, ends

    def labels(self):
        return ["samples at the lowest value", "samples at the highest value"]


def tau_grid(delay_samples, n):
    """Lags (samples) scanned by the forecast-error indicator: dense near the delay."""
    if not delay_samples:
        top = int(min(200, n // 20))
        return np.unique(np.geomspace(1, top, 30).astype(int))
    t0 = round(delay_samples)
    dense = np.arange(max(1, t0 - 5), t0 + 6)
    sparse = np.geomspace(1, 2.2 * t0 + 2, 7).astype(int)
    return np.unique(np.concatenate([dense, sparse]))


def fe_curve(x, taus, *, m=2, n_queries=400, max_len=10_000, refine=True, with_se=False):
    """sigma_m(tau) of the first ``max_len`` samples at ``taus`` (``n_queries`` forecasts per
    delay; ``refine``: more queries around the dip, for locating it); with ``with_se`` also
    its standard error (batch means over the queries).

    The result is the plain k-d tree's per delay to the last bit (barring two neighbours'
    distances within rounding of each other); the search that gives it is chosen by
    whether the run repeats a value.  Without repeats, the scan's projected k-d
    tree (``search="tree"``), which fits each neighbourhood in the plain tree's order and sums
    the errors as it does: sigma and its standard error bit-identical on clean and noisy runs
    of Ikeda, Mackey-Glass and the electro-optic oscillator, 1.5-1.9 times faster.  A run
    that repeats values (clipped, quantized) has tied distances, and which of the tied points
    a search keeps depends on its traversal: there the plain k-d tree (``search="exact"``),
    whose choice the diagnosis was calibrated with.  Bit-identical, not merely equal to
    1e-15: such a difference moved a fitted timebase factor by one unit in the last place,
    and runs of a chaotic simulator at the two factors differ (electro-optic oscillator,
    timebase 0.98 at step 0.25, 6000 samples: gap after the fit 13.05 against 13.78); on
    benchmark seed 22.7e6 it turned a timebase into a delay mismatch.
    """
    from .._selection import forecast_error_curve

    z = zscore(np.asarray(x)[:max_len])
    search = "exact" if np.unique(z).size < z.size else "tree"
    # centre_error="redraws": the refinement the diagnosis's dip tests were calibrated with
    # (the batch error refines fewer cells, and the curves would no longer be bit-identical)
    curve = forecast_error_curve(z, m=(m,), tau=[int(t) for t in taus], n_queries=n_queries,
                                 n_neighbors=20, search=search, random_state=0, refine=refine,
                                 centre_error="redraws")
    sigma = np.asarray(curve.iloc[:, 0], dtype=float)
    if with_se:
        return sigma, np.asarray(curve.attrs["se"].iloc[:, 0], dtype=float)
    return sigma


#: the dip scan spans this many delays (a second feedback delay up to 2.5 x the model's)
SCAN_SPAN = 2.5
#: coarse steps per delay of the dip scan; the scan is refined to step 1 around its minima
SCAN_STEPS = 15


def fe_scan(series, delay_samples=None, *, max_len=10_000, with_se=False):
    """Forecast-error curve for dip location: ``(taus, sigma_2(tau))`` (and its standard
    error with ``with_se``).

    Delays 1 .. ``SCAN_SPAN`` x the model's delay on a coarse grid (step
    ``delay / SCAN_STEPS``), then step 1 around every local minimum of the
    coarse curve (the dip the delay makes and any other, e.g. of a second
    feedback delay), so that :func:`skdelay._dips.locate_dip` sees each dip
    sample by sample.  Without a delay: 1..200, geometric.
    """
    x = np.asarray(series, dtype=float)[:max_len]
    if delay_samples:
        d0 = float(delay_samples)
        step = max(1, round(d0 / SCAN_STEPS))
        coarse = np.arange(1, int(np.ceil(SCAN_SPAN * d0)) + 3, step)
    else:
        step = 1
        coarse = np.unique(np.geomspace(1, min(200, max(x.size // 20, 8)), 40).astype(int))
    curve, se = fe_curve(x, coarse, with_se=True)
    k = np.arange(1, coarse.size - 1)
    minima = k[(curve[k] <= curve[k - 1]) & (curve[k] <= curve[k + 1])]
    minima = np.union1d(minima, [int(np.argmin(curve))]).astype(int)
    dense = []
    for i in minima:
        lo, hi = coarse[max(i - 1, 0)], coarse[min(i + 1, coarse.size - 1)]
        dense.extend(range(max(1, int(lo) - 2), int(hi) + 3))
    extra = np.setdiff1d(np.unique(dense), coarse)
    if extra.size:
        c2, s2 = fe_curve(x, extra, with_se=True)
        curve, se = np.concatenate([curve, c2]), np.concatenate([se, s2])
        coarse = np.concatenate([coarse, extra])
    order = np.argsort(coarse)
    if with_se:
        return coarse[order].astype(float), curve[order], se[order]
    return coarse[order].astype(float), curve[order]


def series_dip(series, delay_samples=None):
    """:class:`skdelay._dips.Dip` of one series' forecast error (delays in samples)."""
    from .._dips import locate_dip

    taus, curve = fe_scan(series, delay_samples)
    return locate_dip(taus, curve)


#: a second dip must lie this far below the curve's baseline and below the simulator's curve
#: at the same delay (relative): the few-percent undulations of sigma(tau) stay below it
#: (skdelay._dips.MIN_RELATIVE_DEPTH: delay dips are 20-90 % deep)
SECOND_DIP_DEPTH = 0.1


def other_dips(taus, curve, main, reference=None, *, min_depth=SECOND_DIP_DEPTH, se=None,
               min_z=0.0):
    """Dips of ``curve`` away from the ``main`` one (e.g. a second feedback delay).

    A local minimum further than ``main.half_width + 2`` samples from the main
    dip counts when it is at least ``min_depth`` (relative) below the curve's
    median and below ``reference`` (the simulator's curve on the same grid),
    with ``se`` (the combined standard error of ``curve - reference`` per delay)
    at least ``min_z`` of them below ``reference``, and :func:`locate_dip` on the
    delays around it (out to the nearest local maxima) finds an interior minimum.
    Returns a list of ``Dip``.

    The standard error matters on finely sampled records: the rms of a few hundred
    local forecasts is lifted by a single failed one, and on Mackey-Glass at step 0.5
    (34 samples per delay) such spikes in the runs' and the record's curves made four
    "second dips the simulator lacks" at 44-62 samples on a record with a hum only.
    """
    from .._dips import locate_dip

    out = []
    curve = np.asarray(curve, dtype=float)
    k = np.arange(1, taus.size - 1)
    minima = k[(curve[k] < curve[k - 1]) & (curve[k] <= curve[k + 1])]
    base = float(np.median(curve))
    for i in minima:
        if abs(taus[i] - main.centre) <= main.half_width + 2:
            continue
        lo = i
        while lo > 0 and curve[lo - 1] >= curve[lo]:
            lo -= 1
        hi = i
        while hi < taus.size - 1 and curve[hi + 1] >= curve[hi]:
            hi += 1
        lo, hi = max(0, lo - 2), min(taus.size, hi + 3)
        if hi - lo < 5:
            continue
        # depths relative to the whole curve's baseline (the local window has no baseline)
        depth = 1.0 - float(curve[i]) / base
        lack = 1.0 - float(curve[i]) / float(reference[i]) if reference is not None else depth
        if depth < min_depth or lack < min_depth:
            continue
        if reference is not None and se is not None and \
                float(reference[i]) - float(curve[i]) < min_z * float(se[i]):
            continue
        dip = locate_dip(taus[lo:hi], curve[lo:hi], min_relative_depth=0.0)
        if dip.reason.startswith("the lowest error lies at the edge"):
            continue
        out.append(dip)
    return out


class ForecastError(Indicator):
    """log10 of the normalised forecast error sigma_2(tau) (floor: noise; dip: delay)."""

    name = "forecast_error"
    tier = "full"
    feature = "log10 forecast error (m=2)"
    unit = "time units (delay)"
    var_floor = 0.05**2  # the rms error of 400 forecasts scatters by ~10 %

    def setup(self, real, sims, sample_dt, delay_samples):
        super().setup(real, sims, sample_dt, delay_samples)
        self.taus = tau_grid(delay_samples, len(real))

    def profile(self, z, blocks=False):
        return self.profile_with_var(z)[0], None

    def profile_with_var(self, z):
        """The features and the variance of their estimate from this series' own queries.

        The rms of 400 local forecasts is heavy-tailed where a rare forecast fails badly
        (an ill-conditioned neighbourhood of a finely sampled series): on Mackey-Glass at
        step 0.5 (34 samples per delay, 6000 samples) one such forecast lifted a no-effect
        record's curve by 0.3-0.5 in log10 at three delays below the dip, where ten runs
        agreed within 0.03, and 3 of 10 records were significant.  The record's own
        standard error (batch means, delta method to log10) says how far its curve can be
        trusted, and enters its z-scores (:meth:`GapProblem._compare`).
        """
        # the indicator compares whole curves bin by bin, real and runs alike: the refinement
        # that places a dip centre to 0.2 samples (4-16x the queries near the dip) is not
        # needed here and took 40 % of this indicator's time (cProfile, 4e4-sample diagnosis)
        sigma, se = fe_curve(z, self.taus, refine=False, with_se=True)
        sigma = np.maximum(sigma, 1e-12)
        var = np.nan_to_num((se / (sigma * np.log(10.0))) ** 2, nan=0.0)
        return np.log10(sigma), var

    def bounds(self):
        return (self.taus - 0.5) * self.sample_dt, (self.taus + 0.5) * self.sample_dt


class CrossPrediction(Indicator):
    """log10 of chi / chi_self per state-space cell: how much worse a simulated run predicts
    the series than the series predicts itself, in 3 x 3 quantile cells of the plane
    (s_n, s_{n+1-tau}) (the paper's cross-prediction error, localised).

    Paired: the features of a series need a database run (``profile(z, database=...)``).
    """

    name = "cross_prediction"
    tier = "full"
    paired = True
    feature = "log10 chi / chi_self"
    unit = "units of real data (current value)"
    var_floor = 0.02**2
    n_regions = 3
    max_len = 10_000

    def setup(self, real, sims, sample_dt, delay_samples):
        super().setup(real, sims, sample_dt, delay_samples)
        self.tau = max(1, round(delay_samples))
        edges = np.quantile(zscore(real), np.linspace(0, 1, self.n_regions + 1))
        self.edges = self.real_mean + self.real_std * edges

    def profile(self, z, blocks=False, database=None):
        from ..validation import cross_prediction_by_region

        x = z[: self.max_len]
        db = x if database is None else database[: self.max_len]
        table = cross_prediction_by_region(x, db, m=2, tau=self.tau, n_regions=self.n_regions,
                                           n_queries=400, n_neighbors=20, random_state=0)
        i = np.searchsorted(np.unique(table["low"]), table["low"])
        j = np.searchsorted(np.unique(table["delayed_low"]), table["delayed_low"])
        chi = np.maximum(np.asarray(table["chi"], dtype=float), 1e-12)
        chi_self = np.maximum(np.asarray(table["chi_self"], dtype=float), 1e-12)
        out = np.zeros(self.n_regions**2)
        ratio = np.log10(chi / chi_self)
        # a cell the series never visits (e.g. a periodic run) carries no information
        cell = np.asarray(i * self.n_regions + j, dtype=int)
        out[cell] = np.where(np.isfinite(ratio), ratio, 0.0)
        return out, None

    def bounds(self):
        k = np.arange(self.n_regions**2) // self.n_regions
        return self.edges[k], self.edges[k + 1]

    def labels(self):
        names = ("low", "middle", "high")
        return [f"{self.feature}, delayed value {names[j]}" for _ in range(self.n_regions)
                for j in range(self.n_regions)]


FAST = (Spectrum, BandSpectrum, Histogram, Increments, Autocorrelation, Segment, Levels, PileUps)
FULL = (ForecastError, CrossPrediction)


def profiles(indicators, runs, blocks=False, n_jobs=None, cache=None):
    """``{name: (features (runs, bins), blocks (runs, n_blocks, bins) or None)}``.

    Block features (for the spread) are only computed with ``blocks=True``.
    ``n_jobs``: joblib workers over the runs (the clean ensemble's profiles, made
    once in the main process; None runs them here, as inside a fit's worker).
    ``cache``: a :class:`FeatureCache` of these ``indicators`` (used without ``n_jobs``).
    """
    zs = [zscore(x) for x in runs]
    # a paired indicator (cross-prediction) reads run j against run j + 1
    jobs = [(z, zs[(j + 1) % len(zs)]) for j, z in enumerate(zs)]
    if n_jobs is None or len(jobs) < 2:
        per_run = [_run_profiles(indicators, z, other, blocks) if cache is None
                   else cache.run_profiles(indicators, z, other, blocks)
                   for z, other in jobs]
    else:
        from joblib import Parallel, delayed

        per_run = Parallel(n_jobs=n_jobs)(
            delayed(_run_profiles)(indicators, z, other, blocks) for z, other in jobs)
    out = {}
    for name in indicators:
        res = [r[name] for r in per_run]
        full = np.array([r[0] for r in res])
        blk = None if any(r[1] is None for r in res) else np.array([r[1] for r in res])
        out[name] = (full, blk)
    return out


def _profile(ind, z, other, blocks):
    """One indicator's ``(features, blocks)`` of one z-scored run."""
    return (ind.profile(z, database=other) if getattr(ind, "paired", False)
            else ind.profile(z, blocks=blocks))


def _run_profiles(indicators, z, other, blocks):
    """Every indicator's ``(features, blocks)`` of one z-scored run (``other``: the run a
    paired indicator reads it against)."""
    return {name: _profile(ind, z, other, blocks) for name, ind in indicators.items()}


class FeatureCache(BoundedStore):
    """Indicator profiles by ``(indicator, run)``, kept for reuse within one diagnosis.

    The same run is profiled many times: a run served again by the run cache, an effect
    whose parameters leave a run as it was (a clipping level above its range), the tie
    test's fresh evaluations of chains already scored.  Ikeda, step 0.25, noise + hum,
    6000 samples, one worker: 8424 runs profiled, 2055 of them repeats, 12.5 of the 85 s
    spent profiling.

    A profile is a deterministic function of the indicator's set-up and the run's values
    (and, for a paired indicator, of the run it is read against), so the key is the
    indicator's name, ``blocks`` and a digest of the values: valid for one set of
    indicators only (a :class:`~skdelay.gap._problem.GapProblem` and its reseeded twins,
    which share them; the halves of a split set up their own).  Stored arrays are
    read-only and copied out by :func:`profiles`.  At most ``MAX_BYTES``; the profiles are
    not pickled, and a copy unpickled in a joblib worker joins the worker's store of this
    set of indicators (:mod:`skdelay._memo`, ``shared``): a run the worker's run cache
    serves again to a later task is not profiled again either.
    """

    #: bytes kept (a profile is at most a few thousand bins)
    MAX_BYTES = 64 * 2**20

    def __init__(self, max_bytes=MAX_BYTES):
        super().__init__(max_bytes, shared=True)

    @staticmethod
    def digest(z):
        """A 128-bit digest of a run's values (shape and dtype included)."""
        z = np.ascontiguousarray(z)
        h = hashlib.blake2b(digest_size=16)
        h.update(f"{z.dtype.str}{z.shape}".encode())
        h.update(z.data)
        return h.digest()

    def run_profiles(self, indicators, z, other, blocks):
        """:func:`_run_profiles`, each indicator's profile from the cache when made before."""
        dz, do = self.digest(z), None
        out = {}
        for name, ind in indicators.items():
            paired = getattr(ind, "paired", False)
            if paired and do is None:
                do = self.digest(other)
            key = (name, bool(blocks), dz, do if paired else None)
            hit = self.get(key)
            if hit is None:
                hit = tuple(None if a is None else np.array(a)
                            for a in _profile(ind, z, other, blocks))
                for a in hit:
                    if a is not None:
                        a.setflags(write=False)
                self.put(key, hit, sum(a.nbytes for a in hit if a is not None))
            out[name] = hit
        return out


def make_indicators(real, sims, sample_dt, delay_samples, lines=()):
    """Set-up instances of every indicator, keyed by name (fast ones first).

    ``cross_prediction`` needs the delay (``delay_samples``) and is left out
    without it; ``spectral_line`` is set up only when ``lines`` were found.
    """
    out = {}
    for cls in FAST + FULL:
        if cls is CrossPrediction and not delay_samples:
            continue
        ind = cls()
        ind.setup(real, sims, sample_dt, delay_samples)
        out[ind.name] = ind
        if cls is Spectrum and lines:
            ind = SpectralLines(lines)
            ind.setup(real, sims, sample_dt, delay_samples)
            out[ind.name] = ind
    return out


# --------------------------------------------------------------------- statistics
def ensemble_stats(features, indicator, blocks=None):
    """Mean and variance per bin of an ensemble's features (rows = runs).

    The variance pools the between-run spread with the within-run spread of
    the features of ``blocks`` (shape (runs, n_blocks, bins), rescaled to the
    full length by 1 / n_blocks), then shrinks it towards the median of
    neighbouring bins (same label) and applies the indicator's floor.
    """
    f = np.asarray(features, dtype=float)
    k = f.shape[0]
    mean = f.mean(axis=0)
    num, dof = np.zeros_like(mean), 0
    if k > 1:
        num += (k - 1) * f.var(axis=0, ddof=1)
        dof += k - 1
    if blocks is not None and blocks.shape[1] > 1:
        nb = blocks.shape[1]
        num += k * (nb - 1) * blocks.var(axis=1, ddof=1).mean(axis=0) / nb
        dof += k * (nb - 1)
    var = num / max(dof, 1)
    pool = np.empty_like(var)
    labels = np.asarray(indicator.labels())
    if getattr(indicator, "exchangeable", False):
        # bins of one label share one spread (Segment): their mean variance, fully pooled
        for lab in dict.fromkeys(labels):
            idx = np.flatnonzero(labels == lab)
            var[idx] = var[idx].mean()
    for lab in dict.fromkeys(labels):
        idx = np.flatnonzero(labels == lab)
        v = var[idx]
        w = indicator.smooth
        if w and v.size > 2 * w + 1:
            padded = np.pad(v, w, mode="edge")
            windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * w + 1)
            pool[idx] = np.median(windows, axis=1)
        else:
            pool[idx] = np.median(v)
    nu0 = 4.0
    var = (dof * var + nu0 * pool) / (dof + nu0)
    var = np.maximum(var, indicator.var_floor)
    return mean, var, k


def zscores(values, mean, var, k, own_var=0.0):
    """z-scores of one run against an ensemble of ``k`` runs (capped at ``Z_CAP``);
    ``own_var``: the variance of the run's own estimate, where the indicator knows it."""
    z = (np.asarray(values) - mean) / np.sqrt(var * (1.0 + 1.0 / k) + own_var)
    # an unusable bin (non-finite feature) counts as maximally discrepant
    return np.clip(np.nan_to_num(z, nan=Z_CAP), -Z_CAP, Z_CAP)


def indicator_gap(z):
    """Excess of the mean squared z-score over its null value 1 (>= 0)."""
    return float(max(np.mean(np.square(z)) - 1.0, 0.0))

