"""Lyapunov spectra of delay maps: the tangent QR engine and data-driven spectra."""

import numpy as np
import pytest
from sklearn.pipeline import make_pipeline

from skdelay._embedding import TwoWindowEmbedding, required_lags
from skdelay._local_linear import LocalLinearDelayMap
from skdelay._tangent import exponents_from_logs, tangent_qr
from skdelay._windows import lagged_windows
from skdelay.dynamics import (
    LyapunovSpectrum,
    dimension_density,
    iterate,
    kaplan_yorke_dimension,
    ks_entropy,
    lyapunov_spectrum,
    rescale_spectrum,
)


def _companion(coef, lags, dim):
    jac = np.zeros((dim, dim))
    jac[1:, :-1] = np.eye(dim - 1)
    for c, lag in zip(coef, lags):
        jac[0, lag] += c
    return jac


def _exact_linear(a, c, tau):
    # s_{n+1} = a s_n + c s_{n+1-tau}: state dimension tau, exponents = log|eig|
    eig = np.linalg.eigvals(_companion([a, c], [0, tau - 1], tau))
    return np.sort(np.log(np.abs(eig)))[::-1]


def _fit(x, m, tau, k, **kw):
    X, y = lagged_windows(x, required_lags(m, tau))
    model = make_pipeline(TwoWindowEmbedding(m=m, tau=tau), LocalLinearDelayMap(n_neighbors=k, **kw))
    return model.fit(X, y)


def _mackey_glass(tau, n, noise=0.005, seed=0):
    from skdelay.systems import MackeyGlass

    x = MackeyGlass(tau=float(tau)).simulate(n, random_state=seed)
    return x + noise * x.std() * np.random.default_rng(seed + 1).standard_normal(n)


# --- tangent engine -------------------------------------------------------------------------

@pytest.mark.parametrize("tau, a, c", [(20, 0.5, -0.9), (7, 1.2, -0.5), (30, 0.3, 0.75)])
def test_constant_linear_delay_map_gives_companion_eigenvalues(tau, a, c):
    jac = np.tile([a, c], (30_000, 1))
    logs, ends = tangent_qr(jac, [0, tau - 1], tau, tau, random_state=0)
    lam, spread, n_used = exponents_from_logs(logs, ends, n_transient=3000)
    assert n_used >= 26_000
    np.testing.assert_allclose(np.sort(lam)[::-1], _exact_linear(a, c, tau), atol=5e-4)
    assert np.all(spread < 5e-3)


def test_random_jacobians_match_dense_qr_reference():
    rng = np.random.default_rng(1)
    dim, n = 12, 2000
    lags = np.array([0, 1, 2, 9, 10, 11])
    jac = rng.normal(0.0, 2.0, (n, lags.size))  # strongly expanding: early QRs kick in
    logs, ends = tangent_qr(jac, lags, dim, 5, interval=6, random_state=0)
    assert np.all(np.diff(ends) <= 6)
    q = np.linalg.qr(rng.normal(size=(dim, 5)))[0]
    total = np.zeros(5)
    for t in range(n):
        q, r = np.linalg.qr(_companion(jac[t], lags, dim) @ q)
        total += np.log(np.abs(np.diag(r)))
    # same Jacobians, different initial vectors: equal up to the O(1/n) transient
    np.testing.assert_allclose(logs.sum(0) / n, total / n, atol=0.02)


def test_tangent_engine_bad_arguments():
    with pytest.raises(ValueError, match="n_exponents"):
        tangent_qr(np.ones((5, 2)), [0, 3], 4, 5)
    with pytest.raises(ValueError, match="lags"):
        tangent_qr(np.ones((5, 2)), [0, 4], 4, 2)


# --- data-driven spectra ----------------------------------------------------------------------

def test_fitted_linear_delay_process_recovers_companion_spectrum():
    # a noise-driven linear delay process; the local linear model recovers (a, c) and its
    # spectrum is the companion one (m = 1: features s_n, s_{n+1-tau})
    a, c, tau, n = 0.55, -0.6, 12, 20_000
    rng = np.random.default_rng(0)
    s = np.zeros(n)
    for t in range(tau, n - 1):
        s[t + 1] = a * s[t] + c * s[t + 1 - tau] + rng.standard_normal()
    model = _fit(s, 1, tau, 200, ridge=1e-6)
    spec = lyapunov_spectrum(model, s, sample_dt=0.5)
    assert isinstance(spec, LyapunovSpectrum)
    assert len(spec) == tau == required_lags(1, tau)
    assert spec.extra["exclude_self"]
    np.testing.assert_allclose(spec.per_step, _exact_linear(a, c, tau), atol=0.02)
    np.testing.assert_allclose(spec.exponents, spec.per_step / 0.5)


@pytest.mark.parametrize(
    "tau, lam1, d_ky, n_pos",
    # reference: Farmer (1982) / exact spectra of skdelay.systems.MackeyGlass
    [(17, 0.0052, 2.13, 1), (23, 0.0093, 2.82, 1), (30, 0.0072, 3.55, 2)],
)
def test_mackey_glass_spectrum_from_noisy_data(tau, lam1, d_ky, n_pos):
    # 3e4 samples (sample_dt = 1), 0.5 % measurement noise; the full-size (1e5) check of
    # tau = 17, 23, 30, 100 is benchmarks/lyapunov.py
    x = _mackey_glass(tau, 30_000)
    model = _fit(x, 3, tau, 30)
    spec = lyapunov_spectrum(model, x, n_exponents=10, flow=True)
    assert spec.n_positive == n_pos
    assert abs(spec.exponents[0] - lam1) < 0.2 * lam1
    assert abs(spec.kaplan_yorke_dimension - d_ky) < 0.1 * d_ky
    assert abs(spec.extra["zero_exponent"]) < 0.15 * lam1
    assert np.all(spec.spread[:3] < 0.15 * lam1)


def test_hyperchaotic_mackey_glass_tau100():
    # exact (skdelay.systems, benchmarks/lyapunov.py): 4 positive besides the zero,
    # D_KY 10.16, h_KS 0.0098 per time unit; 3e4 noisy samples here, 1e5 in the benchmark
    x = _mackey_glass(100, 30_000)
    spec = lyapunov_spectrum(_fit(x, 3, 100, 30), x, n_exponents=20, flow=True)
    assert abs(spec.n_positive - 4) <= 1
    assert abs(spec.kaplan_yorke_dimension - 10.16) < 0.15 * 10.16
    assert abs(spec.ks_entropy - 0.0098) < 0.2 * 0.0098


def test_spectrum_along_model_run_and_subset():
    from skdelay.dynamics import iterate

    x = _mackey_glass(17, 20_000, noise=0.0)
    model = _fit(x, 2, 17, 20)
    run = iterate(model, x[:200], 15_000)
    along_run = lyapunov_spectrum(model, run, n_exponents=4)
    assert not along_run.extra["exclude_self"]
    along_data = lyapunov_spectrum(model, x, n_exponents=4, n_steps=15_000)
    assert along_data.n_steps < 15_000
    assert abs(along_run.exponents[0] - along_data.exponents[0]) < 0.0015
    # flow=True never zeroes a positive exponent when the zero is beyond n_exponents
    first = lyapunov_spectrum(model, x, n_exponents=1, flow=True)
    assert first.extra["zero_exponent"] is None and first.exponents[0] > 0.002


def test_spectrum_errors():
    x = _mackey_glass(17, 3000, noise=0.0)
    model = _fit(x, 2, 17, 20)
    dim = required_lags(2, 17)
    with pytest.raises(ValueError, match=f"exceeds the state dimension {dim}"):
        lyapunov_spectrum(model, x, n_exponents=dim + 1)
    with pytest.raises(ValueError, match="at least"):
        lyapunov_spectrum(model, x[:40])
    with pytest.raises(ValueError, match="order=1"):
        lyapunov_spectrum(_fit(x, 2, 17, 20, order=0), x)
    with pytest.raises(TypeError, match="TwoWindowEmbedding"):
        lyapunov_spectrum(LocalLinearDelayMap().fit(np.ones((5, 2)), np.ones(5)), x)
    with pytest.raises(ValueError, match="exclude_self=True"):
        lyapunov_spectrum(model, x[::-1].copy(), exclude_self=True)


def test_reexported_summaries():
    lam = [0.02, 0.0, -0.05]
    assert kaplan_yorke_dimension(lam) == pytest.approx(2.4)
    assert ks_entropy(lam) == pytest.approx(0.02)
    assert dimension_density(24.0, 400.0) == pytest.approx(0.06)
    np.testing.assert_allclose(rescale_spectrum(lam, 100)[1], [2.0, 0.0, -5.0])


# --- bad input (issue: hardening) --------------------------------------------------------------

@pytest.fixture(scope="module")
def mg_model():
    from skdelay.systems import MackeyGlass

    x = MackeyGlass(tau=17.0).simulate(6000, random_state=0)
    return _fit(x, 2, 17, 20), x


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"qr_interval": 0}, "qr_interval"), ({"qr_interval": -1}, "qr_interval"),
    ({"n_blocks": 0}, "n_blocks"), ({"n_transient": -5}, "n_transient"),
    ({"sample_dt": float("inf")}, "sample_dt"), ({"sample_dt": 0.0}, "sample_dt"),
])
def test_lyapunov_spectrum_rejects_invalid_parameters(mg_model, kwargs, match):
    model, x = mg_model
    with pytest.raises(ValueError, match=match):
        lyapunov_spectrum(model, x, n_exponents=2, **kwargs)


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"escape_distance": float("nan")}, "escape_distance"), ({"escape_distance": 0}, "escape"),
    ({"noise": -1.0}, "noise"), ({"range_margin": float("inf")}, "range_margin"),
])
def test_iterate_rejects_invalid_parameters(mg_model, kwargs, match):
    model, x = mg_model
    with pytest.raises(ValueError, match=match):
        iterate(model, x[:100], 10, **kwargs)


def test_spectrum_along_a_foreign_series_warns(mg_model):
    from skdelay.dynamics import OffSupportWarning

    model, x = mg_model
    with pytest.warns(OffSupportWarning, match="outside the support"):
        lyapunov_spectrum(model, x + 3 * x.std(), n_exponents=2)


@pytest.mark.parametrize("scale", [1e-200, 1e200])
def test_runs_and_spectra_do_not_depend_on_scale(scale):
    from skdelay.systems import MackeyGlass

    x = MackeyGlass(tau=17.0).simulate(6000, random_state=0)
    ref, big = _fit(x, 2, 17, 20), _fit(x * scale, 2, 17, 20)
    np.testing.assert_allclose(iterate(big, x[:100] * scale, 500) / scale,
                               iterate(ref, x[:100], 500), rtol=1e-9)
    np.testing.assert_allclose(lyapunov_spectrum(big, x * scale, n_exponents=3).exponents,
                               lyapunov_spectrum(ref, x, n_exponents=3).exponents, rtol=1e-9)
