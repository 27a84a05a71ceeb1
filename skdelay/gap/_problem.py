"""The gap problem: a real series, a simulator, its seed ensemble and the gap of a chain of effects.

:class:`GapProblem` simulates the clean ensemble once, sets up the indicators
on it, and evaluates the gap between the real series and "simulator + chain
of effects" (an ensemble with the same seeds, so that evaluations share their
random numbers and the objective is smooth in the effect parameters).
"""

from __future__ import annotations

import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
from joblib import Parallel, delayed, effective_n_jobs

from .._checks import check_random_state
from .._memo import BoundedStore
from ._effects import (
    HISTORY,
    SAMPLING_FACTOR,
    CandidateFailed,
    EffectFailed,
    SimulationFailed,
    call_hook,
)
from ._indicators import (
    FeatureCache,
    ensemble_stats,
    indicator_gap,
    make_indicators,
    profiles,
    zscores,
)
from ._lines import CALIBRATION_RUNS, line_scan, spectrum_view
from ._signature import zscore
from ._where import DIP_DEPTH_RATIO, DIP_Z, dip_window

__all__ = ["Evaluation", "GapProblem", "RunCache", "SimulationFailed", "run_simulator"]


def run_simulator(simulator, n, sample_dt, seed, overrides):
    """``simulator.simulate`` with every failure turned into :class:`SimulationFailed`;
    the override :data:`~skdelay.gap._effects.SAMPLING_FACTOR` scales ``sample_dt`` and
    :data:`~skdelay.gap._effects.HISTORY` prepends a history, cut off again."""
    overrides = dict(overrides)
    factor = float(overrides.pop(SAMPLING_FACTOR, 1.0))
    history = float(overrides.pop(HISTORY, 0.0))
    total = n + max(round(n * history), 0)
    what = (f"simulate({_kw(overrides)})" if factor == 1.0 else
            f"simulate(sample_dt={sample_dt * factor!r}{', ' if overrides else ''}"
            f"{_kw(overrides)})")
    try:
        x = simulator.simulate(total, sample_dt=sample_dt * factor, random_state=int(seed),
                               **overrides)
        # converting the output is still user territory (a list of strings, a ragged list)
        x = np.asarray(x, dtype=float)
    except Exception as exc:  # boundary of user code: fails this candidate only
        raise SimulationFailed(f"{what} failed: {type(exc).__name__}: {exc}") from exc
    x = check_run(x, total, what, SimulationFailed)
    return x[total - n: total] if total > n else x


class RunCache(BoundedStore):
    """Simulator runs by ``(length, seed, overrides)``, kept for reuse within one diagnosis.

    A diagnosis asks for the same run many times: a search's last comparisons rerun its
    best values on more seeds (the first seeds again), the halves of a cross-validation
    share the whole record's seeds and search the same grid points, and the second round
    refits the first round's effects.  CO2 laser with a hum, 4e4 samples, one worker: 752
    runs of which 104 repeated an earlier one, 15 % of the simulation time.

    A run is a deterministic function of its key (``simulate`` is seeded), so a hit gives
    the same numbers as a new run.  Entries are copies and every hit is a copy: an effect
    that changes its input in place cannot alter a stored run.  At most ``max_bytes`` are
    kept, least recently used first out.  The runs are not pickled (shipping them with
    every task would cost more than it saves); a copy unpickled in a joblib worker joins
    the worker's store of this diagnosis's runs (:mod:`skdelay._memo`, ``shared``), so the
    tasks a worker runs one after another share them as the tasks of one process do.  CO2
    laser with a hum, 4e4 samples, 2 workers: 553 runs against 499 with one worker, 28 of
    them repeating a run the same worker had made for an earlier task (a cross-validation
    fold's noise ladder and grid, the fresh ensembles of the two halves).
    """

    #: bytes kept (about 800 runs of 4e4 samples)
    MAX_BYTES = 256 * 2**20

    def __init__(self, max_bytes=MAX_BYTES):
        super().__init__(max_bytes, shared=True)

    @staticmethod
    def key(n, sample_dt, seed, overrides):
        """The run's key, or None when an override value cannot be hashed."""
        items = []
        for k, v in sorted(dict(overrides).items()):
            if isinstance(v, np.ndarray):
                v = (v.dtype.str, v.shape, v.tobytes())
            elif isinstance(v, list):
                v = tuple(v)
            items.append((k, v))
        key = (int(n), float(sample_dt), int(seed), tuple(items))
        try:
            hash(key)
        except TypeError:
            return None
        return key

    def run(self, simulator, n, sample_dt, seed, overrides):
        """:func:`run_simulator`'s result, from the cache when this run was made before."""
        key = self.key(n, sample_dt, seed, overrides)
        if key is not None:
            x = self.get(key)
            if x is not None:
                return x.copy()
        x = run_simulator(simulator, n, sample_dt, seed, overrides)
        if key is not None:
            self.put(key, x.copy(), x.nbytes)
        return x


def check_run(x, n, what, error=SimulationFailed):
    """``x`` if it is a finite, non-constant 1-D series of at least ``n`` samples, else raise.

    A 2-D output such as ``(n, 2)`` (two variables) is refused rather than
    flattened: flattening would interleave the variables into a nonsense series.
    """
    if x.ndim != 1:
        raise error(f"{what} returned an array of shape {x.shape}; a scalar series of shape "
                    f"(n,) is needed (select the observed variable).")
    if x.size < n:
        raise error(f"{what} returned {x.size} samples instead of {n}.")
    if not np.all(np.isfinite(x)):
        raise error(f"{what} returned non-finite values (NaN or inf: diverged?).")
    if np.ptp(x) == 0:
        raise error(f"{what} returned a constant series (dead dynamics).")
    return x


#: an ensemble's own spread counts up to this multiple of the clean variance
SPREAD_CAP = 25.0


def _spread(features, base_var):
    """Ensemble mean and the variance used for its z-scores (see ``GapProblem._compare``)."""
    f = np.asarray(features)
    own = f.var(axis=0, ddof=1) if f.shape[0] > 1 else np.zeros(f.shape[1])
    return f.mean(axis=0), np.maximum(base_var, np.minimum(own, SPREAD_CAP * base_var))


def _kw(overrides):
    return ", ".join(f"{k}={v!r}" for k, v in overrides.items())


@dataclass
class Evaluation:
    """Gap between the real series and one ensemble (total and per indicator)."""

    gap: float
    gaps: dict
    z: dict = field(repr=False)
    mean: dict = field(repr=False)
    std: dict = field(repr=False)
    runs: list = field(default=None, repr=False)


def dip_difference_se(real_se, sim_se, sim_centres):
    """Standard error of the record's dip centre minus the mean of the runs' centres.

    Under "no delay change" the record's centre and each run's are draws from one
    distribution of variance ``V`` (the chaos of the run and the scan's own noise), so the
    difference has variance ``V (1 + 1 / n)`` for ``n`` runs.  ``V`` is the larger of the
    runs' scatter and the median bootstrap variance of all ``n + 1`` centres; the record's
    own bootstrap variance replaces ``V`` for the record where it is larger (a record
    whose dip is poorly placed).

    The median runs over the record and the runs, not the runs alone: a run's bootstrap
    error is inflated when a few draws jump to a distant minimum of the curve, and two of
    four such runs set the median.  Ikeda (step 0.5, 6000 samples, delay 8.49 against 10
    samples, benchmark seed 17.7e6): four runs at 10.00, 10.00, 10.00, 10.00 with errors
    1.60, 0.99, 0.18, 0.03; the record at 8.44 +- 0.15.  The old sum of the record's error,
    the runs' median error and their scatter gave 0.60 and a shift of 2.6 errors (under
    ``DIP_Z`` = 3); this gives 0.20 and 7.8.  Mackey-Glass, Ikeda at step 0.5 and the
    electro-optic oscillator at 0.25 (6000 samples, seeds 8.1e6 + 31 j, 10 records each):
    without an effect the largest shift is 1.1 of these errors (0.9 of the old); with a
    moderate delay mismatch 3, 10 and 10 records shift by more than ``DIP_Z``, as with the
    old error (Mackey-Glass's dip moves little and not always the way the delay does).
    """
    sim_se = np.asarray(sim_se, dtype=float)
    centres = np.asarray(sim_centres, dtype=float)
    n = centres.size
    scatter2 = float(centres.var(ddof=1)) if n > 1 else 0.0
    typical2 = float(np.median(np.r_[real_se, sim_se])) ** 2
    v = max(scatter2, typical2)
    return float(np.sqrt(max(v, float(real_se) ** 2) + v / max(n, 1)))


class GapProblem:
    """Real series + simulator + clean ensemble + indicators; evaluates chains of effects.

    Parameters
    ----------
    real : ndarray (n,)
        Checked real series.
    simulator : object with ``simulate`` and ``params``
    sample_dt : float
    n_sims : int
        Ensemble size (seeds) for the reference and for the final evaluations.
    search_sims, search_length : int
        Ensemble size and run length of the cheaper evaluations that drive the
        parameter searches of simulation effects.
    random_state : int, RandomState or None
    n_jobs : int or None
        joblib workers for the clean ensemble.
    time_unit : str or None
        The simulator's time unit (for reports in Hz); None: unknown.
    runs : list of ndarray or None
        Clean runs to use instead of simulating them (the halves of a
        cross-validation split reuse the full problem's runs).
    scan_dips : bool, default=True
        Locate the forecast-error dips (skipped for a held-out half, which is
        only scored).
    lines : list of Line or None
        Spectral lines to use instead of searching them (the halves of a
        split use the whole record's: a hum of 3 cycles per record has 1.5
        per half; the line's frequency is a signature read off the whole
        record, its amplitude is what the halves fit and score).
    line_hints, line_start : list of Line, Line or None
        With ``lines``: the sub-threshold candidates and the most coherent bin
        of :func:`skdelay.gap._lines.line_scan` (starting points of a hum fit).
    """

    def __init__(self, real, simulator, *, sample_dt=1.0, n_sims=6, search_sims=2,
                 search_length=10_000, random_state=None, n_jobs=None, time_unit=None,
                 runs=None, scan_dips=True, lines=None, line_hints=None, line_start=None):
        self.real = real
        self.time_unit = time_unit
        self.simulator = simulator
        self.run_cache = RunCache()
        self.sample_dt = float(sample_dt)
        self.n_samples = n = len(real)
        rng = check_random_state(random_state)
        self.sim_seeds = rng.randint(0, 2**31 - 1, size=n_sims)
        self.effect_seed = int(rng.randint(0, 2**31 - 1))
        self.search_sims = min(search_sims, n_sims)
        self.search_length = int(min(n, search_length))
        tau = (getattr(simulator, "params", None) or {}).get("tau")
        self.delay_samples = float(tau) / self.sample_dt if tau is not None else None
        real_scan = self._start_real_scan(scan_dips, n_jobs)
        if runs is None:
            runs = Parallel(n_jobs=n_jobs)(
                delayed(run_simulator)(simulator, n, self.sample_dt, s, {})
                for s in self.sim_seeds)
        self.base = runs
        # lines anywhere from a few cycles per record to Nyquist (a 50 Hz hum at 1 MHz)
        # and sub-threshold candidates, where a hum fit may also start (_lines.line_scan)
        if lines is None:
            self.lines, self.line_hints, self.line_start = line_scan(
                real, runs, self.sample_dt, more_runs=self._line_runs(n_jobs),
                threads=effective_n_jobs(n_jobs))
        else:
            self.lines, self.line_hints = list(lines), list(line_hints or [])
            self.line_start = line_start
        self.spectrum_view = spectrum_view(real, runs[:2], self.sample_dt) if scan_dips else None
        self.indicators = make_indicators(real, runs, self.sample_dt, self.delay_samples,
                                          self.lines)
        # profiles of these indicators by run (shared with reseeded twins: same indicators)
        self.feature_cache = FeatureCache()
        self._set_real(real)
        self.base_features = profiles(self.indicators, runs, blocks=True, n_jobs=n_jobs)
        self.base_var = {k: ensemble_stats(f, self.indicators[k], b)[1]
                         for k, (f, b) in self.base_features.items()}
        self._scan_dips(scan_dips, n_jobs, real_scan)
        self.before = self._compare({k: f for k, (f, _) in self.base_features.items()}, runs)
        self.null_gaps = self._null_gaps()

    def _line_runs(self, n_jobs):
        """``more_runs`` of :func:`~skdelay.gap._lines.line_scan`: further clean runs that
        only calibrate the tests of narrow discrepancies (lines, excursions beyond the runs'
        range), seeded from the first run's seed (the problem's random stream, and with it
        every other draw, stays as it is).  Drawn once and kept: the range tests reuse the
        runs the line scan drew (:meth:`calibration_runs`)."""
        seeds = self._calibration_seeds()
        drawn = []

        def more(k):
            if k > len(drawn):
                drawn.extend(Parallel(n_jobs=n_jobs)(
                    delayed(run_simulator)(self.simulator, self.n_samples, self.sample_dt,
                                           s, {})
                    for s in seeds[len(drawn):k]))
            return drawn[:k]
        self._more_runs = more
        return more

    def calibration_runs(self):
        """The clean runs plus the calibration runs of :meth:`_line_runs`, up to
        :data:`~skdelay.gap._lines.CALIBRATION_RUNS` in all (the extra ones drawn on first
        use, the same the line scan drew)."""
        more = getattr(self, "_more_runs", None)
        if more is None:
            more = self._line_runs(None)
        return list(self.base) + list(more(max(CALIBRATION_RUNS - len(self.base), 0)))

    def _set_real(self, real):
        """The record's z-scored series and its indicator profiles (on the indicators' bins)."""
        self.real = real
        self.real_z = zscore(real)
        self.real_features, self.real_var = {}, {}
        for k, ind in self.indicators.items():
            if ind.paired:
                self.real_features[k] = ind.profile(self.real_z,
                                                    database=zscore(self.base[0]))[0]
            elif hasattr(ind, "profile_with_var"):  # the record's own estimation variance
                self.real_features[k], self.real_var[k] = ind.profile_with_var(self.real_z)
            else:
                self.real_features[k] = ind.profile(self.real_z)[0]

    #: simulator runs whose forecast-error curves give the model's dip and its spread.  Two
    #: runs could not estimate the spread: one run's bootstrap error of its centre is
    #: inflated when a few draws jump to a distant minimum of the whole curve (Ikeda, step
    #: 0.5, delay 10 samples, benchmark seed 15.3e6: 1.6 samples for a run whose dip sat
    #: at 10.0 like the other's, 0.07), and the mean of the two errors hid a dip shift of
    #: 1.6 samples (real 8.38, delay 4.29 against 5).  Four runs give a scatter of their
    #: centres and, with the record, a median of five errors (:func:`dip_difference_se`;
    #: about 1-2 s more per 6000-sample diagnosis).
    DIP_RUNS = 4
    #: set by the diagnosis when the dip is the record's only significant discrepancy
    #: (a delay fit then stays within the dip's standard error)
    dip_only = False
    #: set by the diagnosis: the indicators significantly off before any effect is added
    #: (:func:`~skdelay.gap._diagnose.off_indicators`); ``None`` where nothing judged them
    off_before = None

    def _start_real_scan(self, scan, n_jobs):
        """The record's own dip scan (:func:`~skdelay.gap._indicators.fe_scan`), started in
        a thread when the diagnosis may use more than one core, or None.

        It needs only the record, and its kernels release the GIL, so it runs beside this
        process's own work on the clean runs (the line scan, the indicators) instead of
        after it: about 2 s of a 4e4-sample diagnosis on 2 workers.  ``n_jobs=1`` keeps
        the diagnosis on one core.
        """
        if not (scan and self.delay_samples) or effective_n_jobs(n_jobs) < 2:
            return None
        from ._indicators import fe_scan

        pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="skdelay-dip-scan")
        future = pool.submit(fe_scan, self.real, self.delay_samples, with_se=True)
        pool.shutdown(wait=False)  # the thread ends with the scan
        return future

    def _scan_dips(self, scan=True, n_jobs=None, real_scan=None):
        """Forecast-error dips of the real data and of the clean runs (step 1 near the dips).

        Sets ``dip`` (the real data's :class:`~skdelay._dips.Dip`), ``sim_dips``,
        ``dip_real`` / ``dip_sim`` (centres, samples), ``dip_spread`` (the
        centre's uncertainty: bootstrap standard errors and the runs' scatter),
        ``dip_curves`` (taus, real, mean simulated) and ``second_dips`` (dips of
        the real data away from the main one that the simulator lacks).
        """
        from .._dips import MIN_RELATIVE_DEPTH, locate_dip
        from ._indicators import fe_scan, other_dips

        if not (self.delay_samples and scan):
            self.dip = None
            self.sim_dips, self.second_dips, self.dip_curves = [], [], None
            self.dip_real = self.dip_sim = self.dip_spread = None
            return
        from ._indicators import fe_curve

        taus, real_curve, real_se = (real_scan.result() if real_scan is not None else
                                     fe_scan(self.real, self.delay_samples, with_se=True))
        sims = Parallel(n_jobs=n_jobs)(delayed(fe_curve)(x, taus, with_se=True)
                                       for x in self.base[: self.DIP_RUNS])
        sim_curves = [c for c, _ in sims]
        # the delay's dip is sought near the model's delay (see _where.dip_window)
        d0 = self.delay_samples
        near = np.abs(taus - d0) <= dip_window(d0)
        if near[int(np.argmin(real_curve))]:
            near[:] = True  # the deepest dip is the delay's: the whole curve gives the baseline
        self.sim_dips = [locate_dip(taus[near], c[near]) for c in sim_curves]
        # the record's dip counts when it is as deep as the model's own allows (half of it,
        # DIP_DEPTH_RATIO), not only above the scan's fixed floor: Ikeda (step 0.5, delay 10
        # samples, real 13.0, benchmark seed 15.1e6) dipped 9.6 % at z 3.8 (threshold 3.4)
        # against the runs' 11-12 %, and the floor of 10 % left a 3-sample shift unseen
        depth = min(MIN_RELATIVE_DEPTH, DIP_DEPTH_RATIO * float(np.mean(
            [d.depth / d.baseline for d in self.sim_dips if d.baseline > 0] or [np.inf])))
        self.dip = locate_dip(taus[near], real_curve[near], min_relative_depth=depth)
        if self.dip.reason.startswith("the lowest error lies at the edge") and not near.all():
            # the record's dip lies beyond the window (a delay a third shorter: Ikeda at step
            # 0.25, delay 20 samples, real 13.3, window +-6): the window saw only its flank,
            # and the whole curve places it
            self.dip = locate_dip(taus, real_curve, min_relative_depth=depth)
        centres = np.array([d.centre for d in self.sim_dips])
        self.dip_real, self.dip_sim = self.dip.centre, float(centres.mean())
        self.dip_spread = dip_difference_se(self.dip.centre_se,
                                            [d.centre_se for d in self.sim_dips], centres)
        mean_sim = np.mean(sim_curves, axis=0)
        self.dip_curves = (taus, real_curve, mean_sim)
        # the standard error of real - mean of the runs: the record's own, the runs' own and
        # their scatter (the runs' curves differ by more than their queries say)
        runs_var = (np.mean([s**2 for _, s in sims], axis=0)
                    + (np.var(sim_curves, axis=0, ddof=1) if len(sims) > 1 else 0.0))
        self.dip_curve_se = np.sqrt(real_se**2 + runs_var / max(len(sims), 1))
        self.second_dips = other_dips(taus, real_curve, self.dip, reference=mean_sim,
                                      se=self.dip_curve_se, min_z=DIP_Z)

    # ----------------------------------------------------------------- runs
    def _effect_seed(self, j, name):
        return np.random.SeedSequence([self.effect_seed, int(j), zlib.crc32(name.encode())])

    def ensemble(self, chain, tier="full", n_search=None):
        """Runs of simulator + chain (list of ``(effect, params)``).

        ``tier="fast"`` simulates ``search_length`` samples with the first ``n_search``
        seeds (default ``search_sims``); ``"full"`` the whole record with every seed.
        """
        overrides = self._overrides(chain)
        if overrides:
            if tier == "fast":
                n, seeds = self.search_length, self.sim_seeds[: n_search or self.search_sims]
            else:
                n, seeds = self.n_samples, self.sim_seeds
            runs = [self.run_cache.run(self.simulator, n, self.sample_dt, s, overrides)
                    for s in seeds]
        else:
            runs = self.base
        return self._observed(runs, chain)

    def _overrides(self, chain):
        """The simulator parameters that the simulation effects of ``chain`` set."""
        overrides = {}
        for eff, params in chain:
            if eff.target == "simulation":
                overrides.update(call_hook(eff, "overrides", params, self.simulator))
        return overrides

    def _observed(self, runs, chain, first=0):
        """``runs`` as the observation effects of ``chain`` record them (in stage order;
        run ``j`` of the list draws with effect seed ``first + j``)."""
        obs_part = sorted(((e, p) for e, p in chain if e.target == "observation"),
                          key=lambda item: item[0].stage)
        out = []
        for j, x in enumerate(runs, start=first):
            n_run = x.size
            for eff, params in obs_part:
                y = call_hook(eff, "apply", x, params, sample_dt=self.sample_dt,
                              random_state=self._effect_seed(j, eff.name))
                x = check_run(np.asarray(y, dtype=float), 16,
                              f"effect {eff.name!r}.apply with {params}", EffectFailed)
            out.append(x[:n_run])  # never longer than the run (a slower time base stretches it)
        return out

    def calibration_ensemble(self, chain, k):
        """The first ``k`` calibration runs (:meth:`calibration_runs` beyond the clean
        ensemble; at most as many as there are) as the observation effects of ``chain``
        record them, each effect drawing with seeds that follow the ensemble's: with
        :meth:`ensemble` they are independent runs of simulator + ``chain``.  A chain with
        a simulation effect would need runs of its own: a ValueError."""
        if any(eff.target != "observation" for eff, _ in chain):
            raise ValueError("calibration_ensemble takes observation effects only; "
                             f"got {[eff.name for eff, _ in chain]}")
        k = max(min(int(k), CALIBRATION_RUNS - len(self.base)), 0)
        runs = self.calibration_runs()[len(self.base):len(self.base) + k]
        return self._observed(runs, chain, first=len(self.base))

    def chain_calibration(self, chain):
        """``CALIBRATION_RUNS`` runs of simulator + ``chain``: its :meth:`ensemble` and, beyond
        it, the calibration runs' seeds (:meth:`calibration_runs`, those of the clean
        calibration runs: the two differ by the chain alone), simulated with the chain's
        simulation effects and recorded through its observation effects.  What the tests of
        narrow discrepancies ask of a candidate where its six runs cannot decide
        (:func:`~skdelay.gap._diagnose._excursions_off`)."""
        k = max(CALIBRATION_RUNS - len(self.base), 0)
        overrides = self._overrides(chain)
        if not overrides:
            return self.ensemble(chain, "full") + self.calibration_ensemble(chain, k)
        seeds = self._calibration_seeds()[:k]
        runs = [self.run_cache.run(self.simulator, self.n_samples, self.sample_dt, s, overrides)
                for s in seeds]
        return self.ensemble(chain, "full") + self._observed(runs, chain, first=len(self.base))

    def _calibration_seeds(self):
        """Seeds of the calibration runs (:meth:`_line_runs`), from the first run's seed: the
        problem's random stream, and with it every other draw, stays as it is."""
        return np.random.RandomState(int(self.sim_seeds[0])).randint(
            0, 2**31 - 1, size=CALIBRATION_RUNS)

    def run_features(self, overrides, n, seed, names=None):
        """Fast-indicator features of one simulator run (``overrides``, length ``n``)."""
        names = names or [k for k, ind in self.indicators.items() if ind.tier == "fast"]
        run = self.run_cache.run(self.simulator, n, self.sample_dt, seed, overrides)
        feats = profiles({k: self.indicators[k] for k in names}, [run],
                         cache=self.feature_cache)
        return {k: f[0] for k, (f, _) in feats.items()}

    def evaluate(self, chain, tier="full", keep_runs=False, n_search=None):
        """:class:`Evaluation` of real vs simulator + chain (``tier='fast'``: cheap indicators,
        on ``n_search`` runs: see :meth:`ensemble`)."""
        runs = self.ensemble(chain, tier, n_search)
        names = [k for k, ind in self.indicators.items() if tier == "full" or ind.tier == "fast"]
        feats = profiles({k: self.indicators[k] for k in names}, runs,
                         cache=self.feature_cache)
        ev = self._compare({k: f for k, (f, _) in feats.items()}, runs)
        if not keep_runs:
            ev.runs = None
        return ev

    def _compare(self, feats, runs=None):
        """Real vs an ensemble, every bin in units of the clean sim-vs-sim spread.

        The variance of a bin is the clean spread, or the ensemble's own spread
        where the effect makes the runs scatter more (random spikes, noise), but
        at most ``SPREAD_CAP`` times the clean variance: an effect cannot hide a
        discrepancy by making its runs scatter without bound.
        """
        gaps, zs, means, stds = {}, {}, {}, {}
        for k, f in feats.items():
            real = self.real_features[k]
            if self.indicators[k].paired and runs is not None and runs is not self.base:
                real = self.indicators[k].profile(self.real_z, database=zscore(runs[0]))[0]
            mean, var = _spread(f, self.base_var[k])
            z = zscores(real, mean, var, f.shape[0], self.real_var.get(k, 0.0))
            gaps[k], zs[k], means[k], stds[k] = indicator_gap(z), z, mean, np.sqrt(var)
        return Evaluation(float(sum(gaps.values())), gaps, zs, means, stds, runs)

    def _null_gaps(self):
        """Gap of each clean run against the others (leave-one-out): the no-gap distribution."""
        k_runs = len(self.base)
        out = []
        self.null_by_indicator = {k: [] for k in self.base_features}
        for j in range(k_runs):
            total = 0.0
            for k, (f, blocks) in self.base_features.items():
                others = np.delete(f, j, axis=0)
                ob = None if blocks is None else np.delete(blocks, j, axis=0)
                mean, var = _spread(others, ensemble_stats(others, self.indicators[k], ob)[1])
                gap = indicator_gap(zscores(f[j], mean, var, others.shape[0]))
                self.null_by_indicator[k].append(gap)
                total += gap
            out.append(total)
        return np.array(out)

    def calibrated_z(self, names):
        """The record's z-scores of the indicators ``names`` against the calibration runs
        (:meth:`calibration_runs`: the clean runs and the line scan's further ones), with
        their spread estimated as for the clean runs.  ``{name: z}``; paired indicators
        (read against a partner run) are left out.  Why: :func:`skdelay.gap._diagnose.
        _far_bin_kept`.
        """
        runs = self.calibration_runs()
        chosen = {k: self.indicators[k] for k in names if not self.indicators[k].paired}
        out = {}
        for k, (f, blocks) in profiles(chosen, runs, blocks=True).items():
            mean, var = _spread(f, ensemble_stats(f, chosen[k], blocks)[1])
            out[k] = zscores(self.real_features[k], mean, var, f.shape[0],
                             self.real_var.get(k, 0.0))
        return out

    def lacking_dips(self, chain):
        """The second dips of the real data that simulator + ``chain`` still lack.

        A dip "the simulator lacks" may come from an effect (a strong hum makes
        one at a quarter of its period): two runs with the chain are scanned at
        the delays around each dip and the dip counts only if the real curve
        still lies ``SECOND_DIP_DEPTH`` below theirs there.
        """
        from ._indicators import SECOND_DIP_DEPTH, fe_curve

        if not self.second_dips:
            return []
        if not chain:
            return list(self.second_dips)
        taus, real_curve, _ = self.dip_curves
        try:
            runs = self.ensemble(chain, "full")[: self.DIP_RUNS]
        except CandidateFailed:
            return list(self.second_dips)
        out = []
        for dip in self.second_dips:
            k = int(np.argmin(np.abs(taus - dip.tau_min)))
            ref = np.mean([fe_curve(x, [taus[k]])[0] for x in runs])
            if (1.0 - real_curve[k] / ref >= SECOND_DIP_DEPTH
                    and ref - real_curve[k] >= DIP_Z * self.dip_curve_se[k]):
                out.append(dip)
        return out

    def split(self):
        """``(first, second)``: problems on the two halves of the record (same seeds and
        clean runs, cut likewise) for cross-validation: fit on one, score on the other."""
        h = self.n_samples // 2
        parts = []
        for lo in (0, h):
            p = GapProblem.__new__(GapProblem)
            p._init_part(self, lo, lo + h)
            parts.append(p)
        return tuple(parts)

    #: what the forecast-error dips of the whole record say (see :meth:`_scan_dips`)
    _DIP_FIELDS = ("dip", "sim_dips", "second_dips", "dip_curves", "dip_real", "dip_sim",
                   "dip_spread", "dip_curve_se")

    def _init_part(self, parent, lo, hi):
        # a half searches a simulation effect with every run of the ensemble, not the
        # whole record's two: its runs are half as long, and two of them left the search
        # objective too rough to fit on.  Ikeda (step 0.5, 6000 samples, mu drifting
        # 20 -> 25, benchmark seed 12.2e6): on the first half the fast gap at end values
        # +0, 2, 5, 8, 12, 16, 20 % was 3.6, 1.3, 1.9, 0.8, 1.7, 2.2, 4.9 with two runs
        # (fitted +2 %, held-out shrink 0.09) and 5.6, 3.1, 2.2, 1.5, 1.05, 1.6, 1.4 with
        # six (the true +12.5 % at the minimum; held-out shrink 0.87).  The runs share
        # their seeds across parameter values, so more of them smooth the landscape.
        GapProblem.__init__(
            self, parent.real[lo:hi], parent.simulator, sample_dt=parent.sample_dt,
            n_sims=len(parent.base), search_sims=len(parent.base),
            search_length=parent.search_length, random_state=0, time_unit=parent.time_unit,
            runs=[x[lo:hi] for x in parent.base], scan_dips=False, lines=parent.lines,
            line_hints=parent.line_hints, line_start=parent.line_start)
        # the parent's seeds: the halves' evaluations share the parent's random numbers
        self.sim_seeds, self.effect_seed = parent.sim_seeds, parent.effect_seed
        # and its runs: a half's search tries many of the whole record's values
        self.run_cache = parent.run_cache
        # where the part lies in the record, as fractions of its length: an effect tied to
        # the record's start (a drift from the simulator's value) fits a later part on the
        # ramp through that start (ParameterDrift.search)
        self.anchor = (lo / parent.n_samples, hi / parent.n_samples)
        # where the record's dip lies, and whether it can be placed against the model's, is
        # judged on the whole record, as its lines are: it sets where a delay or timebase fit
        # searches, and a half's own dip is twice as noisy.  Mackey-Glass (real delay 16.05
        # against 17, 6000 samples): the whole record's dip could not be placed (the search
        # spans 11..23 and finds 16.0, shrink 0.99), the first half's seemed to sit at 20.3,
        # so that half searched 19.2..22.2 and the held-out shrink read 0.10
        for name in self._DIP_FIELDS:
            setattr(self, name, getattr(parent, name, None))

    def reseeded(self, seed):
        """This problem with fresh simulator and effect seeds (and fresh clean runs).

        The indicators, their bins and the clean spread stay those of the
        original ensemble, so gaps on the copy are on the same scale; only the
        random numbers change.  :func:`~skdelay.gap._diagnose.tie_test` uses it
        to see how far a candidate's gap moves with the noise realisation.
        """
        import copy

        rng = np.random.default_rng(np.random.SeedSequence([self.effect_seed, int(seed)]))
        twin = copy.copy(self)
        twin.sim_seeds = rng.integers(0, 2**31 - 1, size=len(self.sim_seeds))
        twin.effect_seed = int(rng.integers(0, 2**31 - 1))
        # through the run cache: the two halves of a split draw the same fresh runs (they
        # share the record's seeds and have one length), one fold's reference after the other
        twin.base = [self.run_cache.run(self.simulator, self.n_samples, self.sample_dt, s, {})
                     for s in twin.sim_seeds]
        return twin

    def with_lines(self, lines, line_hints):
        """This problem with the spectral lines ``lines`` (and hints ``line_hints``) in place
        of its own: the same record, runs, seeds, dips and caches, with the indicators (the
        spectral line indicator measures each line), their clean spread, the gap before any
        effect and its no-gap distribution made anew for them.

        The diagnosis takes a line here that its scan found only against the runs of the
        best effect (:func:`~skdelay.gap._diagnose.masked_lines`): measured by no indicator,
        no fit could show what a hum there removes.
        """
        import copy

        twin = copy.copy(self)
        twin.lines, twin.line_hints = list(lines), list(line_hints)
        twin.indicators = make_indicators(self.real, self.base, self.sample_dt,
                                          self.delay_samples, twin.lines)
        twin.feature_cache = FeatureCache()
        twin._set_real(self.real)
        twin.base_features = profiles(twin.indicators, self.base, blocks=True)
        twin.base_var = {k: ensemble_stats(f, twin.indicators[k], b)[1]
                         for k, (f, b) in twin.base_features.items()}
        twin.before = twin._compare({k: f for k, (f, _) in twin.base_features.items()},
                                    self.base)
        twin.null_gaps = twin._null_gaps()
        return twin

    def world(self, chain, seed):
        """This problem reseeded (:meth:`reseeded`) with a record simulated as simulator +
        ``chain`` in place of the real one: a record of the world in which ``chain`` is the
        truth, on the original indicators' bins.  Its own seeds differ from the ensemble's.

        :func:`~skdelay.gap._diagnose.compare_chains` asks such records whether a difference
        between two explanations seen on the real record could arise were the runner-up true.
        What the real record's signatures say (its lines, its forecast-error dips) stays
        the real record's: it only sets where fits start and search.  Raises
        ``CandidateFailed`` when the chain yields no record of the real one's length.
        """
        import copy

        twin = self.reseeded(seed)
        rng = np.random.default_rng(np.random.SeedSequence([self.effect_seed, int(seed), 1]))
        source = copy.copy(twin)
        source.sim_seeds = rng.integers(0, 2**31 - 1, size=1)
        source.effect_seed = int(rng.integers(0, 2**31 - 1))
        source.base = [run_simulator(self.simulator, self.n_samples, self.sample_dt,
                                     source.sim_seeds[0], {})]
        record = source.ensemble(chain, "full")[0]
        if record.size != self.n_samples:
            raise CandidateFailed(f"the chain made a record of {record.size} samples, "
                                  f"not {self.n_samples}")
        twin._set_real(record)
        twin.before = twin.evaluate([], "full")
        return twin

    def line_contribution(self):
        """Gap removed by subtracting the strongest spectral line (its signature estimate)."""
        if not self.lines:
            return 0.0
        from ._effects import get_effect

        hum = get_effect("periodic_interference")
        try:
            after = self.evaluate([(hum, hum.initial(self))], "full").gap
        except CandidateFailed:
            return 0.0
        return float(max(self.before.gap - after, 0.0))

    def fast_gap_before(self):
        """Gap before any effect on the fast indicators only (the search objective's scale)."""
        return float(sum(g for k, g in self.before.gaps.items()
                         if self.indicators[k].tier == "fast"))
