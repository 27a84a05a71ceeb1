"""The default parameter search of an effect: a bounded grid, then Brent or Nelder-Mead.

Kept apart from the effect classes (which call it from :meth:`Effect.search`)
and from the fitting driver (which calls the effects), so imports point one way.
"""

from __future__ import annotations

import numpy as np
from scipy import optimize

__all__ = ["generic_search"]

#: evaluation budgets (observation effects are cheap, simulation effects are not)
GRID = {"observation": 7, "simulation": 5}
REFINE = {"observation": 6, "simulation": 3}
NM_EVALS = {"observation": 25, "simulation": 12}


def _transform(effect, key, lo, hi):
    if key in effect.log_params:
        lo, hi = max(lo, 1e-300), max(hi, 1e-300)
        return np.log(lo), np.log(hi), np.exp, np.log
    return lo, hi, (lambda v: v), (lambda v: v)


#: the search result replaces the signature guess only if it lowers the gap by more than
#: this (absolute, relative to the guess's gap): on a flat objective the guess is better.
#: Simulation effects re-draw their runs at every evaluation, so their objective is noisier.
KEEP_GUESS = {"observation": (0.25, 0.02), "simulation": (1.0, 0.1)}


def generic_search(effect, problem, guess, objective, n_grid=None, n_refine=None, space=None):
    """Bounded grid + Brent (1-D) or Nelder-Mead (2-D) search around ``guess``.

    Returns the guess itself when the search cannot beat it clearly (flat,
    noisy objective): the signature estimate (line amplitude from the DFT,
    ADC step from the distinct values, ...) is then the better value.
    ``n_grid``, ``n_refine``: points of the 1-D grid and Brent iterations
    between its neighbours (defaults ``GRID`` and ``REFINE`` for the effect's
    target; an effect whose objective has features narrower than the default
    spacing asks for more).  ``space``: bounds to search instead of the effect's
    :meth:`~skdelay.gap.Effect.search_bounds`.
    """
    space = effect.search_bounds(guess, problem) if space is None else space
    keys = list(space)
    kind = effect.target
    gap_guess = objective(guess)
    if not keys:
        return guess
    best = _bounded_search(effect, problem, guess, objective, space, keys, kind,
                           n_grid or GRID[kind], REFINE[kind] if n_refine is None else n_refine)
    absolute, relative = KEEP_GUESS[kind]
    if objective.best[0] < gap_guess - max(absolute, relative * gap_guess):
        return best
    return guess


def _bounded_search(effect, problem, guess, objective, space, keys, kind, n_grid, n_refine):
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
        grid = np.linspace(lo, hi, n_grid)
        values = np.array([f(g) for g in grid])
        i = int(np.argmin(values))
        if np.isfinite(values[i]) and n_refine > 0:
            a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
            if b > a:
                optimize.minimize_scalar(f, bounds=(a, b), method="bounded",
                                         options={"maxiter": n_refine,
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
