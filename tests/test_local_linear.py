import numpy as np
import pytest
from scipy.spatial import cKDTree

from skdelay._local_linear import LocalLinearDelayMap
from skdelay._neighbours import fit_from_series, fit_gathered, tree_neighbours


@pytest.fixture
def smooth_data():
    rng = np.random.default_rng(0)
    V = rng.uniform(-1, 1, size=(800, 3))
    y = np.sin(2 * V[:, 0]) + V[:, 1] * V[:, 2]
    return V, y


def test_affine_function_is_reproduced_exactly():
    rng = np.random.default_rng(1)
    V = rng.normal(size=(300, 4))
    y = 0.3 + V @ np.array([1.0, -2.0, 0.5, 3.0])
    model = LocalLinearDelayMap(n_neighbors=12, ridge=1e-12).fit(V, y)
    Vq = rng.normal(size=(50, 4))
    np.testing.assert_allclose(model.predict(Vq), 0.3 + Vq @ [1.0, -2.0, 0.5, 3.0], atol=1e-7)
    A, b = model.local_maps(Vq)
    np.testing.assert_allclose(A, np.tile([1.0, -2.0, 0.5, 3.0], (50, 1)), atol=1e-7)
    np.testing.assert_allclose(b, 0.3, atol=1e-7)


def test_local_maps_match_predict_and_beat_local_constant(smooth_data):
    V, y = smooth_data
    model = LocalLinearDelayMap(n_neighbors=20).fit(V, y)
    A, b = model.local_maps(V[:100], query_index=np.arange(100))
    pred = model.predict(V[:100], query_index=np.arange(100))
    np.testing.assert_allclose(b + (A * V[:100]).sum(1), pred, atol=1e-10)
    err1 = np.sqrt(np.mean((pred - y[:100]) ** 2))
    const = LocalLinearDelayMap(n_neighbors=20, order=0).fit(V, y)
    err0 = np.sqrt(np.mean((const.predict(V[:100], query_index=np.arange(100)) - y[:100]) ** 2))
    assert err1 < 0.1 and err1 < err0 / 1.5
    A0, _ = const.local_maps(V[:5])
    assert np.all(A0 == 0)


def test_batched_fit_equals_per_point_ridge_solution(smooth_data):
    V, y = smooth_data
    k, ridge = 15, 1e-2
    model = LocalLinearDelayMap(n_neighbors=k, ridge=ridge).fit(V, y)
    Vq = V[:20] + 0.01
    A, b = model.local_maps(Vq)
    _, idx = cKDTree(V).query(Vq, k=k)
    for i in range(20):
        N, t = V[idx[i]], y[idx[i]]
        D = N - N.mean(0)
        G = D.T @ D
        a = np.linalg.solve(G + ridge * np.trace(G) / 3 * np.eye(3), D.T @ (t - t.mean()))
        np.testing.assert_allclose(A[i], a, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(b[i], t.mean() - a @ N.mean(0), rtol=1e-8, atol=1e-10)


def test_local_constant_is_neighbour_mean(smooth_data):
    V, y = smooth_data
    pred = LocalLinearDelayMap(n_neighbors=7, order=0).fit(V, y).predict(V[:30] + 0.02)
    _, idx = cKDTree(V).query(V[:30] + 0.02, k=7)
    np.testing.assert_allclose(pred, y[idx].mean(1), rtol=1e-12)


def test_theiler_exclusion():
    # a trajectory that never returns: temporal neighbours are the nearest points
    t = np.arange(2000) * 0.05
    V = np.column_stack([t, np.sin(t)])
    tree = cKDTree(V)
    q = np.arange(100, 1900, 97)
    for w in (0, 5, 40):
        pos, weight = tree_neighbours(tree, V[q], 10, query_ids=q, theiler_window=w)
        assert weight.all()
        assert np.all(np.abs(pos - q[:, None]) > w)
    pos, _ = tree_neighbours(tree, V[q], 10)
    assert np.all(pos[:, 0] == q)  # without query_index the point itself is used
    y = np.arange(2000.0) ** 2  # local mean - q^2 = mean squared time offset of the neighbours
    model = LocalLinearDelayMap(n_neighbors=5, order=0, theiler_window=3).fit(V, y)
    np.testing.assert_allclose(model.predict(V[q]) - q**2, 2.0)  # offsets 0, +-1, +-2
    model.set_params(n_neighbors=4)
    np.testing.assert_allclose(model.predict(V[q], query_index=q) - q**2, 20.5)  # +-4, +-5


def test_radius_neighbourhoods_with_knn_fallback():
    rng = np.random.default_rng(2)
    V = np.concatenate([rng.normal(0, 0.01, size=(50, 2)), rng.uniform(5, 10, size=(50, 2))])
    y = np.concatenate([np.ones(50), np.zeros(50)])
    tree = cKDTree(V)
    pos, weight = tree_neighbours(tree, np.zeros((1, 2)), 5, radius=0.1)
    assert weight.sum() == 50 and set(pos[weight].tolist()) == set(range(50))
    pos, weight = tree_neighbours(tree, np.full((1, 2), 7.5), 5, radius=0.1)
    assert weight.sum() == 5  # too few inside the radius: the 5 nearest
    model = LocalLinearDelayMap(n_neighbors=5, radius=0.1, order=0).fit(V, y)
    np.testing.assert_allclose(model.predict([[0.0, 0.0], [7.5, 7.5]]), [1.0, 0.0])


def test_degenerate_neighbourhoods_do_not_crash():
    rng = np.random.default_rng(3)
    x = rng.uniform(-1, 1, size=(200, 1))
    V = np.hstack([x, x, x, x])  # duplicated columns (tau = 1 windows)
    y = x[:, 0] ** 2
    pred = LocalLinearDelayMap(n_neighbors=10, ridge=0.0).fit(V, y).predict(V)
    assert np.all(np.isfinite(pred)) and np.abs(pred - y).max() < 0.01
    same = np.ones((30, 3))  # all neighbours coincide: the map is their mean
    model = LocalLinearDelayMap(n_neighbors=30).fit(same, np.arange(30.0))
    A, b = model.local_maps(same[:3])
    np.testing.assert_allclose(b, 14.5)
    assert np.all(A == 0)
    few = LocalLinearDelayMap(n_neighbors=50).fit(rng.normal(size=(4, 6)), np.arange(4.0))
    assert np.all(np.isfinite(few.predict(rng.normal(size=(3, 6)))))
    one = LocalLinearDelayMap().fit([[1.0, 2.0]], [3.0])
    np.testing.assert_allclose(one.predict([[0.0, 0.0]]), [3.0])


def test_local_affine_empty_neighbourhood_uses_fallback():
    Vn = np.zeros((2, 3, 2))
    A, _, pred = fit_gathered(np.zeros((2, 2)), Vn, np.ones((2, 3)),
                              np.array([[0, 0, 0], [1, 1, 0]], float), 1e-3, 1, 7.0)
    np.testing.assert_allclose(pred, [7.0, 1.0])
    assert np.all(A == 0)



def test_weighted_fit_ignores_whatever_unused_slots_hold():
    # the moments are dot products over sqrt(w)-weighted, centred columns: general weights
    # give the weighted least-squares map, and a slot of weight 0 is skipped even when it
    # holds garbage (NaN, inf) from an earlier neighbourhood
    rng = np.random.default_rng(4)
    k, p, ridge = 25, 6, 1e-3
    Vn = rng.normal(size=(1, k, p))
    yn = np.sin(Vn[0] @ rng.normal(size=p))[None] + 0.1 * rng.normal(size=(1, k))
    w = rng.uniform(0.2, 3.0, size=(1, k))
    w[0, [3, 11]] = 0.0
    Vn[0, 3], yn[0, 11], Vn[0, 11, 2] = np.nan, np.inf, -np.inf
    vq = rng.normal(size=(1, p))
    A, b, pred = fit_gathered(vq, Vn, yn, w, ridge, 1, 0.0)
    used = w[0] > 0
    N, t, ww = Vn[0][used], yn[0][used], w[0][used]
    mu, tbar = ww @ N / ww.sum(), ww @ t / ww.sum()
    D = N - mu
    G = D.T @ (ww[:, None] * D)
    a = np.linalg.solve(G + ridge * np.trace(G) / p * np.eye(p), D.T @ (ww * (t - tbar)))
    np.testing.assert_allclose(A[0], a, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(b[0], tbar - a @ mu, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(pred[0], tbar + a @ (vq[0] - mu), rtol=1e-9, atol=1e-12)

def test_n_jobs_and_chunking_do_not_change_results(smooth_data, monkeypatch):
    V, y = smooth_data
    ref = LocalLinearDelayMap(n_neighbors=9).fit(V, y).predict(V, query_index=np.arange(800))
    par = LocalLinearDelayMap(n_neighbors=9, n_jobs=2).fit(V, y)
    np.testing.assert_allclose(par.predict(V, query_index=np.arange(800)), ref, rtol=1e-12)
    import skdelay._neighbours as mod

    monkeypatch.setattr(mod, "CHUNK_VALUES", 50)
    np.testing.assert_allclose(par.predict(V, query_index=np.arange(800)), ref, rtol=1e-12)


@pytest.mark.parametrize(
    ("params", "match"),
    [({"n_neighbors": 0}, "n_neighbors"), ({"order": 2}, "order"), ({"ridge": -1.0}, "ridge"),
     ({"radius": 0.0}, "radius"), ({"theiler_window": -1}, "theiler_window")],
)
def test_bad_parameters(params, match):
    with pytest.raises(ValueError, match=match):
        LocalLinearDelayMap(**params).fit(np.ones((5, 2)) * np.arange(5)[:, None], np.arange(5.0))


def test_bad_query_index(smooth_data):
    V, y = smooth_data
    model = LocalLinearDelayMap().fit(V, y)
    with pytest.raises(ValueError, match="query_index"):
        model.predict(V[:3], query_index=[0, 1])
    with pytest.raises(ValueError, match="query_index"):
        model.predict(V[:2], query_index=[0.5, 1.0])


def test_one_fit_for_estimator_and_series_kernel():
    """The estimator and the scan's series kernel fit the same neighbourhoods identically."""
    rng = np.random.default_rng(5)
    s = np.cumsum(rng.normal(size=3000)) * 0.1 + np.sin(np.arange(3000) / 7.0)
    cols = np.array([0, 1, 9, 10])
    t = np.arange(20, 2990)
    V, y = s[t[:, None] - cols], s[t + 1]
    q = np.arange(100, 2900, 37)
    pos, weight = tree_neighbours(cKDTree(V), V[q], 15, query_ids=q, theiler_window=3)
    pred_series = fit_from_series(s, t[q], t[pos], weight, cols, 1e-3, 1, 0.0)
    A, b, pred = fit_gathered(V[q], V[pos], y[pos], weight.astype(float), 1e-3, 1, 0.0)
    np.testing.assert_allclose(pred_series, pred, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(b + (A * V[q]).sum(1), pred, rtol=1e-9, atol=1e-10)
    model = LocalLinearDelayMap(n_neighbors=15, theiler_window=3).fit(V, y)
    np.testing.assert_allclose(model.predict(V[q], query_index=q), pred, rtol=1e-8, atol=1e-9)


@pytest.mark.parametrize("scale", [1e-300, 1e-160, 1e160, 1e300])
def test_results_do_not_depend_on_scale(smooth_data, scale):
    V, y = smooth_data
    ref = LocalLinearDelayMap(n_neighbors=12).fit(V, y)
    big = LocalLinearDelayMap(n_neighbors=12).fit(V * scale, y * scale)
    np.testing.assert_allclose(big.predict(V[:50] * scale) / scale, ref.predict(V[:50]),
                               rtol=1e-9, atol=1e-12)
    A0, b0 = ref.local_maps(V[:5])
    A1, b1 = big.local_maps(V[:5] * scale)
    np.testing.assert_allclose(A1, A0, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(b1 / scale, b0, rtol=1e-9, atol=1e-12)


def test_offset_beyond_resolution_is_refused():
    V = 1e17 + np.arange(40.0).reshape(20, 2)  # distinct only in the last bits
    with pytest.raises(ValueError, match="last bits"):
        LocalLinearDelayMap(n_neighbors=5).fit(V, np.arange(20.0))


def test_n_jobs_zero_is_refused_at_fit(smooth_data):
    V, y = smooth_data
    with pytest.raises(ValueError, match="n_jobs"):
        LocalLinearDelayMap(n_jobs=0).fit(V, y)
