"""Figures: each function returns a Figure, draws into a given ax, and says how to get matplotlib."""

import sys

import numpy as np
import pandas as pd
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.figure import Figure

from skdelay import plotting
from skdelay._testing_maps import henon
from skdelay.classic import correlation_dimension, maximal_lyapunov_exponent


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def test_forecast_error_and_shared_axes():
    curve = pd.DataFrame({2: [0.3, 0.1, 0.3], 3: [0.2, 0.05, 0.2]},
                         index=pd.Index([16, 17, 18], name="tau"))
    fig = plotting.plot_forecast_error(curve, logy=True)
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    np.testing.assert_array_equal(ax.lines[1].get_ydata(), [0.2, 0.05, 0.2])
    assert plotting.plot_forecast_error(curve, ax=ax) is fig
    assert len(ax.lines) == 4


def test_spectra_and_histograms():
    rng = np.random.default_rng(0)
    data = {"data": rng.normal(size=4000), "m = 3": rng.normal(size=4000)}
    fig = plotting.plot_power_spectra(data, sample_dt=0.5, nperseg=256)
    line = fig.axes[0].lines[0]
    assert line.get_xdata().max() == pytest.approx(1.0)  # Nyquist of sample_dt=0.5
    fig = plotting.plot_histograms(data, bins=25)
    assert len(fig.axes[0].lines) == 2
    assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == ["data", "m = 3"]


def test_lyapunov_spectra_raw_and_rescaled():
    spectra = {"tau=150": [1.4, 0.8, 0.1, -0.5], "tau=400": [0.55, 0.4, 0.2, 0.05]}
    fig = plotting.plot_lyapunov_spectrum(spectra, tau={"tau=150": 0.15, "tau=400": 0.4},
                                          rescaled=True)
    line = fig.axes[0].lines[0]
    np.testing.assert_allclose(line.get_xdata(), np.arange(1, 5) / 0.15)
    np.testing.assert_allclose(line.get_ydata(), np.array([1.4, 0.8, 0.1, -0.5]) * 0.15)
    fig = plotting.plot_lyapunov_spectrum([0.1, -0.2, 0.3])
    np.testing.assert_allclose(fig.axes[0].lines[0].get_ydata(), [0.3, 0.1, -0.2])
    with pytest.raises(ValueError, match="needs the delay tau"):
        plotting.plot_lyapunov_spectrum(spectra, rescaled=True)


def test_space_time_image():
    fig = plotting.plot_space_time(np.sin(np.arange(2000) / 7.0), period=44.0)
    img = fig.axes[0].images[0]
    assert img.get_array().shape == (45, 44)
    with pytest.raises(ValueError, match="period"):
        plotting.plot_space_time(np.arange(100.0))


def test_classic_result_plots():
    s = henon(3000, random_state=0)
    res = correlation_dimension(s, dims=[1, 2, 3], random_state=0)
    fig = plotting.plot_correlation_dimension(res)
    assert len(fig.axes[0].lines) == 4  # three dims + D2 line
    lyap = maximal_lyapunov_exponent(s, dim=2, max_steps=10, fit_range=(0, 4), random_state=0)
    fig = plotting.plot_divergence(lyap)
    np.testing.assert_allclose(fig.axes[0].lines[0].get_ydata(), lyap.divergence.to_numpy())


def test_missing_matplotlib_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib.pyplot", None)
    with pytest.raises(ImportError, match=r"pip install skdelay\[plot\]"):
        plotting.plot_histograms(np.arange(10.0))


@pytest.mark.parametrize("call, error, needle", [
    (lambda p: p.plot_forecast_error(np.ones(5)), TypeError, "must be a pandas DataFrame"),
    (lambda p: p.plot_forecast_error(pd.DataFrame()), ValueError, "has no columns"),
    (lambda p: p.plot_correlation_dimension(np.ones(5)), TypeError,
     "must be a CorrelationDimension"),
    (lambda p: p.plot_divergence("S"), TypeError, "must be a MaximalLyapunovExponent"),
    (lambda p: p.plot_lyapunov_spectrum(None), ValueError, "finite exponents"),
    (lambda p: p.plot_lyapunov_spectrum({"a": [0.1, np.nan]}), ValueError, "finite exponents"),
])
def test_wrong_inputs_are_refused_before_a_figure_is_made(call, error, needle):
    # these raised AttributeError ("'ndarray' object has no attribute 'local_slopes'") or
    # drew a NaN line into a new, orphaned figure
    before = len(plt.get_fignums())
    with pytest.raises(error, match=needle):
        call(plotting)
    assert len(plt.get_fignums()) == before
