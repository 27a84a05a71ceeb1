"""The paper's Lyapunov table (Buenner et al. 2000, Tab. 3) on the laser-like example data.

Run: ``python benchmarks/paper_table.py`` (a few minutes on 2 cores; the exact
spectra are the shipped converged ones of :func:`skdelay.datasets.laser_exact_spectrum`,
made by ``benchmarks/exact_spectra.py``).

For each delay (50, 150, 400 microseconds = samples) of
``skdelay.datasets.load_laser`` (1e5 samples, 12-bit, 0.5 % measurement and
0.3 % dynamical noise) an m = 5 two-window model is fitted at the known delay
and its spectrum computed along the data (``flow=True``); beside it the exact
spectrum of the simulator that made the data (``Bunch.system``).  Columns as
in the paper: N (positive exponents), lambda_max and h_KS in 1/ms, D_KY and
D_KY / tau in 1/ms.  The rescaled spectra (lambda_i tau vs i / tau) are saved
to ``benchmarks/out/rescaled_spectra.png``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
from sklearn.pipeline import make_pipeline

from skdelay import LocalLinearDelayMap, TwoWindowEmbedding, lagged_windows, required_lags
from skdelay.datasets import laser_exact_spectrum, load_laser
from skdelay.dynamics import dimension_density, lyapunov_spectrum

OUT = Path(__file__).resolve().parent / "out"
N_EXPONENTS = {50: 40, 150: 80, 400: 160}
EXACT_EXPONENTS = {50: 20, 150: 40, 400: 80}


def n_positive_flow(lam, spread):
    """Exponents above their spread, not counting the flow's zero (closest to 0)."""
    lam = np.array(lam, dtype=float)
    lam[np.argmin(np.abs(lam))] = 0.0
    return int(np.sum(lam > np.maximum(spread, 0.0)))


def summary(lam, spread, delay):
    from skdelay.dynamics import kaplan_yorke_dimension, ks_entropy

    lam = np.asarray(lam)
    d_ky = kaplan_yorke_dimension(lam)
    return {"N": n_positive_flow(lam, spread), "lambda_max": 1e3 * lam[0],
            "D_KY": d_ky, "h_KS": 1e3 * ks_entropy(lam),
            "D_KY/tau": 1e3 * dimension_density(d_ky, delay),
            "closed": d_ky < lam.size}


def exact_spectra(delays):
    """The shipped converged exact spectra (``benchmarks/exact_spectra.py``)."""
    out = {}
    for delay in delays:
        spec = laser_exact_spectrum(delay)
        if spec is None:
            raise SystemExit("no shipped exact spectrum for the laser's parameters: run "
                             "python benchmarks/exact_spectra.py first")
        out[str(delay)] = {"exponents": spec.exponents.tolist(), "spread": spec.spread.tolist()}
    return out


def estimated_spectrum(delay, m, k, ridge, n_samples):
    data = load_laser(delay, n_samples=n_samples)
    x, tau = data.series, int(data.delay_samples)
    t0 = time.perf_counter()
    X, y = lagged_windows(x, required_lags(m, tau))
    model = make_pipeline(TwoWindowEmbedding(m=m, tau=tau),
                          LocalLinearDelayMap(n_neighbors=k, ridge=ridge, n_jobs=2)).fit(X, y)
    spec = lyapunov_spectrum(model, x, n_exponents=min(N_EXPONENTS[delay],
                                                       required_lags(m, tau)),
                             sample_dt=data.sample_dt, flow=True)
    return spec, time.perf_counter() - t0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--m", type=int, default=5)
    parser.add_argument("--k", type=int, default=100, help="neighbours (default 100)")
    parser.add_argument("--ridge", type=float, default=3e-2)
    parser.add_argument("--n-samples", type=int, default=100_000)
    parser.add_argument("--delays", type=int, nargs="+", default=[50, 150, 400])
    args = parser.parse_args()

    exact = exact_spectra(args.delays)
    rows, est_spectra, ex_spectra = [], {}, {}
    for delay in args.delays:
        spec, seconds = estimated_spectrum(delay, args.m, args.k, args.ridge, args.n_samples)
        est = summary(spec.exponents, spec.spread, delay)
        ex = summary(exact[str(delay)]["exponents"], exact[str(delay)]["spread"], delay)
        rows.append({"tau0": delay, **{f"{key}": val for key, val in est.items()},
                     **{f"{key} exact": val for key, val in ex.items()}, "sec": seconds})
        est_spectra[f"model tau={delay}"] = spec.exponents
        ex_spectra[f"exact tau={delay}"] = np.asarray(exact[str(delay)]["exponents"])
    table = pd.DataFrame(rows).set_index("tau0")
    cols = ["N", "N exact", "lambda_max", "lambda_max exact", "D_KY", "D_KY exact",
            "h_KS", "h_KS exact", "D_KY/tau", "D_KY/tau exact", "closed", "closed exact", "sec"]
    with pd.option_context("display.width", 250, "display.max_columns", 30,
                           "display.precision", 3):
        print(f"m={args.m}, k={args.k}, ridge={args.ridge}, N={args.n_samples} samples; "
              "lambda_max, h_KS, D_KY/tau in 1/ms ('closed': enough exponents for D_KY)")
        print(table[cols])
        print("paper (experiment, 1e6 samples): N = 1, 4, 11; lambda_max = 2.5, 1.4, 0.55; "
              "D_KY = 3.4, 10.2, 23.8; h_KS = 2.5, 3.3, 3.0; D_KY/tau = 68, 68, 59")
        for col in ("h_KS", "D_KY/tau"):
            for which in ("", " exact"):
                v = table[col + which]
                print(f"{col + which:>15}: spread over delays {v.std() / v.mean():.0%} of mean")
    plot(est_spectra, ex_spectra, args.delays)


def plot(est_spectra, ex_spectra, delays):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from skdelay.plotting import plot_lyapunov_spectrum

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    for ax, spectra, title in ((axes[0], est_spectra, "two-window models (m=5)"),
                               (axes[1], ex_spectra, "exact (simulator)")):
        taus = {label: float(label.split("=")[1]) for label in spectra}
        plot_lyapunov_spectrum(spectra, tau=taus, rescaled=True, ax=ax)
        ax.set_title(title)
        ax.set_xlim(0, 0.35)
        ax.set_ylim(-2, 1)
    OUT.mkdir(exist_ok=True)
    path = OUT / "rescaled_spectra.png"
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"saved {path}")


if __name__ == "__main__":
    main()
