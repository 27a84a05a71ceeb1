"""Which model settings give the laser's exact spectrum, and which data-only score sees it.

Run: ``python benchmarks/spectrum_settings.py --delay 50 --grid "3,9,150,1e-3;2,14,150,1e-2"``
(each grid entry ``step,m,k,ridge``; about 10-100 s per entry on 2 cores).

For each setting: the local linear two-window model of the embedded laser data
(:func:`skdelay.datasets.load_laser`) sampled every ``step`` microseconds, window
``m`` (spanning ``m * step`` us), delay ``round(delay / step)`` steps, ``k``
neighbours and relative ridge; its Lyapunov spectrum along the whole series
(``flow=True``) beside the shipped exact one; and the RMS error of free runs of
the same model fitted on the first two thirds, started from the true history at
``--runs`` random times of the last third, after 10, 25, 50, 100 and 200 us
(normalised by the std; an escaped run counts as sqrt(2)).  The exact spectra
are *only* printed for comparison: nothing here chooses a setting.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

import numpy as np

from skdelay.datasets import laser_exact_spectrum, load_laser
from skdelay.dynamics import iterate, lyapunov_spectrum
from skdelay.model_selection import ModelOptions

HORIZONS = (10, 25, 50, 100, 200)


def _fit(series, m, tau, options):
    from sklearn.pipeline import make_pipeline

    from skdelay import LocalLinearDelayMap, TwoWindowEmbedding, lagged_windows, required_lags

    X, y = lagged_windows(series, required_lags(m, tau))
    return make_pipeline(
        TwoWindowEmbedding(m=m, tau=tau),
        LocalLinearDelayMap(n_neighbors=options.n_neighbors, ridge=options.ridge,
                            theiler_window=options.theiler_window)).fit(X, y)


def row(s0, delay, step, m, k, ridge, starts, n_exponents=20):
    s = s0[::step]
    tau = round(delay / step)
    opts = ModelOptions(n_neighbors=k, ridge=ridge)
    t0 = time.perf_counter()
    model = _fit(s, m, tau, opts)
    spec = lyapunov_spectrum(model, s, n_exponents=min(n_exponents, tau + m // 2), flow=True,
                             n_jobs=1, sample_dt=step)
    ntr = 2 * s0.size // 3
    cv = _fit(s[:ntr // step], m, tau, opts)
    hist = tau + m // 2 + 1
    steps = -(-max(HORIZONS) // step)
    sd = s0.std()
    err = np.full((len(starts), len(HORIZONS)), np.sqrt(2) * sd)
    for j, i in enumerate(starts):
        i_h = i // step
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            run = iterate(cv, s[i_h - hist:i_h], steps, on_escape="ignore")
        for q, horizon in enumerate(HORIZONS):
            st = -(-horizon // step)
            if run.size >= st:
                err[j, q] = run[st - 1] - s0[(i_h - 1 + st) * step]
    rms = np.sqrt(np.mean(err ** 2, axis=0)) / sd
    return (f"step={step} m={m:2d} span={step * m:2d} k={k:4d} ridge={ridge:.0e} "
            f"N+={spec.n_positive:2d} lmax={1e3 * spec.exponents[0]:5.2f} "
            f"DKY={spec.kaplan_yorke_dimension:5.2f} hKS={1e3 * spec.ks_entropy:5.2f} | "
            + " ".join(f"T{h}={e:.3f}" for h, e in zip(HORIZONS, rms))
            + f"  {time.perf_counter() - t0:.0f}s")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--delay", type=int, default=50)
    parser.add_argument("--n-samples", type=int, default=100_000)
    parser.add_argument("--runs", type=int, default=400)
    parser.add_argument("--grid", required=True)
    parser.add_argument("--out", default=None)
    parser.add_argument("--n-exponents", type=int, default=20)
    args = parser.parse_args(argv)
    s0 = load_laser(args.delay, n_samples=args.n_samples).series
    rng = np.random.default_rng(0)
    ntr = 2 * s0.size // 3
    starts = np.sort(rng.choice(np.arange(ntr + 2000, s0.size - max(HORIZONS) - 1),
                                args.runs, replace=False))
    ex = laser_exact_spectrum(args.delay)
    lines = [(f"# {time.strftime('%Y-%m-%d %H:%M')} UTC, load {os.getloadavg()[0]:.1f}; "
              + " ".join(["python", *sys.argv])),
             (f"exact N+={ex.n_positive} lmax={1e3 * ex.exponents[0]:.2f} "
              f"DKY={ex.kaplan_yorke_dimension:.2f} hKS={1e3 * ex.ks_entropy:.2f}")]
    print("\n".join(lines), flush=True)
    for entry in args.grid.split(";"):
        step, m, k, ridge = entry.split(",")
        lines.append(row(s0, args.delay, int(step), int(m), int(k), float(ridge), starts,
                         args.n_exponents))
        print(lines[-1], flush=True)
    if args.out:
        with open(args.out, "a") as fh:
            fh.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
