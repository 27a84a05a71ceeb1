"""Base class of the delay systems: parameters, ``simulate`` and exact spectra.

A concrete system only declares its parameters (the ``__init__`` signature,
which must include ``tau``), its dimension ``dim``, the fed-back component
``feedback_index``, and two numba-compilable functions ``_rhs`` / ``_jac``
with the C signatures of :mod:`._integrate`.  Everything else (checks, drift,
noise, integration step, transient, Lyapunov spectrum) lives here, once.
"""

from __future__ import annotations

import inspect
import math
import numbers

import numpy as np

from .._checks import check_positive_int, check_random_state
from .._memo import BoundedStore
from .._spectrum import LyapunovSpectrum
from ._integrate import integrate_chunk, register, stencils
from ._tangent import orthonormalise, tangent_run

_CHUNK_STEPS = 1 << 18  # integration steps per noise chunk (memory bound)
#: generous multiple of a system's a-priori amplitude before a run counts as diverged
#: (the attractors stay well inside it; noise and drift only add a few widths)
_BOUND_FACTOR = 1e3
#: most RK4 steps one simulate() call may take (~minutes with the numba kernels): beyond
#: it the run would look like a hang, so say which argument to change instead
_MAX_STEPS = 10_000_000_000
#: a-priori amplitude used when a system declares none
_DEFAULT_SCALE = 1e6
#: states of seeded runs after their transient, kept per process for the runs that share
#: them (see :meth:`DelaySystem.simulate`); 24 MiB hold about 150 states of the CO2 laser
#: at tau = 400 (20 000 history steps each), more than a gap diagnosis's seeds.  Not
#: pickled: a joblib worker fills its own, and keeps it from task to task.
_SETTLED = BoundedStore(24 * 2**20)


class DivergenceError(ValueError):
    """A simulation left every plausible range: the parameters give no bounded solution."""


def _ring_size(tau_max, dt):
    """Length of the ring buffer of ``x_l`` for a largest delay ``tau_max``."""
    return math.ceil(tau_max / dt - 1e-9) + 3


class DelaySystem:
    """A DDE ``dx/dt = f(x(t), x_l(t - tau))`` with one delayed feedback component.

    Subclasses set ``name``, ``dim``, ``feedback_index``, ``max_dt`` (largest
    default integration step, in time units), ``time_unit``, ``noise_scale``
    (per-component scale of the dynamical noise), ``transient_time`` and
    ``transient_delays`` (the default transient is the longer of the two, the second
    in delays) and the numba functions ``_rhs`` and ``_jac``; their ``__init__`` passes its
    arguments (including ``tau``) to ``DelaySystem.__init__``.

    Integration is RK4 with a fixed step ``dt`` (see :mod:`._integrate`); by
    default ``dt`` is the largest ``sample_dt / k`` (integer ``k``) not above
    ``max_dt``, so every sample falls on the integration grid.
    """

    name = "delay_system"
    dim = 1
    feedback_index = 0
    max_dt = 0.05
    time_unit = "time unit"
    transient_time = 500.0
    transient_delays = 10.0
    qr_interval = 1.0
    spectrum_duration = 20_000.0
    noise_scale = (1.0,)

    _rhs = None
    _jac = None

    def __init__(self, **params):
        for key, value in params.items():
            params[key] = self._check_value(key, value)
        self._params = params
        self._check_params(dict(params))

    # ------------------------------------------------------------------ params
    @classmethod
    def param_names(cls):
        """Parameter names in the order of the constructor (``tau`` included)."""
        sig = inspect.signature(cls.__init__)
        return tuple(p for p in sig.parameters if p != "self")

    @property
    def params(self):
        """dict of the parameter values (a copy)."""
        return dict(self._params)

    def set_params(self, **params):
        """Return a new system of the same class with some parameters replaced."""
        new = self.params
        new.update(self._check_overrides(params, allow_drift=False)[0])
        return type(self)(**new)

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self._params.items())
        return f"{type(self).__name__}({args})"

    def __eq__(self, other):
        return type(self) is type(other) and self._params == other._params

    def __hash__(self):
        return hash((type(self).__name__, tuple(self._params.items())))

    def _check_value(self, key, value):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
            raise TypeError(
                f"{type(self).__name__} parameter {key!r} must be a real number, got {value!r}."
            )
        value = float(value)
        if not math.isfinite(value):
            raise ValueError(
                f"{type(self).__name__} parameter {key!r} is {value}; give a finite number."
            )
        if key == "tau" and value <= 0:
            raise ValueError(
                f"the delay tau must be positive (in {self.time_unit}s), got {value}; a system "
                "without delay is an ODE - use a small positive tau if you really want that."
            )
        return value

    def _check_params(self, params):
        """Hook for system-specific domain checks (raise ValueError)."""

    def _amplitude(self, params):
        """A-priori amplitude of the observed component for ``params`` (hook).

        :meth:`simulate` treats ``|x| > _BOUND_FACTOR * (amplitude + noise)``
        as divergence.  Systems override it with a bound from their equations
        (e.g. ``a / b`` for Mackey-Glass); the default is deliberately loose.
        """
        return _DEFAULT_SCALE

    def _changed(self, params):
        """``{name: (value, default)}`` of the parameters that differ from the defaults."""
        try:
            defaults = type(self)().params
        except (TypeError, ValueError):  # pragma: no cover - systems without defaults
            return {}
        return {k: (v, defaults[k]) for k, v in params.items()
                if k in defaults and v != defaults[k]}

    def _check_overrides(self, overrides, *, allow_drift):
        """Split overrides into (start, end) parameter dicts, validating names and values."""
        names = self.param_names()
        start, end = self.params, self.params
        start, end = dict(start), dict(end)
        drift = False
        for key, value in overrides.items():
            if key not in names:
                raise TypeError(
                    f"{type(self).__name__} has no parameter {key!r}; valid parameters: "
                    f"{', '.join(names)} (and the keywords sample_dt, dt, transient, "
                    "random_state, dynamical_noise)."
                )
            if isinstance(value, (tuple, list, np.ndarray)):
                if not allow_drift:
                    raise ValueError(
                        f"parameter {key!r} got {value!r}; a (start, end) drift is only allowed "
                        "in simulate(), give a single number here."
                    )
                if len(value) != 2:
                    raise ValueError(
                        f"a drifting parameter is given as (start, end); {key!r} got {value!r}."
                    )
                start[key] = self._check_value(key, value[0])
                end[key] = self._check_value(key, value[1])
                drift = drift or start[key] != end[key]
            else:
                start[key] = end[key] = self._check_value(key, value)
        self._check_params(dict(start))
        self._check_params(dict(end))
        return start, end, drift

    def _vector(self, params):
        return np.array([params[k] for k in self.param_names() if k != "tau"], dtype=np.float64)

    # --------------------------------------------------------------- numerics
    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.__dict__.get("_rhs") is not None:
            cls._tag = register(cls.__name__, cls._rhs, cls._jac, cls.dim)

    def _kernel_tag(self):
        """The tag instance the kernels are compiled for (their work arrays are sized by the
        class's ``dim`` when it was defined: :func:`._integrate.register`)."""
        if self.dim != self._tag.DIM:
            raise ValueError(
                f"{type(self).__name__}.dim is {self.dim}, but the class was defined with "
                f"dim = {self._tag.DIM}; set dim as a class attribute, not per instance "
                "(the integrator is compiled for one state dimension per class)."
            )
        return self._tag(self.dim)

    def _choose_dt(self, sample_dt, dt):
        sample_dt = float(sample_dt)
        if not (math.isfinite(sample_dt) and sample_dt > 0):
            raise ValueError(f"sample_dt must be a positive time step, got {sample_dt}.")
        if dt is None:
            every = max(1, math.ceil(sample_dt / self.max_dt - 1e-9))
            return sample_dt / every, every
        dt = float(dt)
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"the integration step dt must be positive, got {dt}.")
        ratio = sample_dt / dt
        every = round(ratio)
        if every < 1 or abs(ratio - every) > 1e-6 * ratio:
            raise ValueError(
                f"sample_dt={sample_dt} is not an integer multiple of the integration step "
                f"dt={dt}; choose dt = sample_dt / k, e.g. dt={sample_dt / max(1, math.ceil(ratio))}."
            )
        return sample_dt / every, every

    def _check_resolution(self, tau, dt):
        if dt >= tau:
            raise ValueError(
                f"the integration step dt={dt} does not resolve the delay tau={tau}: dt must be "
                f"smaller than tau (ideally tau/dt >= 20); pass a smaller dt or sample_dt."
            )
        if tau / dt > 5e7:
            raise ValueError(
                f"tau/dt = {tau / dt:.3g} history points is too many; use a larger dt."
            )

    def _initial_state(self, rng, times, params):
        """Initial state (d,) at t = 0 and history of x_l at ``times`` (< 0).

        Default: a random state and a constant history with 1 % jitter;
        systems override it with a sensible range.
        """
        x0 = 0.5 + rng.uniform(size=self.dim)
        hist = x0[self.feedback_index] * (1.0 + 0.01 * rng.standard_normal(times.size))
        return x0, hist

    def _start(self, rng, tau_max, dt, params):
        m_ring = _ring_size(tau_max, dt)
        x0, hist = self._initial_state(rng, (np.arange(m_ring) - m_ring) * dt, params)
        x = np.array(x0, dtype=np.float64)
        ring = np.ascontiguousarray(hist, dtype=np.float64)
        counter = np.array([m_ring], dtype=np.int64)  # ring[m % M] = x_l(t_m), m < M
        return x, ring, counter

    def _diverged(self, params, where, end=None, *, what="non-finite state"):
        vals = ", ".join(
            f"{k}={v:g}" if end is None or end[k] == v else f"{k}=({v:g} -> {end[k]:g})"
            for k, v in params.items()
        )
        changed = self._changed(params)
        if end is not None:
            changed.update(self._changed(end))
        if changed:
            fix = "change " + ", ".join(f"{k} (default {d:g})" for k, (_, d) in changed.items())
            fix += " back towards the default"
        else:
            fix = "lower dynamical_noise or pass a smaller dt"
        return DivergenceError(
            f"{type(self).__name__} diverged ({what}) during {where} with {vals}; these "
            f"parameters give no bounded solution: {fix}."
        )

    def _transient(self, transient, tau):
        if transient is None:
            return max(self.transient_time, self.transient_delays * tau)
        transient = float(transient)
        if not (math.isfinite(transient) and transient >= 0):
            raise ValueError(f"transient must be a non-negative time, got {transient}.")
        return transient

    # --------------------------------------------------------------- simulate
    def simulate(self, n_samples, *, sample_dt=1.0, random_state=None, dynamical_noise=0.0,
                 transient=None, dt=None, **overrides):
        """Integrate the system and return the observed (fed-back) component.

        Parameters
        ----------
        n_samples : int
            Number of samples to return.
        sample_dt : float, default=1.0
            Sampling step, in the system's time unit.
        random_state : int, RandomState instance or None
            Seeds the random initial history and the dynamical noise.
        dynamical_noise : float, default=0.0
            Intensity ``D`` of additive white noise: each integration step adds
            ``D * noise_scale * sqrt(dt) * N(0, 1)`` to every component
            (Euler-Maruyama).
        transient : float or None
            Time discarded before recording; default
            ``max(transient_time, transient_delays * tau)``.
        dt : float or None
            Integration step; must divide ``sample_dt``.  Default: the largest
            ``sample_dt / k`` not above ``max_dt``.
        **overrides
            Parameter values for this run.  A ``(start, end)`` pair makes the
            parameter drift linearly from ``start`` (also used during the
            transient) to ``end`` over the recorded part; ``tau`` may drift too.

        Returns
        -------
        ndarray of shape (n_samples,)
            The fed-back component ``x_l`` at times ``transient + i * sample_dt``.

        Notes
        -----
        A run seeded by an integer keeps the state its transient ends in (per
        process, a bounded store): a later run with the same seed, start
        parameters, step, delay, transient and noise intensity continues from
        it, with the same numbers as integrating the transient again.  A
        shorter run is therefore the start of a longer one with the same seed.
        """
        n_samples, start, end, drift, dt, every, noise, transient = self._check_simulation(
            n_samples, sample_dt, dynamical_noise, transient, dt, overrides)
        tau0, tau1 = start["tau"], end["tau"]
        rng = check_random_state(random_state)
        n_trans = math.ceil(transient / (every * dt) - 1e-9)

        p0 = self._vector(start)
        # A seeded run's state after the transient depends only on the seed, the start
        # parameters, the ring's size, dt, the number of steps and the noise: runs that
        # share them (different lengths, or drifts that leave the same start) continue
        # from the stored state, bit for bit the same as integrating the transient again.
        # The CO2 laser discards 7500 us before a gap diagnosis's 6000-10 000-sample
        # runs, which repeat a few tens of seeds hundreds of times.
        settled_key = None
        if isinstance(random_state, numbers.Integral) and n_trans > 0:
            settled_key = (type(self), self.feedback_index, tuple(self.noise_scale),
                           int(random_state), float(dt), n_trans * every,
                           _ring_size(max(tau0, tau1), dt), float(tau0), p0.tobytes(), noise)
        settled = _SETTLED.get(settled_key) if settled_key is not None else None
        if settled is not None:
            x, ring, counter, rng_state = settled
            x, ring, counter = x.copy(), ring.copy(), counter.copy()
            rng.set_state(rng_state)
            n_trans = 0
        else:
            x, ring, counter = self._start(rng, max(tau0, tau1), dt, start)
        dp = self._vector(end) - p0
        p = p0.copy()
        tag = self._kernel_tag()
        noise_scale = np.asarray(self.noise_scale, dtype=np.float64)
        noise_idx = np.flatnonzero(noise_scale).astype(np.int64)
        scale = noise * math.sqrt(dt) * noise_scale[noise_idx]
        rec_start = int(counter[0]) + n_trans * every
        rec_len = max(1, (n_samples - 1) * every)
        out = np.empty(n_samples, dtype=np.float64)
        chunk = max(1, _CHUNK_STEPS // every) if noise > 0 else n_samples + n_trans
        no_noise = np.empty((0, noise_idx.size))
        total = n_trans + n_samples
        done = 0
        while done < total:
            m = min(chunk, total - done)
            if done < n_trans:
                m = min(m, n_trans - done)
                target = np.empty(m)
            else:
                target = out[done - n_trans: done - n_trans + m]
            eps = (rng.standard_normal((m * every, noise_idx.size)) * scale if noise > 0
                   else no_noise)
            ok = integrate_chunk(tag, x, ring, counter, self.feedback_index, p, p0, dp,
                                 tau0, tau1 - tau0, drift, rec_start, rec_len, dt, every,
                                 eps, noise_idx, target)
            if ok < m:
                where = "the transient" if done < n_trans else "the recorded run"
                raise self._diverged(start, where, end if drift else None)
            done += m
            if done == n_trans and settled_key is not None:
                _SETTLED.put(settled_key, (x.copy(), ring.copy(), counter.copy(), rng.get_state()),
                             x.nbytes + ring.nbytes + 5000)
        # finite but absurd values (e.g. 1e243) are divergence too, not data
        bound = _BOUND_FACTOR * (max(self._amplitude(start), self._amplitude(end)) + noise)
        peak = float(np.max(np.abs(out)))
        if not peak <= bound:
            raise self._diverged(start, "the recorded run", end if drift else None,
                                 what=f"|x| reached {peak:.3g}, beyond the bound {bound:.3g}")
        return out

    def _check_simulation(self, n_samples, sample_dt, dynamical_noise, transient, dt,
                          overrides):
        n_samples = check_positive_int(n_samples, name="n_samples")
        start, end, drift = self._check_overrides(overrides, allow_drift=True)
        dt, every = self._choose_dt(sample_dt, dt)
        self._check_resolution(min(start["tau"], end["tau"]), dt)
        noise = float(dynamical_noise)
        if not (math.isfinite(noise) and noise >= 0):
            raise ValueError(f"dynamical_noise must be a non-negative number, got {noise}.")
        transient = self._transient(transient, max(start["tau"], end["tau"]))
        n_steps = (math.ceil(transient / (every * dt) - 1e-9) + n_samples) * every
        if n_steps > _MAX_STEPS:
            raise ValueError(
                f"this run needs {n_steps:.3g} integration steps of dt={dt:g} (n_samples="
                f"{n_samples}, sample_dt={sample_dt:g}, transient={transient:g}); more than "
                f"{_MAX_STEPS:.0e} - use fewer samples, a smaller sample_dt or a shorter transient."
            )
        return n_samples, start, end, drift, dt, every, noise, transient

    def check_simulation(self, n_samples, *, sample_dt=1.0, dynamical_noise=0.0,
                         transient=None, dt=None, **overrides):
        """Make every check of :meth:`simulate` without integrating; raise on a problem.

        Lets a caller (the command line) reject bad arguments before any work
        starts.  Divergence can only be found by simulating.

        Parameters
        ----------
        n_samples, sample_dt, dynamical_noise, transient, dt, **overrides
            As in :meth:`simulate`.

        Raises
        ------
        ValueError, TypeError
            With the message :meth:`simulate` would give.
        """
        self._check_simulation(n_samples, sample_dt, dynamical_noise, transient, dt, overrides)

    # -------------------------------------------------------------- spectrum
    def lyapunov_spectrum(self, n_exponents, *, duration=None, n_steps=None, dt=None,
                          transient=None, tangent_transient=None, qr_interval=None,
                          n_blocks=10, random_state=None, **overrides):
        """Exact Lyapunov spectrum of the RK4-discretised DDE.

        The tangent dynamics of the full discretised state (current state plus
        the ``~tau/dt`` history points of ``x_l``) is propagated with the
        linearised scheme and re-orthonormalised every ``qr_interval``
        (Farmer 1982).  Tangent vectors live in a ring buffer like the history,
        so a step costs O(n_exponents * dim^2).

        Parameters
        ----------
        n_exponents : int
            Number of (largest) exponents, at most ``dim + ~tau/dt``.
        duration : float, optional
            Averaging time (system time units).  Default ``spectrum_duration``.
        n_steps : int, optional
            Averaging length in integration steps (instead of ``duration``).
        dt : float, optional
            Integration step; default ``max_dt``.  The spectrum is that of the
            map with this step; it converges to the DDE's as ``dt -> 0``.
        transient : float, optional
            Time integrated before the tangent dynamics starts (default as in
            :meth:`simulate`).
        tangent_transient : float, optional
            Time the tangent vectors are evolved (to align) before averaging;
            default ``max(5 tau, duration / 20)``.
        qr_interval : float, optional
            Time between re-orthonormalisations; default ``qr_interval``
            class attribute (rounded to whole steps).
        n_blocks : int, default=10
            The average is split into this many blocks; ``spread`` is the
            standard error of the block means.
        random_state : int, RandomState or None
            Initial history and initial tangent vectors.
        **overrides
            Parameter values for this computation (no drift).

        Returns
        -------
        LyapunovSpectrum
            Exponents per time unit (natural log), descending, with ``spread``;
            ``sample_dt`` is the integration step and ``extra`` holds ``dt``,
            ``tau``, ``n_dim`` (dimension of the discretised state), ``blocks``
            (per-block exponents) and ``params``.
        """
        k = check_positive_int(n_exponents, name="n_exponents")
        n_blocks = check_positive_int(n_blocks, name="n_blocks", minimum=2)
        params, _, _ = self._check_overrides(overrides, allow_drift=False)
        tau = params["tau"]
        dt = float(self.max_dt if dt is None else dt)
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"the integration step dt must be positive, got {dt}.")
        self._check_resolution(tau, dt)
        if n_steps is not None and duration is not None:
            raise ValueError("give either duration or n_steps, not both.")
        if n_steps is None:
            duration = float(self.spectrum_duration if duration is None else duration)
            if not (math.isfinite(duration) and duration > 0):
                raise ValueError(f"duration must be a positive time, got {duration}.")
            n_steps = math.ceil(duration / dt)
        n_steps = check_positive_int(n_steps, name="n_steps")
        qr_time = float(self.qr_interval if qr_interval is None else qr_interval)
        if not (math.isfinite(qr_time) and qr_time > 0):
            raise ValueError(f"qr_interval must be a positive time, got {qr_time}.")
        qr_every = max(1, round(qr_time / dt))
        n_qr = max(n_blocks, math.ceil(n_steps / qr_every))
        per_block = math.ceil(n_qr / n_blocks)
        rng = check_random_state(random_state)

        tau_steps = tau / dt
        starts = np.empty(3, dtype=np.int64)
        weights = np.empty((3, 4))
        stencils(tau_steps, starts, weights)
        # oldest history point any stage reads (with a non-zero weight)
        m_ring = max(1, -min(int(starts[i]) + j for i in range(3) for j in range(4)
                             if weights[i, j] != 0.0))
        n_dim = self.dim + m_ring
        if k > n_dim:
            raise ValueError(
                f"n_exponents={k} exceeds the dimension {n_dim} of the discretised state "
                f"(dim + tau/dt); ask for fewer exponents or use a smaller dt."
            )
        x, ring_big, counter = self._start(rng, tau, dt, params)
        tag = self._kernel_tag()
        p = self._vector(params)
        l = self.feedback_index
        # trajectory transient with the simulation kernel, then hand over the history
        trans = self._transient(transient, tau)
        n_trans = math.ceil(trans / dt)
        if n_trans:
            ok = integrate_chunk(tag, x, ring_big, counter, l, p, p, np.zeros_like(p), tau, 0.0,
                                 False, 0, 1, dt, n_trans, np.empty((0, 0)),
                                 np.empty(0, dtype=np.int64), np.empty(1))
            if ok < 1:
                raise self._diverged(params, "the transient")
        n = int(counter[0])
        ring = np.empty(m_ring)
        for m in range(n - m_ring, n):
            ring[m % m_ring] = ring_big[m % ring_big.shape[0]]
        V = rng.standard_normal((k, self.dim))
        W = rng.standard_normal((k, m_ring))
        orthonormalise(V, W)
        logsum = np.zeros(k)
        t_warm = (max(5.0 * tau, n_qr * qr_every * dt / 20.0) if tangent_transient is None
                  else float(tangent_transient))
        n_warm = math.ceil(t_warm / (qr_every * dt))
        if not tangent_run(tag, x, ring, counter, l, p, dt, starts, weights, V, W, n_warm,
                           qr_every, logsum, False):
            raise self._diverged(params, "the tangent transient")
        blocks = np.empty((n_blocks, k))
        for b in range(n_blocks):
            logsum[:] = 0.0
            if not tangent_run(tag, x, ring, counter, l, p, dt, starts, weights, V, W,
                               per_block, qr_every, logsum, True):
                raise self._diverged(params, "the Lyapunov run")
            blocks[b] = logsum / (per_block * qr_every * dt)
        exponents = blocks.mean(axis=0)
        spread = blocks.std(axis=0, ddof=1) / math.sqrt(n_blocks)
        return LyapunovSpectrum(
            exponents, spread, sample_dt=dt, n_steps=n_blocks * per_block * qr_every,
            extra={"dt": dt, "tau": tau, "n_dim": n_dim, "blocks": blocks, "params": params,
                   "system": self.name, "qr_every": qr_every},
        )
