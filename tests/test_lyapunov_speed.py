"""The compiled Jacobian loop of lyapunov_spectrum, chunked free runs and progress bars.

The fast paths must give the answers of the reference paths they replaced, computed here
at test time: ``LocalLinearDelayMap.local_maps`` (cKDTree + batched fits) for the
Jacobians, and one uninterrupted compiled call for a free run.
"""

import numpy as np
import pytest
from sklearn.pipeline import make_pipeline

import skdelay._iterate as iterate_module
from skdelay._embedding import TwoWindowEmbedding, required_lags
from skdelay._iterate import progress_bars
from skdelay._local_linear import LocalLinearDelayMap
from skdelay._lyapunov import local_gradients, thread_count
from skdelay._model import resolve_model, self_query_index
from skdelay._tangent import exponents_from_logs, tangent_qr
from skdelay._windows import lagged_windows
from skdelay.dynamics import iterate, lyapunov_spectrum


def _fit(x, m, tau, k, **kw):
    X, y = lagged_windows(x, required_lags(m, tau))
    return make_pipeline(TwoWindowEmbedding(m=m, tau=tau),
                         LocalLinearDelayMap(n_neighbors=k, **kw)).fit(X, y)


@pytest.fixture(scope="module")
def mg():
    from skdelay.systems import MackeyGlass

    x = MackeyGlass(tau=30.0).simulate(12_000, random_state=0)
    # unquantised noise: no distance ties, so both searches find the same neighbours
    return x + 0.005 * x.std() * np.random.default_rng(1).standard_normal(x.size)


@pytest.mark.parametrize("theiler, self_query, n_jobs", [
    (0, False, 1), (3, True, 1), (3, True, 2), (0, True, -1)])
def test_compiled_gradients_equal_local_maps(mg, theiler, self_query, n_jobs):
    model = _fit(mg, 3, 30, 25, ridge=1e-2, theiler_window=theiler)
    mdl = resolve_model(model)
    X, _ = lagged_windows(mg, mdl.state_dim())
    V = np.ascontiguousarray(X[:, mdl.lags()])
    qidx = self_query_index(mdl.regressor, V) if self_query else None
    ref, _ = mdl.regressor.local_maps(V, query_index=qidx)
    got = local_gradients(mdl.regressor, V, qidx, n_jobs=n_jobs)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-10)


def test_radius_models_take_the_reference_path(mg):
    model = _fit(mg[:4000], 2, 30, 10, radius=0.05)
    mdl = resolve_model(model)
    X, _ = lagged_windows(mg[:4000], mdl.state_dim())
    V = np.ascontiguousarray(X[:, mdl.lags()])
    np.testing.assert_array_equal(local_gradients(mdl.regressor, V),
                                  mdl.regressor.local_maps(V)[0])


def test_spectrum_equals_reference_pipeline(mg):
    """lyapunov_spectrum = local_maps Jacobians + the tangent QR, computed here."""
    model = _fit(mg, 3, 30, 25, ridge=1e-2, theiler_window=2)
    mdl = resolve_model(model)
    X, _ = lagged_windows(mg, mdl.state_dim())
    V = np.ascontiguousarray(X[:, mdl.lags()])
    jac, _ = mdl.regressor.local_maps(V, query_index=self_query_index(mdl.regressor, V))
    dim = mdl.state_dim()
    logs, ends = tangent_qr(jac, mdl.lags(), dim, 8, interval=max(1, dim // 2),
                            random_state=3)
    lam, spread, _ = exponents_from_logs(logs, ends, n_transient=min(max(2 * dim, 1000),
                                                                     jac.shape[0] // 5))
    spec = lyapunov_spectrum(model, mg, n_exponents=8, random_state=3, n_jobs=2)
    np.testing.assert_allclose(spec.exponents, lam, rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(spec.spread, spread, rtol=1e-6, atol=1e-12)
    assert spec.exponents[0] > 0 > spec.exponents[-1]  # chaotic: a real spectrum was compared


def test_thread_count_follows_joblib_convention():
    import os

    cpus = os.cpu_count() or 1
    assert thread_count(None) == 1
    assert thread_count(1) == 1
    assert thread_count(-1) == cpus
    assert thread_count(10_000) == cpus
    assert thread_count(-cpus - 5) == 1


def test_chunked_free_run_equals_one_call(mg, monkeypatch):
    model = _fit(mg, 3, 30, 20)
    whole = iterate(model, mg[:200], 3000, noise=1e-3, random_state=4)
    monkeypatch.setattr(iterate_module, "RUN_CHUNK", 7)
    chunked = iterate(model, mg[:200], 3000, noise=1e-3, random_state=4)
    np.testing.assert_array_equal(chunked, whole)
    assert not whole.escaped


def test_chunked_free_run_keeps_the_escape_step(mg, monkeypatch):
    model = _fit(mg, 2, 30, 10)
    far = np.full(200, mg.max() + 3 * mg.std())
    whole = iterate(model, far, 500, on_escape="ignore")
    monkeypatch.setattr(iterate_module, "RUN_CHUNK", 3)
    chunked = iterate(model, far, 500, on_escape="ignore")
    assert whole.escaped and chunked.escaped
    assert chunked.escape_step == whole.escape_step
    np.testing.assert_array_equal(chunked, whole)


def test_progress_bars_only_when_asked(mg, capsys, monkeypatch):
    model = _fit(mg[:5000], 2, 30, 10)
    iterate(model, mg[:100], 500)
    lyapunov_spectrum(model, mg[:5000], n_exponents=2)
    assert capsys.readouterr().err == ""  # off by default (tests, the API)
    lyapunov_spectrum(model, mg[:5000], n_exponents=2, progress=True)
    assert "Jacobians" in capsys.readouterr().err
    timings = {}
    monkeypatch.setattr(iterate_module, "FREE_RUN_BAR_DELAY", 0.0)  # a run this short too
    with progress_bars(enabled=True, timings=timings):
        iterate(model, mg[:100], 500)
        lyapunov_spectrum(model, mg[:5000], n_exponents=2)
    err = capsys.readouterr().err
    assert "free run" in err and "Jacobians" in err
    assert set(timings) == {"free_runs", "spectra"}
    assert all(v > 0 for v in timings.values())
    with progress_bars(enabled=False, timings=timings):
        iterate(model, mg[:100], 500)
    assert capsys.readouterr().err == ""  # quiet, but still timed


def test_rotated_index_finds_the_exact_neighbours():
    from scipy.spatial import cKDTree

    from skdelay._lyapunov import RotatedIndex

    rng = np.random.default_rng(5)
    base = rng.standard_normal((3000, 2))
    data = np.column_stack([base, base @ [[1.0, 0.5], [0.2, 1.0]] + 1e-3 * rng.standard_normal(
        (3000, 2))])  # strongly correlated columns, like delay vectors
    q = data[:200] + 0.01 * rng.standard_normal((200, 4))
    _, ref = cKDTree(data).query(q, k=15)
    np.testing.assert_array_equal(np.sort(RotatedIndex(data).query(q, 15), axis=1),
                                  np.sort(ref, axis=1))
    one = RotatedIndex(data[:1])  # degenerate database: no axes, still a search
    assert one.query(q[:3], 1).tolist() == [[0], [0], [0]]


def test_covering_spectrum_computes_the_jacobians_once(mg, monkeypatch):
    import skdelay._lyapunov as lyap

    model = _fit(mg, 3, 30, 25, ridge=1e-2)
    calls = []
    original = lyap.local_gradients
    monkeypatch.setattr(lyap, "local_gradients",
                        lambda *a, **kw: calls.append(1) or original(*a, **kw))
    spec = lyap.covering_spectrum(model, mg, n_exponents=1, max_doublings=2)
    assert len(spec) == 4 and len(calls) == 1  # doubled twice, Jacobians once
    ref = lyapunov_spectrum(model, mg, n_exponents=4)
    np.testing.assert_array_equal(spec.exponents, ref.exponents)
    assert spec.extra["ky_closed"] == (spec.kaplan_yorke_dimension < 4)
