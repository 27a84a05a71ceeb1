"""The paper's analysis of one series, end to end (what ``skdelay analyze`` runs).

:func:`analyze_series` chains the library's steps -- correlation revivals,
forecast-error delay scan, local linear models, Lyapunov spectrum, free runs
compared with the data and the minimal faithful ``m`` -- and returns an
:class:`AnalysisResult` that can print a summary, write its tables and a
self-contained HTML report.  :func:`run_demo` does it for the embedded laser
data at three delays and adds the paper's table and the rescaled-spectrum
collapse.  Nothing here computes anything itself: every number comes from the
public functions of :mod:`skdelay`.
"""

from __future__ import annotations

import json
import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ._checks import check_series

__all__ = [
    "PAPER_TABLE",
    "AnalysisResult",
    "DemoResult",
    "analyze_series",
    "check_options",
    "default_tau_max",
    "run_demo",
    "strongest_revival",
]

DEFAULT_M = (2, 3, 4, 5)
MAX_TAU = 500
#: Table of Bunner et al. (CO2 laser, exponents in 1/ms), for comparison in the demo.
PAPER_TABLE = pd.DataFrame(
    {"N": [1, 4, 11], "lambda_max": [2.5, 1.4, 0.55], "D_KY": [3.4, 10.2, 23.8],
     "h_KS": [2.5, 3.3, 3.0], "D_KY/tau": [68, 68, 59]},
    index=pd.Index([50, 150, 400], name="tau0"),
)


def _quiet(_message):
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
    from ._correlation import autocorrelation

    s = check_series(series, name="series", min_length=50)
    max_lag = int(min(s.size // 4, math.ceil(cap / 1.25) + 50))
    best = strongest_revival(autocorrelation(s, max_lag))
    if best is None:
        return min(100, cap)
    return int(min(cap, max(20, math.ceil(1.25 * best) + 10)))


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
    from scipy.signal import find_peaks

    c = np.asarray(curve, dtype=float)
    rises = np.flatnonzero(np.diff(c) > 0)  # the first rise follows the first local minimum
    if rises.size == 0:
        return None
    start = int(rises[0])
    tail = c[start:]
    peaks, _ = find_peaks(tail, prominence=0.02 * np.ptp(tail))
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
    try:
        ms = tuple(sorted({int(v) for v in np.atleast_1d(m)}))
    except (TypeError, ValueError):
        raise ValueError(f"m must be window lengths like (2, 3, 4, 5), got {m!r}.") from None
    if not ms or ms[0] < 1:
        raise ValueError(f"m must hold window lengths >= 1, got {m!r}.")
    sample_dt = float(sample_dt)
    if not (math.isfinite(sample_dt) and sample_dt > 0):
        raise ValueError(f"the sampling interval must be positive, got {sample_dt}.")
    tau_min = int(tau_min)
    if tau_min < 1:
        raise ValueError(f"the smallest delay of the scan must be >= 1, got {tau_min}.")
    if tau_max is None:
        tau_max = default_tau_max(s) if s.size >= 200 else 20
        tau_max = max(tau_max, tau_min + 10)
    tau_max = int(tau_max)
    if tau_max < tau_min + 4:
        raise ValueError(f"the delay scan {tau_min}..{tau_max} is too short to show a dip; "
                         "scan at least 5 delays (raise --tau-max or lower --tau-min).")
    need = max(1000, 20 * (tau_max + ms[-1]))
    if s.size < need:
        raise ValueError(
            f"the series has {s.size} samples but a scan up to tau={tau_max} with m={ms[-1]} "
            f"needs at least {need}; record a longer series or lower --tau-max / --m."
        )
    if n_queries is not None:
        n_queries = int(n_queries)
        if n_queries < 100:
            raise ValueError(f"n_queries must be >= 100, got {n_queries}.")
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
        Sampling interval (time unit of all exponents: per this unit).
    series : ndarray
        The analysed series.
    revivals : dict
        ``acf`` and ``mi`` curves and the lags of their first revival.
    forecast_error : pandas.DataFrame
        sigma_m(tau) / std, index ``tau``, one column per ``m``.
    delays : pandas.DataFrame
        Per ``m``: ``delay`` (dip centre, samples), ``half_width``,
        ``tau_min`` (grid minimum), ``min_error``, ``tau_used`` (integer delay
        of the model).
    m : int
        Window length of the reported model (the largest scanned).
    spectra : dict of int -> LyapunovSpectrum
        Lyapunov spectrum of the model of each ``m``.
    validation : pandas.DataFrame
        :func:`skdelay.dynamics.minimal_embedding` table (one row per ``m``).
    minimal_m : int or None
        The smallest faithful ``m`` (paper's ``m_d``).
    runs : dict of int -> ndarray
        Free runs of each model (for histograms, spectra, space-time plots).
    timings : dict
        Seconds per stage.
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
    options: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)

    @property
    def delay(self):
        """Delay of the reported model in samples (dip centre of its ``m``, rounded)."""
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
            "delay": self.delay,
            "delay_error": float(self.delays.loc[self.m, "half_width"]),
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
        }

    def to_dict(self):
        """JSON-ready dict of the results (no arrays of the size of the series)."""
        rev = self.revivals
        return {
            "name": self.name,
            "n_samples": int(self.series.size),
            "sample_dt": self.sample_dt,
            "summary": self.summary_row(),
            "revival": {"autocorrelation_first": rev.get("acf_revival"),
                        "autocorrelation_strongest": rev.get("acf_strongest"),
                        "mutual_information_first": rev.get("mi_revival"),
                        "mutual_information_strongest": rev.get("mi_strongest")},
            "delays": _records(self.delays),
            "validation": _records(self.validation),
            "spectra": {int(m): {"exponents": s.exponents.tolist(), "spread": s.spread.tolist()}
                        for m, s in self.spectra.items()},
            "options": self.options,
            "timings_s": {k: round(v, 2) for k, v in self.timings.items()},
        }

    def summary(self):
        """A few lines for the terminal."""
        r = self.summary_row()
        lines = [
            f"{self.name}: {self.series.size} samples, dt = {self.sample_dt:g}",
            "delay per m (samples): " + ", ".join(
                f"m={m}: {row.delay:.1f} +- {row.half_width:.1f}"
                for m, row in self.delays.iterrows()),
            (f"model m={r['m']}, tau={r['delay']}: {r['N']} positive exponent(s), "
            f"lambda_max = {r['lambda_max']:.4g} /time unit, "
            f"D_KY {'=' if r['D_KY_closed'] else '>='} {r['D_KY']:.2f}, "
            f"h_KS = {r['h_KS']:.4g} /time unit, D_KY/tau = {r['D_KY/tau']:.4g} /time unit"),
            "minimal faithful m: " + (str(self.minimal_m) if self.minimal_m is not None
                                      else f"none up to m={max(self.spectra)}"),
        ]
        return "\n".join(lines)

    def write_files(self, directory):
        """Write results.json, the CSV tables, the model runs and report.html into ``directory``."""
        from pathlib import Path

        from ._report import write_analysis_report

        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        (d / "results.json").write_text(json.dumps(self.to_dict(), indent=2, default=_json),
                                        encoding="utf-8")
        self.forecast_error.to_csv(d / "forecast_error.csv")
        self.delays.to_csv(d / "delays.csv")
        self.validation.to_csv(d / "validation.csv")
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
        from ._io import atomic_directory

        with atomic_directory(directory, force=force) as tmp:
            self.write_files(tmp)
        return directory


def _records(df):
    out = df.reset_index()
    return json.loads(out.to_json(orient="records"))


def _json(value):
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating,)):
        return float(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


def _spectra_frame(spectra):
    rows = []
    for m, spec in spectra.items():
        frame = spec.to_frame().reset_index()
        frame.insert(0, "m", m)
        rows.append(frame)
    return pd.concat(rows, ignore_index=True)


# -------------------------------------------------------------------------------- pipeline
def _fit_model(series, m, tau, n_neighbors, ridge):
    from sklearn.pipeline import make_pipeline

    from ._embedding import TwoWindowEmbedding, required_lags
    from ._local_linear import LocalLinearDelayMap
    from ._windows import lagged_windows

    X, y = lagged_windows(series, required_lags(m, tau))
    model = make_pipeline(TwoWindowEmbedding(m=m, tau=tau),
                          LocalLinearDelayMap(n_neighbors=n_neighbors, ridge=ridge,
                                              theiler_window=2))
    return model.fit(X, y)


def _covering_spectrum(model, series, *, n_exponents, sample_dt, n_steps, dim,
                       max_doublings=1, flow=False):
    """Lyapunov spectrum with enough exponents to close the Kaplan-Yorke sum (if affordable).

    Starts with ``n_exponents`` and doubles (at most ``max_doublings`` times)
    while every partial sum is still positive; ``extra["ky_closed"]`` says
    whether the Kaplan-Yorke dimension is a value or only a lower bound.
    """
    from .dynamics import lyapunov_spectrum

    n_exp = min(dim, n_exponents)
    for attempt in range(max_doublings + 1):
        spec = lyapunov_spectrum(model, series, n_exponents=n_exp, sample_dt=sample_dt,
                                 n_steps=n_steps, flow=flow)
        closed = spec.kaplan_yorke_dimension < n_exp - 1e-9 or n_exp >= dim
        if closed or attempt == max_doublings:
            spec.extra["ky_closed"] = bool(closed)
            return spec
        n_exp = min(dim, 2 * n_exp)
    return spec  # pragma: no cover - the loop always returns


def analyze_series(series, *, m=DEFAULT_M, tau_min=1, tau_max=None, sample_dt=1.0,
                   n_queries=None, n_neighbors=None, ridge=1e-3, flow=False,
                   n_exponents=None, n_run=None,
                   n_spectrum_steps=None, n_validation=None, quick=False, random_state=0,
                   n_jobs=None, verbose=0, progress=None, name="series"):
    """Run the two-window analysis of Bünner et al. on one scalar series.

    Steps: autocorrelation and mutual-information revivals; forecast-error
    scan sigma_m(tau) over ``tau_min..tau_max`` for every ``m``
    (:func:`skdelay.forecast_error_curve`) and its dips
    (:func:`skdelay._selection.locate_dips`); a local linear model per ``m``
    at its delay; Lyapunov spectra (:func:`skdelay.dynamics.lyapunov_spectrum`)
    with enough exponents for the Kaplan-Yorke dimension; free runs
    (:func:`skdelay.dynamics.iterate`) and the faithfulness table with the
    minimal ``m`` (:func:`skdelay.dynamics.minimal_embedding`).

    Parameters
    ----------
    series : array-like of shape (n_samples,)
        The data, sampled every ``sample_dt``.
    m : sequence of int, default=(2, 3, 4, 5)
        Window lengths.  The model of the largest one is reported.
    tau_min, tau_max : int
        Delay scan range in samples; ``tau_max=None``: 1.25 x the strongest
        autocorrelation revival (see :func:`default_tau_max`).
    sample_dt : float, default=1.0
        Sampling interval; exponents are per its time unit.
    n_queries : int, default=None
        Forecasts per scan cell (default ``min(n, 4000)``; 1500 with ``quick``).
    n_neighbors : int, default=None
        Neighbourhood size of the models (default ``4 (2 m + 1)``).
    ridge : float, default=1e-3
        Relative ridge of the local linear fits (see
        :class:`~skdelay.LocalLinearDelayMap`); larger values damp the spurious
        expansion that measurement noise gives poorly spread neighbourhoods.
    flow : bool, default=False
        The data sample a continuous-time flow: pin the exponent nearest zero
        to zero in the spectra (see :func:`skdelay.dynamics.lyapunov_spectrum`).
    n_exponents : int, default=None
        Number of exponents of the reported model (default ``min(D, 20 + tau // 6)``),
        doubled once if the Kaplan-Yorke sum does not close (otherwise D_KY and
        h_KS are lower bounds, flagged by ``D_KY_closed``); 30 for the others.
    n_run : int, default=None
        Length of each free run (default ``min(n, 30000)``; 2000 with ``quick``).
    n_spectrum_steps : int, default=None
        Steps of the data used for each spectrum (default ``min(n, 100000)``; 5000
        with ``quick``).
    n_validation : int, default=None
        Samples (the most recent ones) on which the faithfulness table is
        computed (default ``min(n, 200000)``; the paper, too, uses shorter
        segments for the smaller models).
    quick : bool, default=False
        Smaller defaults everywhere (tests, previews).
    random_state : int, default=0
    n_jobs : int, default=None
        joblib workers of the delay scan; None: all cores for big scans
        (more than 3e5 forecasts), one otherwise.
    verbose : int, default=0
        joblib verbosity of the delay scan (progress lines).
    progress : callable, default=None
        Called with a short message at the start of every stage.
    name : str, default="series"

    Returns
    -------
    AnalysisResult

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay._analysis import analyze_series
    >>> rng = np.random.default_rng(0)
    >>> s = np.full(6000, 0.5)
    >>> for t in range(11, 5999):          # a chaotic map with delay 12
    ...     d = s[t - 11]
    ...     s[t + 1] = 0.5 * s[t] + 2 * d * (1 - d) + 1e-3 * rng.normal()
    >>> res = analyze_series(s[500:], m=(2, 3), tau_min=6, tau_max=18, quick=True)
    >>> bool(abs(res.delays.loc[3, "delay"] - 12) < 1.5)
    True
    """
    from ._correlation import autocorrelation, mutual_information, revival_peak
    from ._embedding import required_lags
    from ._selection import forecast_error_curve, locate_dips
    from .dynamics import iterate, minimal_embedding

    say = progress or _quiet
    s = check_series(series, name="series")
    opts = check_options(s, m=m, tau_min=tau_min, tau_max=tau_max, sample_dt=sample_dt,
                         n_queries=n_queries)
    ms, dt = opts["m"], opts["sample_dt"]
    taus = range(opts["tau_min"], opts["tau_max"] + 1)
    n = s.size
    if opts["n_queries"] is None:
        opts["n_queries"] = min(n, 1500 if quick else 4000)
    n_run = int(n_run or min(n, 2000 if quick else 30_000))
    n_spec = int(n_spectrum_steps or min(n, 5000 if quick else 100_000))
    n_few = 12 if quick else 30  # exponents of the non-reported models
    n_val = int(n_validation or min(n, 200_000))
    if n_jobs is None:  # worker start-up only pays off for big scans
        n_jobs = -1 if len(ms) * len(taus) * opts["n_queries"] > 300_000 else 1
    timings, t0 = {}, time.perf_counter()

    say("autocorrelation and mutual information")
    max_lag = int(min(n - 1, max(opts["tau_max"] + 20, 1.25 * opts["tau_max"])))
    acf = autocorrelation(s, max_lag)
    mi = mutual_information(s, max_lag)
    revivals = {"acf": acf, "mi": mi, "acf_revival": _revival(revival_peak, acf),
                "mi_revival": _revival(revival_peak, mi),
                "acf_strongest": strongest_revival(acf), "mi_strongest": strongest_revival(mi)}
    timings["correlations"] = time.perf_counter() - t0

    say(f"delay scan: m = {', '.join(map(str, ms))}, tau = {taus.start}..{taus.stop - 1} "
        f"({len(ms) * len(taus)} cells, {opts['n_queries']} forecasts each)")
    t1 = time.perf_counter()
    curve = forecast_error_curve(s, m=ms, tau=taus, n_queries=opts["n_queries"],
                                 random_state=random_state, n_jobs=n_jobs, verbose=verbose)
    dips = locate_dips(curve)
    dips["tau_used"] = [max(1, round(v)) for v in dips["delay"]]
    timings["delay_scan"] = time.perf_counter() - t1

    m_all = list(range(ms[0], ms[-1] + 1))
    tau_of = {mm: int(dips.loc[mm, "tau_used"]) if mm in dips.index
              else int(dips.loc[ms[-1], "tau_used"]) for mm in m_all}
    say(f"models, free runs and faithfulness for m = {m_all[0]}..{m_all[-1]}")
    t2 = time.perf_counter()
    n_exp0 = {mm: int(n_exponents or min(required_lags(mm, tau_of[mm]), 20 + tau_of[mm] // 6))
              for mm in m_all}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table, m_d = minimal_embedding(
            s[n - n_val:], tau=tau_of, m_min=m_all[0], m_max=m_all[-1], n_steps=n_run,
            n_exponents=min(n_few, max(n_exp0.values())), sample_dt=dt, random_state=random_state,
            n_jobs=n_jobs, n_neighbors=n_neighbors, ridge=ridge,
        )
    timings["validation"] = time.perf_counter() - t2

    say("Lyapunov spectra and model runs for the report")
    t3 = time.perf_counter()
    spectra, runs = {}, {}
    rng = np.random.default_rng(random_state)
    for mm in ms:
        k = n_neighbors or 4 * (2 * mm + 1)
        model = _fit_model(s, mm, tau_of[mm], k, ridge)
        dim = required_lags(mm, tau_of[mm])
        if mm == ms[-1]:  # the reported model: close the Kaplan-Yorke sum if affordable
            spectra[mm] = _covering_spectrum(model, s, n_exponents=n_exp0[mm], sample_dt=dt,
                                             n_steps=min(n_spec, n - dim - 1), dim=dim,
                                             flow=flow)
        else:             # the others: the leading exponents, for the convergence plot
            spectra[mm] = _covering_spectrum(model, s, n_exponents=min(n_few, n_exp0[mm]),
                                             sample_dt=dt, n_steps=min(n_spec // 2, n - dim - 1),
                                             dim=dim, max_doublings=0, flow=flow)
        start = int(rng.integers(0, n - dim))
        skip = max(2 * tau_of[mm], 500)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            run = iterate(model, s[start:start + dim], n_run + skip, on_escape="ignore")
        runs[mm] = np.asarray(run[skip:], dtype=float)
    timings["spectra"] = time.perf_counter() - t3
    timings["total"] = time.perf_counter() - t0
    opts["n_run"], opts["n_spectrum_steps"], opts["n_validation"] = n_run, n_spec, n_val
    opts["n_neighbors"], opts["ridge"], opts["flow"] = n_neighbors, float(ridge), bool(flow)
    return AnalysisResult(
        name=name, sample_dt=dt, series=s, revivals=revivals, forecast_error=curve,
        delays=dips, m=ms[-1], spectra=spectra, validation=table, minimal_m=m_d, runs=runs,
        options={k: (list(v) if isinstance(v, tuple) else v) for k, v in opts.items()},
        timings=timings,
    )


def _revival(finder, curve):
    try:
        return int(finder(curve))
    except ValueError:
        return None


# ------------------------------------------------------------------------------------ demo
@dataclass
class DemoResult:
    """The demo's three analyses, the paper's table and the collapse data."""

    results: dict
    table: pd.DataFrame
    exact: dict
    unit: str
    scale: float
    timings: dict = field(default_factory=dict)
    exact_note: str = ""

    def summary(self):
        """The table as text."""
        with pd.option_context("display.float_format", "{:.3g}".format,
                               "display.width", 160):
            return (f"Lyapunov analysis of the laser-like data (exponents in {self.unit}):\n"
                    f"{self.table.to_string()}\n\nPaper (CO2 laser, 1/ms):\n"
                    f"{PAPER_TABLE.to_string()}")

    def save(self, directory, *, force=False):
        """Write one sub-directory per delay, table.csv, results.json and report.html."""
        from ._io import atomic_directory
        from ._report import write_demo_report

        with atomic_directory(directory, force=force) as tmp:
            for delay, res in self.results.items():
                res.write_files(tmp / f"delay_{delay}")
            self.table.to_csv(tmp / "table.csv")
            (tmp / "results.json").write_text(json.dumps({
                "unit": self.unit, "table": _records(self.table),
                "paper": _records(PAPER_TABLE),
                "timings_s": {k: round(v, 1) for k, v in self.timings.items()},
            }, indent=2, default=_json), encoding="utf-8")
            write_demo_report(self, tmp / "report.html")
        return directory


def _time_scale(system):
    unit = str(getattr(system, "time_unit", "")).lower()
    if unit.startswith("microsecond") or unit in {"us", "µs"}:
        return "1/ms", 1000.0
    return f"1/{unit or 'time unit'}", 1.0


def _fmt(value):
    return f"{value:.3g}"


def _exact_columns(spec, tau_time, scale):
    """The table's exact columns; bounds (">= ") where the spectrum is too short."""
    k = len(spec)
    n_pos = int(np.sum(spec.exponents > 0))
    closed = n_pos < k and spec.kaplan_yorke_dimension < k
    bound = "" if closed else ">= "
    return {"exact N": str(n_pos) if n_pos < k else f">= {k}",
            "exact lambda_max": _fmt(spec.exponents[0] * scale),
            "exact D_KY": bound + _fmt(spec.kaplan_yorke_dimension),
            "exact h_KS": ("" if n_pos < k else ">= ") + _fmt(spec.ks_entropy * scale),
            "exact D_KY/tau": bound + _fmt(spec.kaplan_yorke_dimension / tau_time * scale)}


#: the demo's model settings, those of ``benchmarks/paper_table.py``: on this noisy data
#: (0.5 % measurement noise) wide, damped neighbourhoods keep noise from inflating the
#: exponents (lambda_max and D_KY within 22 % and 7 % of the exact values at all three delays)
DEMO_MODEL = {"n_neighbors": 100, "ridge": 3e-2}


def run_demo(*, delays=(50, 150, 400), n_samples=None, exact=True, n_exact=20,
             exact_duration=1000.0, random_state=0, n_jobs=None, verbose=0, progress=None):
    """The paper's analysis on the embedded laser-like data at several delays.

    For each delay: :func:`skdelay.datasets.load_laser`, a delay scan on a grid
    around the physical delay (``delay +- 15`` samples) and the rest of
    :func:`analyze_series` with the models of :data:`DEMO_MODEL` (``flow=True``);
    then the paper's table (N positive exponents,
    lambda_max, D_KY, h_KS, D_KY/tau) with the simulator's exact values
    beside, and the rescaled spectra for the collapse figure.

    Parameters
    ----------
    delays : sequence of int, default=(50, 150, 400)
    n_samples : int, default=None
        Samples per data set (default 100000).
    exact : bool, default=True
        Also compute the simulators' exact spectra (the cheap part: ``n_exact``
        exponents averaged over ``exact_duration`` time units; quantities that
        need more exponents are shown as lower bounds).
    n_exact : int, default=20
    exact_duration : float, default=1000.0
    random_state, n_jobs, verbose, progress
        As in :func:`analyze_series`.

    Returns
    -------
    DemoResult
    """
    from .datasets import load_laser

    say = progress or _quiet
    n_samples = int(n_samples or 100_000)
    results, exact_spectra, rows, timings = {}, {}, {}, {}
    unit, scale = "1/time unit", 1.0
    for delay in delays:
        t0 = time.perf_counter()
        say(f"tau0 = {delay}: loading the laser data ({n_samples} samples)")
        data = load_laser(delay=delay, n_samples=n_samples)
        unit, scale = _time_scale(data.system)
        d = int(data.delay_samples)
        res = analyze_series(
            data.series, m=DEFAULT_M, tau_min=max(1, d - 15), tau_max=d + 15,
            sample_dt=float(data.sample_dt), n_queries=min(n_samples, 2000),
            n_run=min(n_samples, 10_000), n_spectrum_steps=min(n_samples, 40_000),
            n_neighbors=DEMO_MODEL["n_neighbors"], ridge=DEMO_MODEL["ridge"], flow=True,
            random_state=random_state, n_jobs=n_jobs, verbose=verbose,
            progress=lambda msg, _d=delay: say(f"tau0 = {_d}: {msg}"),
            name=f"laser, tau0 = {delay}",
        )
        results[delay] = res
        row = res.summary_row()
        bound = "" if row["D_KY_closed"] else ">= "
        out = {"delay": f"{row['delay']} +- {row['delay_error']:.1f}",
               "N": row["N"], "lambda_max": _fmt(row["lambda_max"] * scale),
               "D_KY": bound + _fmt(row["D_KY"]), "h_KS": _fmt(row["h_KS"] * scale),
               "D_KY/tau": bound + _fmt(row["D_KY/tau"] * scale),
               "m_d": "none" if row["minimal_m"] is None else row["minimal_m"]}
        if exact:
            say(f"tau0 = {delay}: exact spectrum of the simulator ({n_exact} exponents)")
            spec = data.system.lyapunov_spectrum(n_exact, duration=exact_duration,
                                                 random_state=random_state)
            exact_spectra[delay] = spec
            out.update(_exact_columns(spec, float(data.delay), scale))
        rows[delay] = out
        timings[f"tau0={delay}"] = time.perf_counter() - t0
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "tau0"
    note = (f"the simulator's own spectrum (tangent dynamics of the delay equation), "
            f"{n_exact} exponents averaged over {exact_duration:g} time units"
            if exact else "not computed")
    return DemoResult(results=results, table=table, exact=exact_spectra, unit=unit,
                      scale=scale, timings=timings, exact_note=note)
