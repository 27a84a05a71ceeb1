"""The compiled candidate lists of the delay scan against a brute-force search."""

import numpy as np
import pytest

from skdelay._scan import candidate_lists


def _brute(s, m, members, t, n_list, theiler):
    lags = np.arange(m)
    d = ((s[members[:, None] - lags] - s[t - lags]) ** 2).sum(axis=1)
    ok = np.ones(members.size, bool) if theiler is None else np.abs(members - t) > theiler
    return np.sort(d[ok])[:n_list]


@pytest.mark.parametrize("m, theiler, workers", [(1, 3, 1), (3, 7, 2), (4, None, 2)])
def test_candidate_lists_are_the_nearest_eligible_members(m, theiler, workers):
    rng = np.random.default_rng(m)
    # a smooth series, so temporal neighbours are among the nearest windows, with
    # 12-bit-like rounding, so many distances tie
    s = np.round(np.sin(np.arange(4000) * 0.07) + 0.3 * rng.normal(size=4000), 2)
    members = np.arange(20, 3800)
    # runs of consecutive times (the seeded searches) and scattered ones
    needed = np.unique(np.r_[np.arange(100, 400), rng.integers(10, 3990, 500)])
    lists, rk2 = candidate_lists(s, m, members, needed, 25, theiler, workers=workers)
    assert lists.shape == (needed.size, 25) and lists.dtype == np.int32
    lags = np.arange(m)
    for i, t in enumerate(needed):
        got = lists[i].astype(np.int64)
        assert np.all(got >= 0) and np.unique(got).size == 25
        assert np.all(np.isin(got, members))
        if theiler is not None:
            assert np.all(np.abs(got - t) > theiler)
        d = np.sort(((s[got[:, None] - lags] - s[t - lags]) ** 2).sum(axis=1))
        ref = _brute(s, m, members, t, 25, theiler)
        np.testing.assert_allclose(d, ref, rtol=1e-12, atol=1e-14)
        assert rk2[i] == pytest.approx(ref[-1], rel=1e-12, abs=1e-14)


def test_candidate_lists_pad_when_too_few_members():
    s = np.sin(np.arange(200) * 0.3)
    members = np.arange(10, 30)
    lists, rk2 = candidate_lists(s, 2, members, np.array([50, 51]), 40, 2)
    assert np.all(lists[:, 20:] == -1) and np.all(lists[:, :20] >= 10)
    assert np.all(np.isinf(rk2))


def test_candidate_lists_report_progress_per_slice_and_stay_exact_at_the_cuts():
    rng = np.random.default_rng(5)
    s = np.round(np.sin(np.arange(32000) * 0.05) + 0.2 * rng.normal(size=32000), 2)
    members = np.arange(10, 31900)
    needed = np.arange(10, 31900)
    calls = []
    lists, _ = candidate_lists(s, 2, members, needed, 12, 4, workers=2,
                               progress=lambda done, total: calls.append((done, total)))
    n = calls[-1][1]
    assert n > 1 and calls == [(i, n) for i in range(1, n + 1)]
    cuts = np.linspace(0, needed.size, n + 1).astype(int)
    rows = np.unique(np.r_[cuts[1:-1] - 1, cuts[1:-1], cuts[1:-1] + 1, 0, needed.size - 1])
    lags = np.arange(2)
    for r in rows:
        t = needed[r]
        got = lists[r].astype(np.int64)
        d = np.sort(((s[got[:, None] - lags] - s[t - lags]) ** 2).sum(axis=1))
        np.testing.assert_allclose(d, _brute(s, 2, members, t, 12, 4), rtol=1e-12, atol=1e-14)
        assert np.all(np.abs(got - t) > 4)
