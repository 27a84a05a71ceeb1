"""Generate the figures of the example pages (docs/examples/*.rst).

Each ``example_*`` function is shown verbatim on its page (``literalinclude
:pyobject:``) and returns the matplotlib figure saved as
``docs/_static/figures/<name>.png``.  Sizes are chosen so that everything
runs in a few minutes on two cores.

Usage::

    python docs/make_figures.py                 # all figures
    python docs/make_figures.py delay_scan gap  # some of them
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

FIGURES = Path(__file__).resolve().parent / "_static" / "figures"


def example_delay_scan():
    """Forecast-error dips locate the delay of the laser data (tau0 = 150)."""
    import matplotlib.pyplot as plt

    from skdelay import forecast_error_curve, locate_dips
    from skdelay.datasets import load_laser
    from skdelay.plotting import plot_forecast_error

    laser = load_laser(delay=150, n_samples=40_000)
    err = forecast_error_curve(laser.series, m=(2, 3, 4, 5), tau=range(125, 176),
                               n_queries=1500, random_state=0, n_jobs=-1)
    dips = locate_dips(err)                        # centre and half-width per m
    fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    plot_forecast_error(err, logy=True, ax=ax)
    ax.axvline(laser.delay_samples, color="k", ls=":", label="true delay")
    ax.set_title("delay per m: " + ", ".join(
        f"{m}: {row.delay:.1f}+-{row.half_width:.1f}" for m, row in dips.iterrows()), fontsize=9)
    return fig


def example_lyapunov_spectrum():
    """Lyapunov spectrum of a local linear model against the exact spectrum (Mackey-Glass)."""
    import matplotlib.pyplot as plt
    from sklearn.pipeline import make_pipeline

    from skdelay import LocalLinearDelayMap, TwoWindowEmbedding, lagged_windows, required_lags
    from skdelay.dynamics import lyapunov_spectrum
    from skdelay.plotting import plot_lyapunov_spectrum
    from skdelay.systems import MackeyGlass

    mg = MackeyGlass(tau=30.0)
    x = mg.simulate(40_000, sample_dt=1.0, random_state=0)
    m, tau = 3, 30
    X, y = lagged_windows(x, n_lags=required_lags(m, tau))
    model = make_pipeline(TwoWindowEmbedding(m=m, tau=tau),
                          LocalLinearDelayMap(n_neighbors=28)).fit(X, y)
    spec = lyapunov_spectrum(model, x, n_exponents=12, sample_dt=1.0)
    exact = mg.lyapunov_spectrum(12, random_state=0)
    fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    plot_lyapunov_spectrum({"model (data)": spec, "exact (equations)": exact}, ax=ax)
    ax.set_title(f"D_KY: model {spec.kaplan_yorke_dimension:.2f}, "
                 f"exact {exact.kaplan_yorke_dimension:.2f}")
    return fig


def example_model_validation():
    """Free runs of models with m = 1..3 against the data: histograms and power spectra."""
    import matplotlib.pyplot as plt
    import numpy as np
    from sklearn.pipeline import make_pipeline

    from skdelay import LocalLinearDelayMap, TwoWindowEmbedding, lagged_windows, required_lags
    from skdelay.dynamics import iterate
    from skdelay.plotting import plot_histograms, plot_power_spectra
    from skdelay.systems import MackeyGlass

    x = MackeyGlass(tau=30.0).simulate(30_000, random_state=1)
    runs = {"data": x}
    for m in (1, 2, 3):
        X, y = lagged_windows(x, n_lags=required_lags(m, 30))
        model = make_pipeline(TwoWindowEmbedding(m=m, tau=30),
                              LocalLinearDelayMap(n_neighbors=4 * (2 * m + 1))).fit(X, y)
        run = iterate(model, x[:200], 20_500, on_escape="ignore")[500:]
        if run.size > 1000 and np.ptp(run) > 0:
            runs[f"model m = {m}"] = run
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8), layout="constrained")
    plot_histograms(runs, bins=50, ax=ax1)
    plot_power_spectra(runs, ax=ax2)
    return fig


def example_transplant():
    """A model fitted at delay 40 iterated at delay 30, against data recorded at delay 30."""
    import matplotlib.pyplot as plt
    from sklearn.pipeline import make_pipeline

    from skdelay import LocalLinearDelayMap, TwoWindowEmbedding, lagged_windows, required_lags
    from skdelay.dynamics import iterate
    from skdelay.plotting import plot_histograms, plot_power_spectra
    from skdelay.systems import MackeyGlass

    mg = MackeyGlass()
    x40 = mg.simulate(40_000, random_state=2, tau=40.0)   # the data base (delay 40)
    x30 = mg.simulate(20_000, random_state=3, tau=30.0)   # the truth at delay 30
    m = 3
    X, y = lagged_windows(x40, n_lags=required_lags(m, 40))
    model = make_pipeline(TwoWindowEmbedding(m=m, tau=40),
                          LocalLinearDelayMap(n_neighbors=28)).fit(X, y)
    run = iterate(model, x40[:200], 20_500, tau=30, on_escape="ignore")[500:]
    series = {"data, delay 30": x30, "model from delay 40, run at 30": run}
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8), layout="constrained")
    plot_histograms(series, bins=50, ax=ax1)
    plot_power_spectra(series, ax=ax2)
    return fig


def example_rescaled_collapse():
    """Exact spectra of Mackey-Glass at three delays collapse as lambda_i tau vs i / tau."""
    import matplotlib.pyplot as plt

    from skdelay.plotting import plot_lyapunov_spectrum
    from skdelay.systems import MackeyGlass

    spectra, taus = {}, {}
    for tau in (50.0, 100.0, 200.0):
        n = int(tau // 5)                      # same range of i / tau for every delay
        spec = MackeyGlass(tau=tau).lyapunov_spectrum(n, duration=3000.0, dt=0.1,
                                                      random_state=0)
        spectra[f"tau = {tau:g}"], taus[f"tau = {tau:g}"] = spec, tau
    fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    plot_lyapunov_spectrum(spectra, tau=taus, rescaled=True, ax=ax)
    return fig


def example_space_time():
    """Space-time representation of the laser data at delay 400."""
    import numpy as np

    from skdelay.datasets import load_laser
    from skdelay.plotting import plot_space_time
    from skdelay.spacetime import best_space_time_period

    laser = load_laser(delay=400, n_samples=40_000)
    period, _ = best_space_time_period(laser.series, np.arange(398, 420, 0.5))
    fig = plot_space_time(laser.series, period)
    fig.axes[0].set_title(f"tau_1 = {period:g} samples (delay 400)")
    return fig


def example_gap():
    """Which effect explains the gap between a 'recording' and its simulator?"""
    import numpy as np

    from skdelay.gap import diagnose_gap
    from skdelay.systems import MackeyGlass

    mg = MackeyGlass()
    t = np.arange(8000)
    real = mg.simulate(8000, random_state=1) + 0.1 * np.sin(2 * np.pi * 0.2 * t)  # pickup
    report = diagnose_gap(real, mg, random_state=0,
                          effects=["periodic_interference", "measurement_noise",
                                   "quantization", "dynamical_noise"])
    print(report.summary())
    return report.plot()


EXAMPLES = {name[len("example_"):]: fn for name, fn in globals().items()
            if name.startswith("example_")}


def main(names=None, *, only_missing=False):
    """Build the figures ``names`` (default: all) into ``docs/_static/figures``."""
    import matplotlib.pyplot as plt

    FIGURES.mkdir(parents=True, exist_ok=True)
    for name in names or EXAMPLES:
        target = FIGURES / f"{name}.png"
        if only_missing and target.exists():
            continue
        start = time.perf_counter()
        fig = EXAMPLES[name]()
        tmp = target.with_suffix(".tmp.png")
        fig.savefig(tmp, dpi=90)
        os.replace(tmp, target)
        plt.close(fig)
        print(f"{name}: {time.perf_counter() - start:.1f} s -> {target}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or None)
