"""Speed of a long data-driven spectrum: 50 exponents of a tau = 400 model over 1e5 steps.

Run (prints the exact command, the load average and the table)::

    python benchmarks/lyapunov_speed.py [--baseline REV] [--repeats 2]

The model is the paper-scale case of the laser data at delay 400 us
(``skdelay.datasets.load_laser(400)``, m = 5, k = 100, ridge 3e-2, Theiler
window 2), the spectrum taken along all 1e5 samples of the data.  The table
splits the wall time into its two parts -- the local Jacobians (one
k-nearest-neighbour query and local fit per step) and the tangent QR iteration
-- for 1 thread and for all cores (``n_jobs=-1``).  Every repeat fits a fresh
model, so the time includes building the numba k-d tree of its support guard.

``--baseline REV`` also times the package as of git revision ``REV`` (default:
``8507cef``, before the compiled Jacobian loop), exported with ``git archive``
into a temporary directory and run in a subprocess by this same script, one
after the other in the same run; the ratio column is baseline / current for the
same ``n_jobs``.  The baseline only reports its total time (its spectrum does
not time its parts).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _revision import export_package

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_BASELINE = "8507cef"


def _model(series, m, tau, k, ridge):
    from sklearn.pipeline import make_pipeline

    from skdelay import LocalLinearDelayMap, TwoWindowEmbedding, lagged_windows, required_lags

    X, y = lagged_windows(series, required_lags(m, tau))
    return make_pipeline(TwoWindowEmbedding(m=m, tau=tau),
                         LocalLinearDelayMap(n_neighbors=k, ridge=ridge,
                                             theiler_window=2)).fit(X, y)


def measure(n_exponents, repeats, jobs):
    """{n_jobs: {"total", "jacobians", "tangent_qr", "lambda_1", "lambda_n", "n_steps"}}."""
    from skdelay.datasets import load_laser
    from skdelay.dynamics import lyapunov_spectrum

    series = load_laser(400).series
    lyapunov_spectrum(_model(series[:6000], 5, 400, 100, 3e-2), series[:6000],
                      n_exponents=5)  # compile (or load the numba cache) outside the timing
    out = {}
    for n_jobs in jobs:
        rows = []
        for _ in range(repeats):
            model = _model(series, 5, 400, 100, 3e-2)
            t0 = time.perf_counter()
            spec = lyapunov_spectrum(model, series, n_exponents=n_exponents, n_jobs=n_jobs)
            total = time.perf_counter() - t0
            sec = spec.extra.get("seconds", {})
            rows.append((total, sec.get("jacobians", np.nan), sec.get("tangent_qr", np.nan)))
        med = np.median(np.array(rows), axis=0)
        out[n_jobs] = {"total": float(med[0]), "jacobians": float(med[1]),
                       "tangent_qr": float(med[2]), "lambda_1": float(spec.exponents[0]),
                       "lambda_n": float(spec.exponents[-1]), "n_steps": int(spec.n_steps),
                       "spread_n": float(spec.spread[-1])}
    return out


def _baseline(rev, n_exponents, repeats, jobs):
    with tempfile.TemporaryDirectory() as tmp:
        export_package(rev, tmp)
        env = dict(os.environ, PYTHONPATH=tmp)
        res = subprocess.run([sys.executable, __file__, "--worker", "--n-exponents",
                              str(n_exponents), "--repeats", str(repeats), "--jobs",
                              *map(str, jobs)], env=env, cwd=tmp, check=True,
                             capture_output=True, text=True)
        return {int(k): v for k, v in json.loads(res.stdout.splitlines()[-1]).items()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-exponents", type=int, default=50)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--jobs", type=int, nargs="+", default=[1, -1])
    parser.add_argument("--baseline", nargs="?", const=DEFAULT_BASELINE, default=None,
                        metavar="REV", help=f"also time git revision REV (default "
                                            f"{DEFAULT_BASELINE})")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:  # baseline subprocess: JSON on the last line
        print(json.dumps(measure(args.n_exponents, args.repeats, args.jobs)))
        return
    import skdelay

    print("command: python benchmarks/lyapunov_speed.py " + " ".join(sys.argv[1:]))
    print(f"skdelay from {Path(skdelay.__file__).parent}; {os.cpu_count()} cores; "
          f"load average at start {os.getloadavg()[0]:.2f}")
    current = measure(args.n_exponents, args.repeats, args.jobs)
    base = None
    if args.baseline:
        base = _baseline(args.baseline, args.n_exponents, args.repeats, args.jobs)
    print(f"load average at end {os.getloadavg()[0]:.2f}")
    first = current[args.jobs[0]]
    print(f"{args.n_exponents} exponents, laser tau = 400, m = 5, k = 100, "
          f"{first['n_steps']} steps used; median of {args.repeats} repeats")
    head = (f"{'n_jobs':>7} {'Jacobians [s]':>14} {'tangent QR [s]':>15} {'total [s]':>10} "
            f"{'lambda_1':>10} {'lambda_50':>10}")
    if base:
        head += f" {'baseline [s]':>13} {'ratio':>6} {'base lambda_1':>14}"
    print(head)
    for n_jobs in args.jobs:
        r = current[n_jobs]
        line = (f"{n_jobs:>7} {r['jacobians']:14.2f} {r['tangent_qr']:15.2f} "
                f"{r['total']:10.2f} {r['lambda_1']:10.6f} {r['lambda_n']:10.6f}")
        if base:
            b = base[n_jobs]
            line += f" {b['total']:13.2f} {b['total'] / r['total']:6.2f} {b['lambda_1']:14.6f}"
        print(line)
    print(f"standard error of lambda_{args.n_exponents} (blocks): {first['spread_n']:.6f}; "
          "the laser data are quantised, so distance ties are broken differently by the "
          "two searches")
    if base:
        print(f"baseline: git revision {args.baseline} (git archive, subprocess, same run)")


if __name__ == "__main__":
    main()
