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
from scipy import optimize
from threadpoolctl import threadpool_limits

from ._effects import CandidateFailed, NotApplicable, call_hook

#: evaluation budgets (observation effects are cheap, simulation effects are not)
GRID = {"observation": 7, "simulation": 5}
REFINE = {"observation": 6, "simulation": 3}
NM_EVALS = {"observation": 25, "simulation": 12}


@dataclass(frozen=True)
class FitResult:
    """Outcome of fitting one candidate effect.

    ``status`` is ``"ok"`` or ``"failed"``; ``reason`` says why a candidate
    failed (empty when ok).  ``gap_after`` is the gap of simulator + chain +
    effect on every indicator (NaN when failed), ``gap_fast`` the search's
    best gap on the fast indicators, ``gaps`` the gap per indicator.
    ``params`` are the fitted values (the starting guess when the fit failed
    after it, else empty).
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
    evaluation: object = field(default=None, repr=False, compare=False)

    @property
    def ok(self):
        """True when the candidate was fitted and evaluated."""
        return self.status == "ok"


def initial_params(effect, problem):
    """The effect's starting parameters (its :meth:`~Effect.initial` hook)."""
    return dict(call_hook(effect, "initial", problem))


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


def _transform(effect, key, lo, hi):
    if key in effect.log_params:
        lo, hi = max(lo, 1e-300), max(hi, 1e-300)
        return np.log(lo), np.log(hi), np.exp, np.log
    return lo, hi, (lambda v: v), (lambda v: v)


#: the search result replaces the signature guess only if it lowers the gap by more than
#: this (absolute, relative to the guess's gap): on a flat objective the guess is better.
#: Simulation effects re-draw their runs at every evaluation, so their objective is noisier.
KEEP_GUESS = {"observation": (0.25, 0.02), "simulation": (1.0, 0.1)}


def generic_search(effect, problem, guess, objective):
    """Bounded grid + Brent (1-D) or Nelder-Mead (2-D) search around ``guess``.

    Returns the guess itself when the search cannot beat it clearly (flat,
    noisy objective): the signature estimate (line amplitude from the DFT,
    ADC step from the distinct values, ...) is then the better value.
    """
    space = effect.search_bounds(guess, problem)
    keys = list(space)
    kind = effect.target
    gap_guess = objective(guess)
    if not keys:
        return guess
    best = _search(effect, problem, guess, objective, space, keys, kind)
    absolute, relative = KEEP_GUESS[kind]
    if objective.best[0] < gap_guess - max(absolute, relative * gap_guess):
        return best
    return guess


def _search(effect, problem, guess, objective, space, keys, kind):
    tr = {k: _transform(effect, k, *space[k]) for k in keys}

    def params_of(vec):
        p = dict(guess)
        for k, v in zip(keys, vec):
            lo, hi, inv, _ = tr[k]
            p[k] = float(inv(np.clip(v, lo, hi)))
        return p

    def f(vec):
        return objective(params_of(np.atleast_1d(vec)))

    x0 = [float(np.clip(tr[k][3](max(guess[k], 1e-300) if k in effect.log_params else guess[k]),
                        tr[k][0], tr[k][1])) for k in keys]
    if len(keys) == 1:
        lo, hi = tr[keys[0]][0], tr[keys[0]][1]
        grid = np.linspace(lo, hi, GRID[kind])
        values = np.array([f(g) for g in grid])
        i = int(np.argmin(values))
        if np.isfinite(values[i]) and REFINE[kind] > 0:
            a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
            if b > a:
                optimize.minimize_scalar(f, bounds=(a, b), method="bounded",
                                         options={"maxiter": REFINE[kind],
                                                  "xatol": 1e-3 * (hi - lo)})
    else:
        bounds = [(tr[k][0], tr[k][1]) for k in keys]
        simplex = [x0]
        for i, (lo, hi) in enumerate(bounds):
            v = list(x0)
            step = 0.25 * (hi - lo)
            v[i] = v[i] + step if v[i] + step <= hi else v[i] - step
            simplex.append(v)
        optimize.minimize(f, x0, method="Nelder-Mead", bounds=bounds,
                          options={"initial_simplex": np.array(simplex), "maxfev": NM_EVALS[kind],
                                   "xatol": 1e-3, "fatol": 1e-3})
    return objective.best[1] if objective.best[1] is not None else guess


def fit_effect(effect, problem, base_chain=()):
    """Fit ``effect`` on top of ``base_chain``; return a :class:`FitResult`.

    A candidate that cannot act (:class:`NotApplicable`), whose simulator or
    user-defined effect fails (:class:`CandidateFailed`) comes back with
    ``status="failed"`` and the reason; other exceptions from the built-in
    code are bugs and propagate.
    """
    # joblib's workers inherit no thread limit here; BLAS threads spinning against each
    # other made a 4e4-sample diagnosis 3 times slower with n_jobs=2 than with 1
    with threadpool_limits(limits=1, user_api="blas"):
        return _fit(effect, problem, base_chain)


def _fit(effect, problem, base_chain):
    t0 = time.perf_counter()
    objective = _Objective(effect, problem, base_chain)
    guess = None
    try:
        guess = initial_params(effect, problem)
        call_hook(effect, "check", guess, problem.simulator)
        params = call_hook(effect, "search", problem, dict(guess), objective)
        if not isinstance(params, dict):
            raise CandidateFailed(f"effect {effect.name!r}: search() returned "
                                  f"{type(params).__name__}, not a dict of parameters.")
        if not np.isfinite(objective.best[0]) and objective.n_evals:
            raise CandidateFailed(f"the simulator failed for every parameter value tried "
                                  f"(last: {objective.last_error})")
        final = problem.evaluate(list(base_chain) + [(effect, params)], "full")
        if not np.isfinite(final.gap):
            raise CandidateFailed(f"the fitted effect gives a non-finite gap ({final.gaps}).")
    except (NotApplicable, CandidateFailed) as exc:
        return FitResult(effect=effect.name, target=effect.target,
                         params=_clean(guess) if guess else {}, status="failed",
                         reason=str(exc), n_evals=objective.n_evals,
                         seconds=time.perf_counter() - t0)
    return FitResult(effect=effect.name, target=effect.target, params=_clean(params),
                     gap_after=final.gap, gap_fast=objective.best[0], gaps=final.gaps,
                     n_evals=objective.n_evals, seconds=time.perf_counter() - t0,
                     evaluation=final)


def _clean(params):
    """Plain floats (strings and None kept; flags such as ``detected`` dropped)."""
    return {k: (float(v) if isinstance(v, numbers.Real) else v) for k, v in params.items()
            if not isinstance(v, (bool, np.bool_))}
