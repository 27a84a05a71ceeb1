"""Speed of a long data-driven spectrum: 50 exponents of a tau = 400 model over 1e5 steps.

Run: ``python benchmarks/lyapunov_speed.py`` (about a minute on 2 cores).

The model is the paper-scale case of the laser data at delay 400 us
(``skdelay.datasets.load_laser(400)``, m = 5, k = 100, ridge 3e-2).  The
table splits the wall time into its two parts -- the local Jacobians (one
k-nearest-neighbour query and local fit per step) and the tangent QR iteration
-- for 1 thread and for all cores (``n_jobs=-1``, the threads of the k-d tree
queries), and gives the ratio against 1 thread measured in the same run.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from skdelay import LocalLinearDelayMap, TwoWindowEmbedding, lagged_windows, required_lags
from skdelay.datasets import load_laser
from skdelay.dynamics import lyapunov_spectrum


def _model(series, m, tau, k, ridge):
    from sklearn.pipeline import make_pipeline

    X, y = lagged_windows(series, required_lags(m, tau))
    return make_pipeline(TwoWindowEmbedding(m=m, tau=tau),
                         LocalLinearDelayMap(n_neighbors=k, ridge=ridge,
                                             theiler_window=2)).fit(X, y)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-exponents", type=int, default=50)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args(argv)
    series = load_laser(400).series
    model = _model(series, 5, 400, 100, 3e-2)
    lyapunov_spectrum(model, series[:5000], n_exponents=5)  # compile outside the timing
    rows = []
    for n_jobs in (1, -1):
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            spec = lyapunov_spectrum(model, series, n_exponents=args.n_exponents,
                                     n_jobs=n_jobs)
            times.append(time.perf_counter() - t0)
        rows.append((n_jobs, float(np.median(times)), spec))
    base = rows[0][1]
    print(f"50 exponents, tau = 400, m = 5, k = 100, {rows[0][2].n_steps} steps, "
          f"{os.cpu_count()} cores")
    print(f"{'n_jobs':>7} {'wall [s]':>9} {'ratio vs 1':>11} {'lambda_1 [1/ms]':>16}")
    for n_jobs, wall, spec in rows:
        print(f"{n_jobs:>7} {wall:9.1f} {wall / base:11.2f} {1000 * spec.exponents[0]:16.3f}")


if __name__ == "__main__":
    main()
