"""Fit one effect's parameters so that simulator + effect matches the real data.

Start from the effect's signature guess, then a small bounded search on the
total gap of the fast indicators: a coarse grid plus a bounded Brent
refinement in 1-D, Nelder-Mead (bounded) in 2-D.  Simulation effects get
fewer, cheaper evaluations (shorter runs, fewer seeds).  The fitted candidate
is then evaluated once on every indicator.
"""

from __future__ import annotations

import numbers
import time
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from ._effects import CandidateFailed, Effect, NotApplicable, call_hook


@dataclass(frozen=True)
class FitResult:
    """Outcome of fitting one candidate effect.

    ``status`` is ``"ok"`` or ``"failed"``; ``reason`` says why a candidate
    failed (empty when ok).  ``gap_after`` is the gap of simulator + chain +
    effect on every indicator (NaN when failed), ``gap_fast`` the search's
    best gap on the fast indicators, ``gaps`` the gap per indicator.
    ``params`` are the fitted values (the starting guess when the fit failed
    after it, else empty).  ``applicable`` is False when the effect cannot act
    on these data at all (:class:`NotApplicable`: no spike in the record for
    outliers, no delay parameter in the simulator).  ``spread`` is True for the
    second of a pair fitted in turn whose first effect started from one of its
    :meth:`~skdelay.gap.Effect.starts` rather than from its own fit.
    """

    effect: str
    target: str
    params: dict
    gap_after: float = np.nan
    status: str = "ok"
    reason: str = ""
    gap_fast: float = np.nan
    gaps: dict = field(default_factory=dict)
    n_evals: int = 0
    seconds: float = 0.0
    applicable: bool = True
    spread: bool = False
    evaluation: object = field(default=None, repr=False, compare=False)

    @property
    def ok(self):
        """True when the candidate was fitted and evaluated."""
        return self.status == "ok"


def initial_params(effect, problem):
    """The effect's starting parameters (its :meth:`~Effect.initial` hook)."""
    return dict(call_hook(effect, "initial", problem))


def _chain_start(effect, problem, base_chain, guess, objective):
    """The better start of ``guess`` (read against the clean runs) and the effect's
    :meth:`~Effect.guess` read against the runs of simulator + ``base_chain``, the model
    the effect is added to; by ``objective``.  Only for effects whose start is that
    guess (the default :meth:`~Effect.initial`).

    The clean runs miss what the chain does to them: Ikeda (step 0.5, 6000 samples,
    benchmark seed 17.2e6), noise of 0.56 std after a low-pass at 0.068: against the
    clean runs the record's high-frequency floor reads no noise at all (the filter took
    more power than the noise adds), against the low-pass fitted alone (0.50) it reads
    0.31, and against a low-pass at 0.068, 0.53.
    """
    if not base_chain or type(effect).initial is not Effect.initial:
        return guess
    # the fast tier: a chain with a simulation effect is rerun on the search length, so
    # the record is read over as many samples as the runs have
    runs = np.array(problem.ensemble(list(base_chain), "fast"))
    n = min(problem.real.size, runs.shape[1])
    other = dict(call_hook(effect, "guess", problem.real[:n], runs[:, :n],
                           problem.sample_dt))
    if other == guess:
        return guess
    return min((guess, other), key=objective)


class _Objective:
    """Gap of base chain + effect(params) on the fast indicators, with bookkeeping."""

    def __init__(self, effect, problem, base_chain):
        self.effect, self.problem, self.base_chain = effect, problem, list(base_chain)
        self.n_evals = 0
        self.best = (np.inf, None)
        self.last_error = None

    def __call__(self, params):
        self.n_evals += 1
        try:
            gap = self.problem.evaluate(self.base_chain + [(self.effect, params)], "fast").gap
        except CandidateFailed as exc:  # this parameter value fails; the search goes on
            gap, self.last_error = np.inf, exc
        if gap < self.best[0]:
            self.best = (gap, dict(params))
        return gap

    def precise(self, params):
        """The same gap on every run of the ensemble (a search's final comparisons)."""
        self.n_evals += 1
        try:
            return self.problem.evaluate(self.base_chain + [(self.effect, params)], "fast",
                                         n_search=len(self.problem.sim_seeds)).gap
        except CandidateFailed as exc:
            self.last_error = exc
            return np.inf


def fit_effect(effect, problem, base_chain=(), final=True):
    """Fit ``effect`` on top of ``base_chain``; return a :class:`FitResult`.

    ``final=False`` skips the evaluation of the fitted effect on every
    indicator (``gap_after`` NaN): cross-validation only needs the parameters
    of the half it fits on, and scores them on the other half.

    A candidate that cannot act (:class:`NotApplicable`), whose simulator or
    user-defined effect fails (:class:`CandidateFailed`) comes back with
    ``status="failed"`` and the reason; other exceptions from the built-in
    code are bugs and propagate.
    """
    # joblib's workers inherit no thread limit here; BLAS threads spinning against each
    # other made a 4e4-sample diagnosis 3 times slower with n_jobs=2 than with 1
    with threadpool_limits(limits=1, user_api="blas"):
        return _fit(effect, problem, base_chain, final)


def _fit(effect, problem, base_chain, final=True):
    t0 = time.perf_counter()
    objective = _Objective(effect, problem, base_chain)
    guess = None
    try:
        guess = initial_params(effect, problem)
        call_hook(effect, "check", guess, problem.simulator)
        guess = _chain_start(effect, problem, base_chain, guess, objective)
        params = call_hook(effect, "search", problem, dict(guess), objective)
        if not isinstance(params, dict):
            raise CandidateFailed(f"effect {effect.name!r}: search() returned "
                                  f"{type(params).__name__}, not a dict of parameters.")
        if not np.isfinite(objective.best[0]) and objective.n_evals:
            raise CandidateFailed(f"the simulator failed for every parameter value tried "
                                  f"(last: {objective.last_error})")
        if not final:
            return FitResult(effect=effect.name, target=effect.target, params=_clean(params),
                             gap_fast=objective.best[0], n_evals=objective.n_evals,
                             seconds=time.perf_counter() - t0)
        final = problem.evaluate(list(base_chain) + [(effect, params)], "full")
        if not np.isfinite(final.gap):
            raise CandidateFailed(f"the fitted effect gives a non-finite gap ({final.gaps}).")
    except (NotApplicable, CandidateFailed) as exc:
        return FitResult(effect=effect.name, target=effect.target,
                         params=_clean(guess) if guess else {}, status="failed",
                         reason=str(exc), n_evals=objective.n_evals,
                         seconds=time.perf_counter() - t0,
                         applicable=not isinstance(exc, NotApplicable))
    return FitResult(effect=effect.name, target=effect.target, params=_clean(params),
                     gap_after=final.gap, gap_fast=objective.best[0], gaps=final.gaps,
                     n_evals=objective.n_evals, seconds=time.perf_counter() - t0,
                     evaluation=final)


def _clean(params):
    """Plain floats (strings and None kept; flags such as ``detected`` dropped)."""
    return {k: (float(v) if isinstance(v, numbers.Real) else v) for k, v in params.items()
            if not isinstance(v, (bool, np.bool_))}
