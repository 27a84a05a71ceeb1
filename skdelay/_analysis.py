"""The paper's analysis of one series, end to end (what ``skdelay analyze`` runs).

:func:`analyze_series` chains the library's steps -- correlation revivals,
forecast-error delay scan, local linear models, Lyapunov spectrum, free runs
compared with the data and the minimal faithful ``m`` -- and returns an
:class:`AnalysisResult` that can print a summary, write its tables and a
self-contained HTML report (:mod:`skdelay._demo` runs it on the embedded laser
data).  Nothing here computes anything itself: every number comes from the
library's functions, each called once per analysis.
"""

from __future__ import annotations

import json
import math
import time
import warnings
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.signal import find_peaks

from ._checks import check_params, check_positive_int, check_series, resolve_sample_dt
from ._correlation import autocorrelation, mutual_information, revival_peak
from ._dips import DIP_ALPHA, locate_dips
from ._embedding import required_lags
from ._faithful import DEFAULT_RUN, FreeRunOptions, SpectrumOptions, minimal_embedding
from ._io import atomic_directory, write_json
from ._iterate import progress_bars
from ._model import ModelOptions
from ._report import (
    delay_sentence,
    ordinal,
    spectrum_caveat,
    step_sentence,
    write_analysis_report,
)
from ._sampling import MAX_STEP, sampling_step, smooth_at_step
from ._selection import NoDipWarning, forecast_error_curve, no_dip_message

__all__ = [
    "AnalysisOptions",
    "AnalysisResult",
    "analyze_series",
    "check_options",
    "default_tau_max",
    "strongest_revival",
]

#: Coarser steps tried, each twice the last, when the step chosen from the data
#: (:func:`~skdelay._sampling.sampling_step`) shows no significant dip in a record that is
#: smooth at its sampling step (:func:`~skdelay._sampling.smooth_at_step`; a rough record,
#: Ikeda at 5 samples per delay, has no dip that a coarser step could uncover).  The
#: second-difference rule behind that step misses when the structure function is not
#: quadratic over its first lags although the record is smooth: the Ikeda equation sampled
#: 500 times per delay (0.5 % noise, 4e4 samples, tests/test_dips_oversampled.py) got step
#: 1, where no m had a significant dip (z 0.6-1.4), nor at step 2 (z 2.5-3.1), while steps 5
#: and 10 gave z 7-11 with the dip within half a coarse sample of the delay.  Each rung
#: ``r`` tests its dips at ``DIP_ALPHA / 2 ** r``, so the whole ladder keeps a family-wise
#: false-dip rate below ``2 * DIP_ALPHA``; benchmarks/oversampled.py checks it on records
#: no test uses (smooth noise without a delay: no dip at any rung).
STEP_LADDER = 4
#: Window lengths of the paper's analysis (its m_d was at most 5).
DEFAULT_M = (2, 3, 4, 5)
#: Largest delay scanned by default (the paper's longest delay, 400 samples, fits).
MAX_TAU = 500
#: The default scan reaches this multiple of the strongest autocorrelation revival plus
#: SCAN_MARGIN samples: the revival lies beyond the delay by the loop's response time
#: (3-25 % in the paper's laser and in Mackey-Glass), and the dip needs a baseline on its
#: far side.
SCAN_REACH, SCAN_MARGIN = 1.25, 10
#: Shortest default scan, and the default without any revival.
MIN_TAU_MAX, NO_REVIVAL_TAU_MAX = 20, 100
#: A revival must stand out by this fraction of the curve's range (sampling ripples of
#: the autocorrelation of 1e4-sample records are below 1 %).
REVIVAL_PROMINENCE = 0.02
#: The series must hold this many samples per scanned lag (and at least MIN_SAMPLES):
#: with fewer, the k-NN neighbourhoods of the longest windows are no longer local.
SAMPLES_PER_LAG, MIN_SAMPLES = 20, 1000
#: Fewest forecasts per scan cell that give a usable error (standard error ~ 7 %).
MIN_QUERIES = 100
#: Defaults that grow with the record up to these sizes: forecasts per scan cell (the
#: cell's standard error ~ 1 %), steps of the data along which spectra are averaged, and
#: samples on which the models are fitted and validated.
N_QUERIES, N_SPECTRUM_STEPS, N_VALIDATION = 4000, 100_000, 200_000
#: The quick preset's sizes (about 10x less work than the defaults above).
QUICK_QUERIES, QUICK_RUN, QUICK_SPECTRUM_STEPS = 1500, 2000, 5000
#: Scans with more forecasts than this run on all cores (below it, starting the worker
#: processes costs more than it saves).
PARALLEL_FORECASTS = 300_000
#: Exponents of the reported model: N_EXPONENTS_BASE + tau / EXPONENTS_PER_DELAY (the
#: paper's spectra have about tau / 15 positive exponents; twice that closes the
#: Kaplan-Yorke sum).
N_EXPONENTS_BASE, DELAY_PER_EXPONENT = 20, 6
def quiet(_message):
    """Default progress callback: say nothing."""


def default_tau_max(series, *, cap=MAX_TAU):
    """Largest delay worth scanning: 1.25 x the strongest autocorrelation revival.

    The revival of the autocorrelation lies slightly *beyond* the feedback
    delay (the system's response time adds to it), so the scan reaches past
    the delay and far enough for a baseline on both sides of the dip.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
    cap : int, default=500

    Returns
    -------
    int
        Between 20 and ``cap`` (100 when there is no revival).

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._analysis import default_tau_max
    >>> t = np.arange(20000)
    >>> default_tau_max(np.sin(2 * np.pi * t / 80))  # revival at 80 -> 1.25 * 80 + 10
    110
    """
    s = check_series(series, name="series", min_length=50)
    max_lag = int(min(s.size // 4, math.ceil(cap / SCAN_REACH) + 5 * SCAN_MARGIN))
    best = strongest_revival(autocorrelation(s, max_lag))
    if best is None:
        return min(NO_REVIVAL_TAU_MAX, cap)
    return int(min(cap, max(MIN_TAU_MAX, math.ceil(SCAN_REACH * best) + SCAN_MARGIN)))


def strongest_revival(curve):
    """Lag of the highest local maximum after the first local minimum (None if none).

    For a delay system this is the revival near the delay (the paper's
    "marked peak ... slightly larger than the delay time"), whereas the
    *first* revival may be an internal oscillation period.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._analysis import strongest_revival
    >>> lag = np.arange(300)
    >>> curve = 0.3 * np.cos(2 * np.pi * lag / 25) + np.exp(-((lag - 160) / 4.0) ** 2)
    >>> abs(strongest_revival(curve) - 160) <= 1   # not the first revival at 25
    True
    """
    c = np.asarray(curve, dtype=float)
    rises = np.flatnonzero(np.diff(c) > 0)  # the first rise follows the first local minimum
    if rises.size == 0:
        return None
    start = int(rises[0])
    tail = c[start:]
    peaks, _ = find_peaks(tail, prominence=REVIVAL_PROMINENCE * np.ptp(tail))
    if peaks.size == 0:
        return None
    return int(peaks[np.argmax(tail[peaks])]) + start


def check_options(series, *, m=DEFAULT_M, tau_min=1, tau_max=None, sample_dt=1.0,
                  n_queries=None):
    """Check the options of :func:`analyze_series` before any heavy work.

    Returns the normalised options as a dict (``m`` tuple, ``tau_min``,
    ``tau_max``, ``sample_dt``, ``n_queries``); raises ``ValueError`` with a
    message that says what to change.
    """
    s = check_series(series, name="series", min_length=2)
    values = np.atleast_1d(np.asarray(m, dtype=object)).ravel()
    if not all(isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))
               for v in values):
        raise ValueError(f"m must be whole window lengths like (2, 3, 4, 5), got {m!r}.")
    ms = tuple(sorted({int(v) for v in values}))
    if not ms or ms[0] < 1:
        raise ValueError(f"m must hold window lengths >= 1, got {m!r}.")
    sample_dt = float(sample_dt)
    if not (math.isfinite(sample_dt) and sample_dt > 0):
        raise ValueError(f"the sampling interval must be positive, got {sample_dt}.")
    tau_min = int(tau_min)
    if tau_min < 1:
        raise ValueError(f"the smallest delay of the scan must be >= 1, got {tau_min}.")
    if tau_max is None:
        tau_max = default_tau_max(s) if s.size >= 10 * MIN_TAU_MAX else MIN_TAU_MAX
        tau_max = max(tau_max, tau_min + SCAN_MARGIN)
    tau_max = int(tau_max)
    if tau_max < tau_min + 4:
        raise ValueError(f"the delay scan {tau_min}..{tau_max} is too short to show a dip; "
                         "scan at least 5 delays (raise --tau-max or lower --tau-min).")
    need = max(MIN_SAMPLES, SAMPLES_PER_LAG * (tau_max + ms[-1]))
    if s.size < need:
        raise ValueError(
            f"the series has {s.size} samples but a scan up to tau={tau_max} with m={ms[-1]} "
            f"needs at least {need}; record a longer series or lower --tau-max / --m."
        )
    if n_queries is not None:
        n_queries = int(n_queries)
        if n_queries < MIN_QUERIES:
            raise ValueError(f"n_queries must be >= {MIN_QUERIES}, got {n_queries}.")
    return {"m": ms, "tau_min": tau_min, "tau_max": tau_max, "sample_dt": sample_dt,
                "n_queries": n_queries}


# ---------------------------------------------------------------------------------- result
@dataclass
class AnalysisResult:
    """Everything :func:`analyze_series` found about one series.

    Attributes
    ----------
    name : str
        Label of the series (file name).
    sample_dt : float
        Sampling interval of the analysed series (``step`` times that of the
        record); exponents are per its time unit.
    series : ndarray
        The analysed series (every ``step``-th sample of the record); the
        delays of ``delays`` and ``forecast_error`` are in its samples.
    step : int
        Sampling step applied to the record (1: none; see
        :func:`~skdelay._sampling.sampling_step`).
    steps_tried : tuple of int
        Every step whose scan was run: the chosen one and, when it showed no
        significant dip, the coarser ones of :data:`STEP_LADDER`.
    step_given : bool
        Whether the step was given (``step`` option) rather than chosen from the data.
    n_record : int or None
        Samples of the record (None: ``series.size * step``, which overcounts by
        up to ``step - 1``).
    model_selection : pandas.DataFrame or None
        The cross-validation tables behind the model settings (``select_model``):
        one row per window length ``m`` and setting, each ``m`` cross-validated
        on the series its model is fitted on (noise-reduced where it is).
    time_unit : str
        Name of the time unit (labels: exponents per this unit).
    revivals : dict
        ``acf`` and ``mi`` curves and the lags of their first revival.
    forecast_error : pandas.DataFrame
        sigma_m(tau) / std, index ``tau``, one column per ``m``.
    delays : pandas.DataFrame
        Per ``m`` (:func:`skdelay.locate_dips`): ``delay`` (dip centre,
        samples), ``half_width``, ``delay_error``, ``significant``, ...,
        ``tau_used`` (the integer delay of the model: the dip's best delay).
    m : int
        Window length of the reported model (the largest scanned).
    spectra : dict of int -> LyapunovSpectrum
        Lyapunov spectrum of the model of each ``m``.
    validation : pandas.DataFrame
        :func:`skdelay.dynamics.minimal_embedding` table (one row per ``m``).
    minimal_m : int or None
        The smallest faithful ``m`` (paper's ``m_d``).
    minimal_m_reason : str
        Why ``minimal_m`` is None (empty otherwise).
    runs : dict of int -> ndarray
        Free runs of each model (for histograms, spectra, space-time plots).
    timings : dict
        Seconds per stage: ``correlations``, ``delay_scan``, ``models`` (= ``free_runs``
        + ``spectra`` + ``fits_and_validation``), ``total``.
    """

    name: str
    sample_dt: float
    series: np.ndarray = field(repr=False)
    revivals: dict
    forecast_error: pd.DataFrame
    delays: pd.DataFrame
    m: int
    spectra: dict
    validation: pd.DataFrame
    minimal_m: int | None
    runs: dict = field(repr=False)
    minimal_m_reason: str = ""
    step: int = 1
    steps_tried: tuple = (1,)
    step_given: bool = False
    n_record: int | None = None
    model_selection: pd.DataFrame | None = None
    time_unit: str = "time unit"
    options: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)

    @property
    def delay(self):
        """Delay of the reported model in samples (the best delay of its ``m``'s dip)."""
        return int(self.delays.loc[self.m, "tau_used"])

    @property
    def spectrum(self):
        """Lyapunov spectrum of the reported model."""
        return self.spectra[self.m]

    def summary_row(self):
        """The paper's table row: N positive, lambda_max, D_KY, h_KS, D_KY/tau (+ delay)."""
        spec = self.spectrum
        d_ky = spec.kaplan_yorke_dimension
        tau_time = self.delay * self.sample_dt
        return {
            "delay": self.delay * self.step,
            "delay_error": float(self.delays.loc[self.m, "delay_error"]) * self.step,
            "delay_significant": bool(self.delays.loc[self.m, "significant"]),
            "delay_reason": (None if bool(self.delays.loc[self.m, "significant"])
                             else str(self.delays.loc[self.m, "reason"])),
            "delay_time": tau_time,
            "m": self.m,
            "N": int(spec.n_positive),
            "lambda_max": float(spec.exponents[0]),
            "D_KY": float(d_ky),
            "D_KY_closed": bool(spec.extra.get("ky_closed", d_ky < len(spec))),
            "h_KS": float(spec.ks_entropy),
            "D_KY/tau": float(d_ky / tau_time),
            "n_exponents": len(spec),
            "minimal_m": self.minimal_m,
            "minimal_m_reason": self.minimal_m_reason or None,
            "sampling_step": self.step,
            "steps_tried": list(self.steps_tried),
        }

    def to_dict(self):
        """JSON-ready dict of the results (no arrays of the size of the series)."""
        rev = self.revivals
        return {
            "name": self.name,
            "n_samples": int(self.series.size),  # analysed: every step-th of the record's
            "n_record": int(self.n_record or self.series.size * self.step),
            "sample_dt": self.sample_dt,
            "summary": self.summary_row(),
            "revival": {"autocorrelation_first": rev.get("acf_revival"),
                        "autocorrelation_strongest": rev.get("acf_strongest"),
                        "mutual_information_first": rev.get("mi_revival"),
                        "mutual_information_strongest": rev.get("mi_strongest")},
            "delays": records(self.delays),
            "validation": records(self.validation),
            "spectra": {int(m): {"exponents": s.exponents.tolist(), "spread": s.spread.tolist()}
                        for m, s in self.spectra.items()},
            "options": self.options,
            "timings_s": {k: round(v, 2) for k, v in self.timings.items()},
        }

    def summary(self):
        """A few lines for the terminal."""
        r = self.summary_row()
        lines = [
            (f"{self.name}: {self.n_record or self.series.size * self.step} samples, dt = "
             f"{self.sample_dt / self.step:g}"),
            *([step_sentence(self)] if step_sentence(self) else []),
            ("delay per m (samples): " if self.step == 1 else
             f"delay per m (in steps of {self.step} samples): ") + ", ".join(
                f"m={m}: {row.delay:.1f} +- {row.delay_error:.1f}"
                + ("" if row.significant else " (no significant dip)")
                for m, row in self.delays.iterrows()),
            *([] if self.delays["significant"].astype(bool).any()
              else [delay_sentence(self)]),
            (f"model m={r['m']}, tau={r['delay']}: {r['N']} positive exponent(s), "
             f"lambda_max = {r['lambda_max']:.4g} /{self.time_unit}, "
             f"D_KY {'=' if r['D_KY_closed'] else '>='} {r['D_KY']:.2f}, "
             f"h_KS = {r['h_KS']:.4g} /{self.time_unit}"
             # the dimension density needs a delay: without a dip tau is the grid minimum
             + (f", D_KY/tau = {r['D_KY/tau']:.4g} /{self.time_unit}"
                if self.delays["significant"].astype(bool).any() else "")
             + (f"; but {spectrum_caveat(self)}" if spectrum_caveat(self) else "")),
            "minimal faithful m: " + (str(self.minimal_m) if self.minimal_m is not None
                                      else f"none up to m={max(self.spectra)} "
                                           f"({self.minimal_m_reason})"),
        ]
        return "\n".join(lines)

    def write_files(self, directory):
        """Write results.json, the CSV tables, the model runs and report.html into ``directory``."""
        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        write_json(d / "results.json", self.to_dict(), default=str)
        self.forecast_error.to_csv(d / "forecast_error.csv")
        self.delays.to_csv(d / "delays.csv")
        self.validation.to_csv(d / "validation.csv")
        if self.model_selection is not None:
            self.model_selection.to_csv(d / "model_selection.csv", index=False)
        _spectra_frame(self.spectra).to_csv(d / "lyapunov.csv", index=False)
        pd.DataFrame({f"m={m}": pd.Series(r) for m, r in self.runs.items()}).to_csv(
            d / "model_runs.csv", index_label="step")
        write_analysis_report(self, d / "report.html")
        return d

    def save(self, directory, *, force=False):
        """Write everything into ``directory`` atomically.

        The files are written into a temporary directory next to it, which
        then replaces ``directory``; an existing non-empty one needs ``force``.
        """
        with atomic_directory(directory, force=force) as tmp:
            self.write_files(tmp)
        return directory


def records(df):
    """Rows of a table as JSON-ready dicts (the index as a column)."""
    out = df.reset_index()
    return json.loads(out.to_json(orient="records"))


def _spectra_frame(spectra):
    rows = []
    for m, spec in spectra.items():
        frame = spec.to_frame().reset_index()
        frame.insert(0, "m", m)
        rows.append(frame)
    return pd.concat(rows, ignore_index=True)


# -------------------------------------------------------------------------------- options
#: Exponents of the non-reported models (enough for lambda_1 and a closed Kaplan-Yorke
#: sum up to D_KY ~ 25; the reported model gets as many as its delay needs).
N_EXPONENTS_OTHER = 30


@dataclass(frozen=True)
class AnalysisOptions:
    """Settings of :func:`analyze_series` (None: chosen from the series' length).

    Attributes
    ----------
    m : tuple of int
        Window lengths; the model of the largest is reported.
    tau_min, tau_max : int
        Delay scan range in samples; ``tau_max=None``: 1.25 x the strongest
        autocorrelation revival (see :func:`default_tau_max`).
    sample_dt : float
        Sampling interval; exponents are per its time unit.  None: the step in
        seconds of a pandas Series' DatetimeIndex/TimedeltaIndex, else 1.
    n_queries : int
        Forecasts per scan cell (default ``min(n, 4000)``).
    model : ModelOptions
        Neighbourhood size, ridge and Theiler window of the models.
    flow : bool
        The data sample a continuous-time flow: pin the exponent nearest zero
        (see :func:`skdelay.dynamics.lyapunov_spectrum`).
    n_exponents : int
        Exponents of the reported model (default ``min(D, 20 + tau // 6)``,
        doubled once if the Kaplan-Yorke sum does not close).
    n_run : int
        Length of each compared free run (default 10000), at most ``n // 4``
        (the faithfulness bands need four disjoint data segments of that length).
    n_runs : int
        Free runs per model (:func:`~skdelay.dynamics.minimal_embedding`).
    n_spectrum_steps : int
        Steps of the data along which the spectra are computed (default
        ``min(n, 100000)``).
    n_validation : int
        Most recent samples on which the models are fitted and validated
        (default ``min(n, 200000)``).
    step : int
        Analyse every ``step``-th sample; None chooses it from the data
        (:func:`~skdelay._sampling.sampling_step`: 1 unless the record is so
        oversampled that its second difference drowns in measurement noise; when
        that step shows no significant dip, coarser ones are tried, see
        :data:`STEP_LADDER`).  Delay ranges (``tau_min``, ``tau_max``) are in the
        original samples.
    select_model : bool
        Choose the models' neighbourhood size and ridge by time-series
        cross-validation (:func:`~skdelay._model_selection.select_model_options`)
        for every ``m`` (default; off in the quick preset, and when
        :func:`analyze_series` is given ``n_neighbors`` or ``ridge`` without
        ``select_model``), on the series its model is fitted on (see
        :func:`~skdelay.dynamics.minimal_embedding`); the tables are kept in
        ``AnalysisResult.model_selection`` and ``options`` reports the largest
        ``m``'s settings (the model whose spectrum is reported).
    time_unit : str
        Name of the unit of ``sample_dt`` (e.g. ``"us"``), used in every label.
    refine : bool
        Add forecasts around each dip of the delay scan until its centre is known
        to 0.2 samples (see :func:`skdelay.forecast_error_curve`); off in the
        quick preset.
    """

    m: tuple = (2, 3, 4, 5)
    tau_min: int = 1
    tau_max: int | None = None
    sample_dt: float | None = None
    n_queries: int | None = None
    model: ModelOptions = field(default_factory=ModelOptions)
    flow: bool = False
    n_exponents: int | None = None
    n_run: int | None = None
    n_runs: int = 3
    n_spectrum_steps: int | None = None
    n_validation: int | None = None
    step: int | None = None
    select_model: bool = True
    time_unit: str = "time unit"
    refine: bool = True

    @classmethod
    def quick(cls, **changes):
        """Small settings for previews and tests (about 10x faster): a few per cent
        precision in sigma and the exponents instead of about one."""
        base = cls(n_queries=QUICK_QUERIES, n_run=QUICK_RUN, n_runs=2,
                   n_spectrum_steps=QUICK_SPECTRUM_STEPS, refine=False, select_model=False)
        return replace(base, **changes)

    def resolved(self, n):
        """The options with every None that depends on the series' length ``n`` filled in."""
        return replace(
            self,
            n_queries=min(n, N_QUERIES if self.n_queries is None else self.n_queries),
            n_run=min(n // 4, DEFAULT_RUN if self.n_run is None else self.n_run),
            n_spectrum_steps=min(n, N_SPECTRUM_STEPS if self.n_spectrum_steps is None
                                 else self.n_spectrum_steps),
            n_validation=min(n, N_VALIDATION if self.n_validation is None
                             else self.n_validation),
        )

    def to_dict(self):
        """JSON-ready dict (``model`` flattened to ``n_neighbors``, ``ridge``, ...)."""
        out = asdict(self)
        out["m"] = list(self.m)
        out.update(out.pop("model"))
        return out


#: Keywords of :func:`analyze_series` that set :class:`ModelOptions` fields.
_MODEL_KEYS = {"n_neighbors", "ridge", "theiler_window"}


def _options_from(options, quick, overrides):
    unknown = set(overrides) - {f.name for f in fields(AnalysisOptions)} - _MODEL_KEYS
    if unknown:
        raise TypeError(f"analyze_series got unknown option(s) {sorted(unknown)}; valid: "
                        f"{sorted({f.name for f in fields(AnalysisOptions)} | _MODEL_KEYS)}.")
    if options is None:
        options = AnalysisOptions.quick() if quick else AnalysisOptions()
    model = {k: overrides.pop(k) for k in list(overrides) if k in _MODEL_KEYS}
    # neighbours or a ridge set by the user are kept: they switch the cross-validated
    # choice off unless select_model is asked for as well
    if ("select_model" not in overrides
            and any(model.get(k) is not None for k in ("n_neighbors", "ridge"))):
        overrides["select_model"] = False
    model = {k: v for k, v in model.items() if v is not None or k == "n_neighbors"}
    if model:
        overrides["model"] = replace(options.model, **model)

    if "m" in overrides:
        overrides["m"] = tuple(np.atleast_1d(overrides["m"]).tolist())
    for name in ("flow", "select_model", "refine"):
        if name in overrides and not isinstance(overrides[name], (bool, np.bool_)):
            raise TypeError(f"{name} must be True or False, got {overrides[name]!r}.")
    return replace(options, **overrides)


# -------------------------------------------------------------------------------- pipeline
def analyze_series(series, options=None, *, quick=False, random_state=0, n_jobs=None,
                   verbose=0, progress=None, name="series", **overrides):
    """Run the two-window analysis of Bünner et al. on one scalar series.

    Steps: autocorrelation and mutual-information revivals; forecast-error
    scan sigma_m(tau) over ``tau_min..tau_max`` for every ``m``
    (:func:`skdelay.forecast_error_curve`) and its dips
    (:func:`skdelay.locate_dips`); then, once per ``m``, a local linear model
    at the dip's best delay, its free runs, the faithfulness table and the
    Lyapunov spectrum -- all from one call of
    :func:`skdelay.dynamics.minimal_embedding`, so nothing is fitted, run or
    computed twice.

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        The data, sampled every ``sample_dt``.
    options : AnalysisOptions, default=None
        All settings (default ``AnalysisOptions()``, or
        ``AnalysisOptions.quick()`` with ``quick=True``).
    quick : bool, default=False
        Start from the quick preset (tests, previews).
    random_state : int, default=0
    n_jobs : int, default=None
        joblib workers of the delay scan; None: all cores for big scans
        (more than 3e5 forecasts), one otherwise.
    verbose : int, default=0
        joblib verbosity of the delay scan (progress lines).
    progress : callable, default=None
        Called with a short message at the start of every stage.  With
        ``verbose > 0`` as well, the delay scan, every free run and every
        Lyapunov spectrum also show a tqdm progress bar with ETA on stderr.
    name : str, default="series"
    **overrides
        Any field of :class:`AnalysisOptions` (``m``, ``tau_min``, ``tau_max``,
        ``sample_dt``, ``n_queries``, ``flow``, ``n_exponents``, ``n_run``,
        ``n_runs``, ``n_spectrum_steps``, ``n_validation``) or of
        :class:`~skdelay._model.ModelOptions` (``n_neighbors``, ``ridge``,
        ``theiler_window``), replacing the value in ``options``.

    Returns
    -------
    AnalysisResult

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay import analyze_series
    >>> rng = np.random.default_rng(0)
    >>> s = np.full(6000, 0.5)
    >>> for t in range(11, 5999):          # a chaotic map with delay 12
    ...     d = s[t - 11]
    ...     s[t + 1] = 0.5 * s[t] + 2 * d * (1 - d) + 1e-3 * rng.normal()
    >>> res = analyze_series(s[500:], m=(2, 3), tau_min=6, tau_max=18, quick=True)
    >>> bool(abs(res.delays.loc[3, "delay"] - 12) < 1.5)
    True
    """
    say = progress or quiet
    opts = _options_from(options, quick, dict(overrides))
    opts = replace(opts, sample_dt=resolve_sample_dt(series, opts.sample_dt))
    raw = check_series(series, name="series")
    n_jobs = check_params(n_jobs=n_jobs)
    chosen = opts.step is None
    step = sampling_step(raw) if chosen else check_positive_int(opts.step, name="step")
    base, requested, bar = opts, n_jobs, progress is not None and verbose > 0
    timings, t0 = {}, time.perf_counter()

    def scan_at(step, alpha):
        """The record at ``step``: (series, options, n_jobs, curve, dips)."""
        s = raw[::step]
        checked = check_options(
            s, m=base.m, tau_min=max(1, base.tau_min // step),
            tau_max=None if base.tau_max is None else -(-base.tau_max // step),
            sample_dt=base.sample_dt * step, n_queries=base.n_queries)
        o = replace(base, **checked, step=step).resolved(s.size)
        taus = range(o.tau_min, o.tau_max + 1)
        jobs = requested
        if jobs is None:  # worker start-up only pays off for big scans
            jobs = -1 if len(o.m) * len(taus) * o.n_queries > PARALLEL_FORECASTS else 1
        if step > 1:
            say(f"oversampled record: analysing every {ordinal(step)} sample")
        say(f"delay scan: m = {', '.join(map(str, o.m))}, tau = {taus.start}..{taus.stop - 1} "
            f"({len(o.m) * len(taus)} cells, {o.n_queries} forecasts each)")
        # the bar replaces joblib's "Done k out of n" lines, which broke it into pieces
        curve = forecast_error_curve(s, m=o.m, tau=taus, n_queries=o.n_queries,
                                     refine=o.refine, progress=bar, random_state=random_state,
                                     n_jobs=jobs, verbose=0 if bar else verbose)
        return s, o, jobs, curve, locate_dips(curve, alpha=alpha)

    t1 = time.perf_counter()
    s, opts, n_jobs, curve, dips = scan_at(step, DIP_ALPHA)
    tried = [step]
    # no dip at the chosen step of a record that is smooth at its sampling step: the
    # delayed window's share of the next value may still drown in the noise, so coarser
    # steps are tried (see STEP_LADDER)
    if chosen and not dips["significant"].any() and smooth_at_step(raw):
        for rung in range(1, STEP_LADDER + 1):
            coarser = step * 2 ** rung
            if coarser > MAX_STEP:
                break
            try:
                found = scan_at(coarser, DIP_ALPHA / 2 ** rung)
            except ValueError:  # the coarser record is too short for the scan
                break
            tried.append(coarser)
            if found[4]["significant"].any():
                s, opts, n_jobs, curve, dips = found
                break
        if opts.step == step and len(tried) > 1:
            say(f"no significant dip at steps {', '.join(map(str, tried))}: the scan at "
                f"step {step} stands")
    step = opts.step
    dips["tau_used"] = dips["tau_best"]
    if not dips["significant"].astype(bool).any():
        steps = ", ".join(map(str, tried))
        warnings.warn(no_dip_message(dips, (
            f"the delay is unknown (sampling steps tried: {steps}); the models use each m's "
            "grid minimum of the forecast error")), NoDipWarning, stacklevel=2)
    timings["delay_scan"] = time.perf_counter() - t1
    ms, dt, n = opts.m, opts.sample_dt, s.size

    say("autocorrelation and mutual information")
    t_c = time.perf_counter()
    max_lag = int(min(n - 1, max(opts.tau_max + MIN_TAU_MAX, SCAN_REACH * opts.tau_max)))
    acf = autocorrelation(s, max_lag)
    mi = mutual_information(s, max_lag)
    revivals = {"acf": acf, "mi": mi, "acf_revival": _revival(revival_peak, acf),
                "mi_revival": _revival(revival_peak, mi),
                "acf_strongest": strongest_revival(acf), "mi_strongest": strongest_revival(mi)}
    timings["correlations"] = time.perf_counter() - t_c

    m_all = list(range(ms[0], ms[-1] + 1))
    tau_of = {mm: int(dips.loc[mm if mm in dips.index else ms[-1], "tau_used"]) for mm in m_all}
    say(f"models, free runs, spectra and faithfulness for m = {m_all[0]}..{m_all[-1]}")
    t2 = time.perf_counter()
    n_exp = {mm: min(required_lags(mm, tau_of[mm]), N_EXPONENTS_OTHER) for mm in m_all}
    n_exp[ms[-1]] = int(opts.n_exponents or min(required_lags(ms[-1], tau_of[ms[-1]]),
                                                N_EXPONENTS_BASE
                                                + tau_of[ms[-1]] // DELAY_PER_EXPONENT))
    s_val = s[n - opts.n_validation:]
    # tqdm bars (with ETA) for every free run and spectrum when the scan shows one too;
    # their wall times are added up in ``stages``
    stages = {}
    with progress_bars(enabled=progress is not None and verbose > 0, timings=stages):
        faithful = minimal_embedding(
            s_val, tau=tau_of, m_min=m_all[0], m_max=m_all[-1], model=opts.model,
            select_model=bool(opts.select_model), free_runs=FreeRunOptions(n_steps=opts.n_run, n_runs=opts.n_runs),
            spectrum=SpectrumOptions(
                n_exponents=n_exp, max_doublings={mm: int(mm == ms[-1]) for mm in m_all},
                n_steps=min(opts.n_spectrum_steps, s_val.size), flow=bool(opts.flow)),
            sample_dt=dt, random_state=random_state, n_jobs=n_jobs, progress=say)
    timings["models"] = time.perf_counter() - t2
    selection = None
    if faithful.selection:  # one table, a row per (m, setting)
        selection = pd.concat([sel.table.assign(m=mm) for mm, sel in faithful.selection.items()],
                              ignore_index=True)
        selection = selection[["m"] + [c for c in selection.columns if c != "m"]]
        opts = replace(opts, model=faithful.options[ms[-1]])  # the reported model's settings
    timings["free_runs"] = stages.get("free_runs", 0.0)
    timings["spectra"] = stages.get("spectra", 0.0)
    # the rest of the model stage: fits, noise level, histogram/spectrum/chi distances
    timings["fits_and_validation"] = (timings["models"] - timings["free_runs"]
                                      - timings["spectra"])
    timings["total"] = time.perf_counter() - t0
    return AnalysisResult(
        name=name, sample_dt=dt, series=s, revivals=revivals, forecast_error=curve,
        delays=dips, m=ms[-1], spectra=faithful.spectra, validation=faithful.table,
        minimal_m=faithful.m_d, minimal_m_reason=faithful.reason, step=step,
        steps_tried=tuple(tried), step_given=not chosen, n_record=raw.size,
        model_selection=selection,
        time_unit=opts.time_unit,
        runs={mm: r[0] for mm, r in faithful.runs.items() if r}, options=opts.to_dict(),
        timings=timings,
    )


def _revival(finder, curve):
    try:
        return int(finder(curve))
    except ValueError:
        return None


