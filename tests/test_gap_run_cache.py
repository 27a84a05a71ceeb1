"""Simulator runs are made once per diagnosis: the cache returns the same numbers."""

import pickle

import numpy as np

from skdelay.gap import get_effect
from skdelay.gap._problem import GapProblem, RunCache
from skdelay.systems import MackeyGlass


class CountingSimulator:
    """A seeded noise 'simulator' that counts its runs and takes any override."""

    params = {}  # noqa: RUF012 - read-only, as on a DelaySystem

    def __init__(self):
        self.calls = 0

    def simulate(self, n, *, sample_dt=1.0, random_state=None, **overrides):
        self.calls += 1
        rng = np.random.default_rng(random_state)
        return rng.standard_normal(n) * (1.0 + overrides.get("gain", 0.0))


def test_a_repeated_run_is_served_from_the_cache_as_a_fresh_copy():
    sim, cache = CountingSimulator(), RunCache()
    a = cache.run(sim, 500, 1.0, 11, {"gain": 0.5})
    a[:] = 0.0  # the caller may change its copy in place (an effect's apply)
    b = cache.run(sim, 500, 1.0, 11, {"gain": 0.5})
    assert sim.calls == 1 and (cache.hits, cache.misses) == (1, 1)
    assert np.array_equal(b, CountingSimulator().simulate(500, random_state=11, gain=0.5))
    b[:] = 0.0
    assert np.ptp(cache.run(sim, 500, 1.0, 11, {"gain": 0.5})) > 0
    # anything that changes the run is a different key: length, step, seed, overrides
    for args in [(501, 1.0, 11, {"gain": 0.5}), (500, 0.5, 11, {"gain": 0.5}),
                 (500, 1.0, 12, {"gain": 0.5}), (500, 1.0, 11, {"gain": 0.25}),
                 (500, 1.0, 11, {"gain": 0.5, "tau": (1.0, 2.0)}),
                 (500, 1.0, 11, {"gain": 0.5, "tau": (1.0, 2.5)}),
                 (500, 1.0, 11, {"gain": 0.5, "mode": ("a", 1)})]:
        cache.run(sim, *args)
    assert sim.calls == 8
    # an override that cannot be hashed is simulated every time
    assert cache.key(500, 1.0, 11, {"table": [[1.0], [2.0]]}) is None
    cache.run(sim, 500, 1.0, 11, {"table": [[1.0], [2.0]]})
    cache.run(sim, 500, 1.0, 11, {"table": [[1.0], [2.0]]})
    assert sim.calls == 10
    assert cache.key(5, 1.0, 1, {"w": np.ones(2)}) != cache.key(5, 1.0, 1, {"w": np.ones(3)})


def test_the_cache_keeps_its_byte_budget_and_is_not_pickled():
    sim = CountingSimulator()
    cache = RunCache(max_bytes=3 * 8 * 100)  # three runs of 100 samples
    for seed in range(5):
        cache.run(sim, 100, 1.0, seed, {})
    assert cache._bytes <= cache.max_bytes and len(cache._runs) == 3
    cache.run(sim, 100, 1.0, 4, {})  # the newest is kept ...
    assert sim.calls == 5
    cache.run(sim, 100, 1.0, 0, {})  # ... the oldest went first
    assert sim.calls == 6
    clone = pickle.loads(pickle.dumps(cache))
    assert clone.max_bytes == cache.max_bytes and not clone._runs


def test_the_halves_of_a_split_reuse_the_whole_records_runs():
    mg = MackeyGlass()
    real = mg.simulate(4000, random_state=5)
    problem = GapProblem(real, mg, n_sims=2, search_length=1000, random_state=0,
                         scan_dips=False)
    first, second = problem.split()
    assert first.run_cache is problem.run_cache is second.run_cache
    chain = [(get_effect("dynamical_noise"), {"dynamical_noise": 0.002})]
    whole = problem.ensemble(chain, "fast")
    misses = problem.run_cache.misses
    half = first.ensemble(chain, "fast")  # same seeds, same length: no new simulation
    assert problem.run_cache.misses == misses and problem.run_cache.hits >= len(half)
    assert all(np.array_equal(a, b) for a, b in zip(whole, half))
