"""The k-d tree build and the projected tree search per delay, against a baseline revision.

Run (prints the exact command, the load average and the table)::

    python benchmarks/tree_build.py [--baseline REV] [--repeats 5]
    python benchmarks/tree_build.py --baseline REV --n 100000 --held-out-only --repeats 3

One table, measured for the current package and for git revision ``REV``
(default ``d92424b``: median splits at every k-d tree node, boxes computed
top-down), exported with ``git archive`` into a temporary directory and run in
a subprocess by this same script, one after the other in the same run.

:func:`skdelay.forecast_error_curve` with the projected tree search
(``search="tree"``, no refinement) on ``--n`` samples (default 6000) of a noisy
Ikeda run (step 0.25, 20 % noise) and of a noisy Mackey-Glass run (5 %), m = 2
and 4, taus 3..20, k = 20: milliseconds per tau (the best of ``--repeats``) with 10
queries (nearly all of it the tree builds and copies), with 400 queries (as
the gap diagnosis's forecast-error indicator) and with every point a query;
and, held out, every row of the two test folds of a time-series split scored
against its training rows (:class:`skdelay.DelaySelectorCV`, milliseconds per
tau and fold); and whether sigma and its standard error are bit-identical to
the baseline's.

The ratio is baseline / current.  Both trees give the exact k-NN; on these
series (no repeated values) the fits and errors must agree to the last bit.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _revision import ab_parser, export_package

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_BASELINE = "d92424b"
TAUS = np.arange(3, 21)


def _series(kind, n=6000):
    from skdelay.systems import Ikeda, MackeyGlass

    if kind == "ikeda":
        x = Ikeda().simulate(n, sample_dt=0.25, random_state=3)
        x = x + 0.2 * x.std() * np.random.default_rng(0).standard_normal(x.size)
    else:
        x = MackeyGlass().simulate(n, random_state=3)
        x = x + 0.05 * x.std() * np.random.default_rng(0).standard_normal(x.size)
    return (x - x.mean()) / x.std()


def _best(fn, repeats):
    fn()  # compile (or load the numba cache) outside the timing
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def measure(repeats, n=6000, held_out_only=False):
    """{name: [ms per tau, digest of sigma and its standard error]}."""
    from skdelay import forecast_error_curve

    out = {}
    for kind in ("ikeda", "mg"):
        x = _series(kind, n)
        for m in (2, 4):
            for nq in () if held_out_only else (10, 400, None):
                got = {}

                def run(x=x, m=m, nq=nq, got=got):
                    got["curve"] = forecast_error_curve(
                        x, m=(m,), tau=TAUS, n_neighbors=20, n_queries=nq, search="tree",
                        refine=False, random_state=0)

                ms = 1e3 * _best(run, repeats) / TAUS.size
                curve = got["curve"]
                digest = hashlib.sha256(curve.to_numpy().tobytes()
                                        + curve.attrs["se"].to_numpy().tobytes()).hexdigest()
                label = f"{kind} m={m} " + ("all" if nq is None else str(nq)) + " queries"
                out[label] = [ms, digest[:12]]
            out[f"{kind} m={m} held-out"] = _held_out(x, m, repeats)
    return out


def _held_out(x, m, repeats):
    """[ms per tau and fold, digest]: every row of each test fold of a 2-fold time-series
    split a query against its training rows (:class:`skdelay.DelaySelectorCV`)."""
    import warnings

    from sklearn.model_selection import TimeSeriesSplit

    from skdelay import DelaySelectorCV, lagged_windows, required_lags

    X, y = lagged_windows(x, n_lags=required_lags(m, int(TAUS.max())))
    got = {}

    def run():
        sel = DelaySelectorCV(m=(m,), tau=TAUS, cv=TimeSeriesSplit(n_splits=2), search="tree",
                              refine=False, random_state=0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a missing dip is not this benchmark's business
            got["curve"] = sel.fit(X, y).forecast_error_
    ms = 1e3 * _best(run, repeats) / (2 * TAUS.size)
    curve = got["curve"]
    digest = hashlib.sha256(curve.to_numpy().tobytes()
                            + curve.attrs["se"].to_numpy().tobytes()).hexdigest()
    return [ms, digest[:12]]


def _baseline(rev, repeats, extra=()):
    with tempfile.TemporaryDirectory() as tmp:
        export_package(rev, tmp)
        env = dict(os.environ, PYTHONPATH=tmp)
        res = subprocess.run([sys.executable, __file__, "--worker", "--repeats", str(repeats)]
                             + list(extra), env=env, cwd=tmp, check=True, capture_output=True,
                             text=True)
        return json.loads(res.stdout.splitlines()[-1])


def main(argv=None):
    parser = ab_parser(__doc__, repeats=5, baseline=DEFAULT_BASELINE)
    parser.add_argument("--n", type=int, default=6000, help="samples of each series")
    parser.add_argument("--held-out-only", action="store_true",
                        help="only the held-out rows (e.g. at --n 100000)")
    args = parser.parse_args(argv)
    extra = ["--n", str(args.n)] + (["--held-out-only"] if args.held_out_only else [])
    if args.worker:  # baseline subprocess: JSON on the last line
        print(json.dumps(measure(args.repeats, args.n, args.held_out_only)))
        return
    import skdelay

    print("command: python benchmarks/tree_build.py " + " ".join(sys.argv[1:]))
    print(f"skdelay from {Path(skdelay.__file__).parent}; {os.cpu_count()} cores; "
          f"load average at start {os.getloadavg()[0]:.2f}")
    cur = measure(args.repeats, args.n, args.held_out_only)
    base = _baseline(args.baseline, args.repeats, extra)
    print(f"load average at end {os.getloadavg()[0]:.2f}; baseline: git revision "
          f"{args.baseline} (git archive, subprocess, same run); best of {args.repeats}")
    print(f"\n{'per tau':<24} {'current [ms]':>13} {'baseline [ms]':>14} {'ratio':>6} "
          f"{'bit-identical':>14}")
    for name, (ms, digest) in cur.items():
        b, b_digest = base[name]
        print(f"{name:<24} {ms:13.3f} {b:14.3f} {b / ms:6.2f} {digest == b_digest!s:>14}")


if __name__ == "__main__":
    main()
