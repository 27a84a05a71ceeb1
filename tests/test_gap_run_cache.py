"""Simulator runs and indicator profiles are made once per diagnosis: the caches return
the same numbers."""

import pickle

import numpy as np

from skdelay.gap import get_effect
from skdelay.gap._indicators import FeatureCache, profiles
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
    assert cache._bytes <= cache.max_bytes and len(cache) == 3
    cache.run(sim, 100, 1.0, 4, {})  # the newest is kept ...
    assert sim.calls == 5
    cache.run(sim, 100, 1.0, 0, {})  # ... the oldest went first
    assert sim.calls == 6
    clone = pickle.loads(pickle.dumps(cache))
    assert clone.max_bytes == cache.max_bytes and len(clone) == 0


def test_copies_unpickled_in_one_worker_share_their_diagnosis_runs_and_no_other():
    """A task's copy of the cache (unpickled in a joblib worker) joins the worker's store:
    a later task of the same diagnosis finds the runs an earlier one made, as the tasks of
    one process do, while a cache of another diagnosis never sees them; the worker's store
    keeps its byte budget for all of them together."""
    from skdelay import _memo

    sim = CountingSimulator()
    cache, other = RunCache(max_bytes=4 * 8 * 100), RunCache(max_bytes=4 * 8 * 100)
    saved = dict(_memo._JOINED)
    _memo._JOINED.pop(RunCache, None)  # a fresh worker
    try:
        first, second = (pickle.loads(pickle.dumps(cache)) for _ in range(2))
        a = first.run(sim, 100, 1.0, 3, {"gain": 0.5})
        b = second.run(sim, 100, 1.0, 3, {"gain": 0.5})
        assert sim.calls == 1 and np.array_equal(a, b) and a is not b
        assert len(first) == len(second) == 1 and len(cache) == 0  # the owner's stays its own
        stranger = pickle.loads(pickle.dumps(other))
        c = stranger.run(sim, 100, 1.0, 3, {"gain": 0.5})
        assert sim.calls == 2 and np.array_equal(a, c) and len(stranger) == 1
        for seed in range(10, 16):
            stranger.run(sim, 100, 1.0, seed, {})
        host = _memo._JOINED[RunCache]
        assert host._bytes <= host.max_bytes and len(host._items) == 4
        assert len(first) == 0  # the oldest went first, whichever diagnosis made them
    finally:
        _memo._JOINED.clear()
        _memo._JOINED.update(saved)


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


def test_a_repeated_profile_is_served_from_the_feature_cache_unchanged(monkeypatch):
    """Same run, same indicator: the profile is computed once and the numbers are those
    computed without a cache; a run that differs in one sample is a new key; a paired
    indicator's key includes the run it is read against."""
    mg = MackeyGlass()
    real = mg.simulate(3000, random_state=7)
    problem = GapProblem(real, mg, n_sims=3, search_length=1000, random_state=0,
                         scan_dips=False)
    indicators = problem.indicators
    assert any(getattr(ind, "paired", False) for ind in indicators.values())
    runs = [mg.simulate(3000, random_state=s) for s in (21, 22)]
    plain = profiles(indicators, runs)
    calls = []
    for ind in indicators.values():
        real_profile = ind.profile

        def counted(z, *args, _f=real_profile, **kw):
            calls.append(1)
            return _f(z, *args, **kw)

        monkeypatch.setattr(ind, "profile", counted)
    cache = FeatureCache()
    first = profiles(indicators, runs, cache=cache)
    n_first = len(calls)
    assert n_first == 2 * len(indicators) and cache.hits == 0
    again = profiles(indicators, [r.copy() for r in runs], cache=cache)
    assert len(calls) == n_first and cache.hits == n_first
    for name, (f, b) in plain.items():
        for got in (first, again):
            assert np.array_equal(got[name][0], f)
            assert (b is None) == (got[name][1] is None)
    # the stacked features are the caller's to change; the stored ones are not changed
    again[next(iter(again))][0][:] = np.nan
    third = profiles(indicators, runs, cache=cache)
    assert all(np.array_equal(third[k][0], plain[k][0]) for k in plain)
    # one changed sample: every indicator of that run anew; the paired one of the run read
    # against it too (its database changed)
    moved = [runs[0].copy(), runs[1]]
    moved[0][100] += 1e-9
    before = len(calls)
    profiles(indicators, moved, cache=cache)
    n_paired = sum(getattr(ind, "paired", False) for ind in indicators.values())
    assert len(calls) - before == len(indicators) + n_paired
    assert len(pickle.loads(pickle.dumps(cache))) == 0


def test_reseeded_twins_share_the_feature_cache_and_the_halves_do_not():
    mg = MackeyGlass()
    problem = GapProblem(mg.simulate(4000, random_state=5), mg, n_sims=2,
                         search_length=1000, random_state=0, scan_dips=False)
    twin = problem.reseeded(3)
    assert twin.indicators is problem.indicators and twin.feature_cache is problem.feature_cache
    first, second = problem.split()  # their indicators are set up on the halves
    assert first.feature_cache is not problem.feature_cache
    assert first.feature_cache is not second.feature_cache


def test_the_gaps_forecast_error_curve_is_the_plain_trees_with_and_without_ties(monkeypatch):
    """``fe_curve`` takes the faster tree search only where it gives the plain tree's bits
    (no repeated values) and the plain tree where distances tie (a quantized run)."""
    import skdelay._selection as selection
    from skdelay.gap._indicators import fe_curve, zscore

    x = MackeyGlass().simulate(4000, random_state=9)
    x = x + 0.02 * x.std() * np.random.default_rng(1).standard_normal(x.size)
    quantized = get_effect("quantization").apply(x, {"step": 0.05})
    assert np.unique(quantized).size < quantized.size
    taus = [2, 9, 16, 17, 18, 30]
    searches = []
    real_curve = selection.forecast_error_curve

    def spy(*args, search="auto", **kw):
        searches.append(search)
        return real_curve(*args, search=search, **kw)

    monkeypatch.setattr(selection, "forecast_error_curve", spy)
    for series, expected in ((x, "tree"), (quantized, "exact")):
        sigma, se = fe_curve(series, taus, with_se=True)
        assert searches[-1] == expected
        plain = real_curve(zscore(series), m=(2,), tau=taus, n_queries=400, n_neighbors=20,
                           search="exact", random_state=0, refine=True,
                           centre_error="redraws")  # the refinement fe_curve asks for
        assert np.array_equal(sigma, plain.iloc[:, 0].to_numpy())
        assert np.array_equal(se, plain.attrs["se"].iloc[:, 0].to_numpy())
