"""Base class and registry of the candidate causes of a sim-to-real gap.

An *effect* is one physical reason why measured data can differ from a
simulator that is otherwise right: a measurement artefact applied to the
simulated observation (noise, hum, ADC steps, detector bandwidth, ...) or a
change of the simulation itself (dynamical noise, another delay, a drifting
parameter).  Each effect knows

* its parameters, their units and their admissible ``bounds``;
* ``guess(real, sim, sample_dt)``: a first estimate read off the signature the
  effect leaves in the data (a spectral line gives the hum frequency, the set
  of distinct values the ADC step, ...);
* how it is applied: ``apply(x, params, ...)`` to a simulated observation
  (``target = "observation"``) or ``overrides(params, simulator)`` passed to
  ``simulator.simulate(..., **overrides)`` (``target = "simulation"``); the
  overrides :data:`SAMPLING_FACTOR` and :data:`HISTORY` reach no simulator:
  they multiply the sampling step of the runs (a timebase mismatch) and
  prepend the part's history to them (a drift on a later part of a record).

:func:`diagnose_gap` fits every registered effect (or the ones it is given);
:func:`register_effect` adds user-defined ones.
"""

from __future__ import annotations

import math
import re
from typing import ClassVar

import numpy as np

from ._search import generic_search

#: Override key of a simulation effect that changes the runs' sampling step instead of a
#: parameter: ``simulate(n, sample_dt=sample_dt * factor, ...)`` without the key.  A clock
#: mismatch is re-simulated rather than read off the nominal runs by interpolation: every
#: interpolation leaves its own traces, and which one resembles a real recorder depends on
#: the signal (a cubic spline smooths a signal with power near Nyquist -- Ikeda at step
#: 0.25 was told from the simulator at a factor of 1.0001 by that alone --, a Fourier series
#: rings around the laser's spikes: at the true factor of a laser record sampled 1.6 % fast
#: it left a gap of 6.5 against 0.2 for the spline; benchmarks/gap_timebase.py).
SAMPLING_FACTOR = "_sampling_factor"
#: Override key of a simulation effect whose part of the record has a history: the runs
#: are ``simulate(round(n * (1 + h)), ...)`` without the key, of which the last ``n``
#: samples are kept (``h`` the history's length in units of the part's).  A drift fitted on
#: a later part of a record (a cross-validation's second half) is simulated from the
#: record's start, as the real system went through it: started afresh at the part's first
#: value, a system with coexisting attractors can settle on another one.  CO2 laser, pump r
#: 195 -> 129 over 6000 samples (held-out-style benchmark seed 19.4e6): the true ramp over
#: the second half alone, r 163 -> 131 from a fresh start, left that half's gap at 2701
#: (544 with no drift); the same ramp continued from the record's start fits it.
HISTORY = "_history"

#: name -> effect class; filled by the effect modules and :func:`register_effect`.
EFFECTS = {}

# full match only: ``re.match`` with ``$`` would accept a trailing newline ("ok_name\n")
_NAME = re.compile(r"[a-z][a-z0-9_]*")


class NotApplicable(ValueError):
    """The effect cannot act on these data or this simulator (e.g. no delay parameter).

    Raised by the effects' own hooks; the fit turns it into a failed candidate
    with this message as the reason.
    """


class CandidateFailed(RuntimeError):
    """A candidate (simulator + effect) could not be evaluated; the message says why."""


class SimulationFailed(CandidateFailed):
    """The simulator failed, diverged or returned unusable data."""


class EffectFailed(CandidateFailed):
    """A user-registered effect raised an exception or returned unusable data."""


def check_name(name):
    """Return ``name`` if it is a valid effect name, else raise ``ValueError``."""
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise ValueError(
            f"effect name {name!r} is not valid; use a lower-case identifier such as "
            "'my_effect' (letters, digits, underscores, starting with a letter)."
        )
    return name


def is_builtin(effect):
    """True for the effects defined in :mod:`skdelay.gap` (their exceptions are bugs)."""
    return type(effect).__module__.startswith("skdelay.gap.")


def call_hook(effect, hook, *args, **kwargs):
    """``effect.<hook>(*args, **kwargs)`` with user code fenced off.

    A user-registered effect is user code: whatever it raises fails this
    candidate only (:class:`EffectFailed` with the reason) and the diagnosis
    goes on.  The built-in effects are not wrapped: an exception from them
    other than :class:`NotApplicable` / :class:`CandidateFailed` is a bug and
    must surface.
    """
    method = getattr(effect, hook)
    if is_builtin(effect):
        return method(*args, **kwargs)
    try:
        return method(*args, **kwargs)
    except CandidateFailed:
        raise
    except Exception as exc:  # boundary of user code (a registered effect)
        raise EffectFailed(
            f"effect {effect.name!r}: {hook}() raised {type(exc).__name__}: {exc}"
        ) from exc


class Effect:
    """Base class of a candidate cause of a sim-to-real gap.

    Subclasses set the class attributes and implement :meth:`guess` plus
    either :meth:`apply` (``target = "observation"``) or :meth:`overrides`
    (``target = "simulation"``).  The other hooks have default
    implementations that subclasses may override: :meth:`initial` (starting
    parameters from the whole problem), :meth:`starts` (more of them, for a pair
    fitted in turn), :meth:`search` (the fit),
    :meth:`search_bounds`, :meth:`check`, :meth:`transfer` (parameters
    fitted on one half of the record for the other half) and
    :meth:`describe`.  Whatever a user-registered effect raises fails that
    candidate only, with the exception as the reason.  Parameters are plain floats in the units
    listed in ``units``; amplitudes of observation effects are relative to
    the standard deviation of the clean simulated signal, so they do not
    depend on gain or offset of the real data.

    Attributes
    ----------
    name : str
        Registry key (lower case, letters, digits, underscores).
    target : {"observation", "simulation"}
        Where the effect acts.
    stage : int
        Position in the measurement chain (smaller acts first) when several
        observation effects are combined.
    bounds : dict
        ``param -> (low, high)`` admissible values of the searched parameters.
    log_params : tuple of str
        Parameters searched on a logarithmic scale.
    units : dict
        ``param -> unit`` (human readable, for the report).
    description : str
        One line for the report.

    Examples
    --------
    >>> import numpy as np
    >>> from skdelay.gap import EFFECTS, Effect, register_effect, unregister_effect
    >>> class BaselineStep(Effect):
    ...     name = "baseline_step"
    ...     bounds = {"size": (0.01, 3.0)}
    ...     units = {"size": "x signal std"}
    ...     description = "a step in the baseline half-way through the record"
    ...     def guess(self, real, sim, sample_dt):
    ...         half = len(real) // 2
    ...         step = abs(real[half:].mean() - real[:half].mean()) / real.std()
    ...         return {"size": float(np.clip(step, 0.01, 3.0))}
    ...     def apply(self, x, params, *, sample_dt=1.0, random_state=None):
    ...         y = np.array(x, dtype=float)
    ...         y[len(y) // 2:] += params["size"] * y.std()
    ...         return y
    >>> _ = register_effect(BaselineStep)
    >>> "baseline_step" in EFFECTS
    True
    >>> _ = unregister_effect("baseline_step")
    """

    name = None
    target = "observation"
    stage = 50
    bounds: ClassVar[dict] = {}
    log_params = ()
    units: ClassVar[dict] = {}
    description = ""
    #: indicators on which the effect leaves its mark; the second round of a diagnosis
    #: tries the effects whose signature covers an indicator that is still off
    #: (empty: always tried)
    signature: ClassVar[tuple] = ()
    #: the parameters are tied to the start of the record (a drift that starts at the
    #: simulator's value): fitted on its second half they would mean something else, so
    #: cross-validation fits such an effect on the first half only -- unless its search
    #: honours a part's ``anchor`` (``fits_anchored_parts``: the fractions of the record a
    #: part spans), fitting a later part on a ramp through the record's start
    anchored_at_start = False
    fits_anchored_parts = False
    #: how long one fit takes against a simulation effect's 1-D search (None: 1 for a
    #: simulation effect, 0 for an observation effect, which re-runs no simulator).  A
    #: scheduling hint only: a diagnosis hands the longest fits to its workers first, so
    #: that none starts late and runs alone at the end; no result depends on it
    fit_cost = None

    def line_frequencies(self, params):
        """Frequencies (cycles per time unit) of the only spectral lines this effect adds, or
        None when it moves the spectrum over a band (the default).  A diagnosis reads a
        spectral discrepancy away from these lines, left after the effect, as another
        cause's mark: no fit of this effect can leave one there."""
        return None  # noqa: RET501 -- None is the documented "over a band"

    def has_local_mark(self, problem):
        """Does the record hold a localised mark of this effect that no indicator of the
        problem measures (a sub-threshold spectral line)?  The second round of a diagnosis
        then tries the effect even when no indicator of its signature is still off; the
        fit must still earn its place by the residual it removes."""
        return False

    # ----------------------------------------------------------------- API
    def guess(self, real, sim, sample_dt):
        """Initial parameters from the data's signature.

        Parameters
        ----------
        real : ndarray (n,)
            The measured series (any gain and offset).
        sim : ndarray (n_sims, n_sim)
            Clean simulated observations (``n_sim >= n``).
        sample_dt : float
            Sampling step in time units.

        Returns
        -------
        dict
            Every parameter in ``bounds`` (plus any fixed ones ``apply`` needs).
        """
        return {p: _mid(lo, hi, p in self.log_params) for p, (lo, hi) in self.bounds.items()}

    def apply(self, x, params, *, sample_dt=1.0, random_state=None):
        """Return the observation ``x`` as seen through the effect (observation effects)."""
        raise TypeError(
            f"effect {self.name!r} acts on the simulation; use its overrides(), not apply()."
        )

    def overrides(self, params, simulator):
        """Keyword overrides for ``simulator.simulate`` (simulation effects)."""
        raise TypeError(
            f"effect {self.name!r} acts on the observation; use its apply(), not overrides()."
        )

    def initial(self, problem):
        """Starting parameters for a fit on ``problem`` (a :class:`GapProblem`).

        Default: :meth:`guess` on the real series and the clean ensemble.
        Effects that need the simulator (calibration runs) override this.
        """
        return self.guess(problem.real, np.array(problem.base), problem.sample_dt)

    def search(self, problem, guess, objective):
        """Fitted parameters: minimise ``objective(params)`` (the gap) starting at ``guess``.

        Default: the bounded grid + Brent / Nelder-Mead search of
        :func:`skdelay.gap._search.generic_search` within :meth:`search_bounds`.
        """
        return generic_search(self, problem, guess, objective)

    def starts(self, problem):
        """Further starting parameters, spread over the values the record allows.

        A pair of effects fitted in turn (:func:`skdelay.gap.diagnose_gap`: two
        observation effects that mark the same indicators) starts from the best of
        these as well as from the effect's own fit: that fit may sit in another
        basin than the pair's.  Default: none.
        """
        return ()

    def transfer(self, params, n_fit, n_score, sample_dt=1.0, backward=False):
        """Parameters fitted on ``n_fit`` samples, for the next ``n_score`` samples.

        Cross-validation fits on one half of the record and scores on the
        other, both ways round.  Default: the same values (stationary effects);
        a drift overrides this to continue its ramp, a hum to carry its phase on.
        ``sample_dt`` (time units per sample) and ``backward`` (the scored
        samples come *before* the fitted ones) are passed to the built-in
        effects only; a registered effect is called with the first three
        arguments, and one that overrides this method is scored on the forward
        split alone (fitted on the first half, scored on the second).
        """
        return dict(params)

    # ------------------------------------------------------------- helpers
    def search_bounds(self, guess, context):
        """Bounds of the local search around ``guess`` (default: the global ``bounds``).

        ``context`` is the fitting problem (gives ``sample_dt``, ``n_samples``,
        the simulator); effects override this to search a narrow window.
        """
        return dict(self.bounds)

    def check(self, params, simulator=None):
        """Raise :class:`NotApplicable` if the effect cannot act with ``simulator``."""

    def describe(self, params, *, scale=1.0, offset=0.0, sample_dt=1.0, time_unit=None):
        """One phrase with the fitted parameters in physical units.

        ``scale`` and ``offset`` convert the clean signal's standard units into
        the units of the real data (``value_real = offset + scale * z``);
        ``time_unit`` (None: unknown) lets frequencies be named in Hz.
        """
        parts = []
        for key, value in params.items():
            unit = self.units.get(key, "")
            parts.append(f"{key} = {fmt_value(value)}{(' ' + unit) if unit else ''}")
        return ", ".join(parts)

    def __repr__(self):
        return f"{type(self).__name__}()"


def _mid(lo, hi, log):
    return float(math.sqrt(lo * hi) if log else 0.5 * (lo + hi))


def fmt_value(value):
    if isinstance(value, str):
        return value
    value = float(value)
    if not np.isfinite(value):
        return "none"
    return f"{value:.4g}"


def register_effect(effect, *, overwrite=False):
    """Add an effect class (or instance) to :data:`EFFECTS`.

    Parameters
    ----------
    effect : subclass or instance of :class:`Effect`
    overwrite : bool, default False
        Replace an existing effect of the same name.

    Returns
    -------
    type
        The registered class (so this works as a decorator).

    Raises
    ------
    TypeError
        If ``effect`` is not an :class:`Effect` or lacks ``apply``/``overrides``.
    ValueError
        If the name is missing, malformed or already taken.

    Examples
    --------
    >>> from skdelay.gap import Effect, register_effect, unregister_effect
    >>> @register_effect
    ... class Mirror(Effect):
    ...     name = "sign_flip"
    ...     bounds = {"fraction": (0.0, 1.0)}
    ...     def apply(self, x, params, *, sample_dt=1.0, random_state=None):
    ...         return -x if params["fraction"] > 0.5 else x
    >>> Mirror.name
    'sign_flip'
    >>> _ = unregister_effect("sign_flip")
    """
    cls = effect if isinstance(effect, type) else type(effect)
    if not (isinstance(cls, type) and issubclass(cls, Effect)):
        raise TypeError(
            f"register_effect expects a subclass of skdelay.gap.Effect, got {effect!r}; "
            "derive your class from Effect and set name, bounds and apply/overrides."
        )
    name = check_name(cls.name)
    if cls.target not in ("observation", "simulation"):
        raise ValueError(
            f"effect {name!r} has target={cls.target!r}; use 'observation' or 'simulation'."
        )
    hook = "apply" if cls.target == "observation" else "overrides"
    if getattr(cls, hook) is getattr(Effect, hook):
        raise TypeError(f"effect {name!r} acts on the {cls.target} but does not define {hook}().")
    for key, bound in dict(cls.bounds).items():
        if len(bound) != 2 or not float(bound[0]) < float(bound[1]):
            raise ValueError(
                f"effect {name!r}: bounds[{key!r}] must be (low, high) with low < high.")
    if name in EFFECTS and not overwrite and EFFECTS[name] is not cls:
        raise ValueError(
            f"an effect named {name!r} is already registered; pick another name or pass "
            "overwrite=True."
        )
    EFFECTS[name] = cls
    return cls


def unregister_effect(name):
    """Remove ``name`` from :data:`EFFECTS` and return its class."""
    check_name(name)
    try:
        return EFFECTS.pop(name)
    except KeyError:
        raise ValueError(
            f"no effect named {name!r} is registered; registered: {sorted(EFFECTS)}."
        ) from None


def get_effect(effect):
    """Return an effect instance from a name, class or instance (clear error otherwise)."""
    if isinstance(effect, Effect):
        check_name(effect.name)
        return effect
    if isinstance(effect, type) and issubclass(effect, Effect):
        check_name(effect.name)
        return effect()
    if isinstance(effect, str):
        if effect not in EFFECTS:
            raise ValueError(
                f"unknown effect {effect!r}; valid names are {sorted(EFFECTS)} "
                "(or register your own with skdelay.gap.register_effect)."
            )
        return EFFECTS[effect]()
    raise TypeError(
        f"effects must be given by name, Effect class or instance, got {effect!r}."
    )


def resolve_effects(effects):
    """Instances for ``effects`` (None -> every registered effect), no duplicates."""
    if effects is None:
        items = list(EFFECTS)
    elif isinstance(effects, (str, Effect, type)):
        items = [effects]
    else:
        items = list(effects)
    out, seen = [], set()
    for item in items:
        eff = get_effect(item)
        if eff.name in seen:
            raise ValueError(f"effect {eff.name!r} is listed twice; list each effect once.")
        seen.add(eff.name)
        out.append(eff)
    if not out:
        raise ValueError("effects is empty; pass None (all effects) or at least one name.")
    return out
