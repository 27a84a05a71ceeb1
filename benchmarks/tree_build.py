"""The k-d tree build and the projected tree search per delay, against a baseline revision.

Run (prints the exact command, the load average and the table)::

    python benchmarks/tree_build.py [--baseline REV] [--repeats 5]

Two tables, each measured for the current package and for git revision ``REV``
(default ``d92424b``: median splits at every node, boxes computed top-down),
exported with ``git archive`` into a temporary directory and run in a
subprocess by this same script, one after the other in the same run:

* ``build_tree`` on 6000 four-dimensional two-window vectors (m = 2) of a noisy
  Ikeda run (step 0.25, 20 % noise) and of a noisy Mackey-Glass run (5 %), and on
  10^5 random normal points: the best of ``--repeats`` builds.
* ``tree_cells`` (the tree search of :func:`skdelay.forecast_error_curve`) on the
  same runs, m = 2 and 4, taus 3..20, k = 20: milliseconds per tau with no
  queries (the tree builds and the copies), with 400 queries (the gap
  diagnosis's forecast-error indicator) and with every point a query; and
  whether the squared errors are bit-identical to the baseline's.

The ratio is baseline / current.  Both trees give the exact k-NN; on these
series (no repeated values) the fits and errors must agree to the last bit.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_BASELINE = "d92424b"
TAUS = np.arange(3, 21)


def _series(kind):
    from skdelay.systems import Ikeda, MackeyGlass

    if kind == "ikeda":
        x = Ikeda().simulate(6000, sample_dt=0.25, random_state=3)
        x = x + 0.2 * x.std() * np.random.default_rng(0).standard_normal(x.size)
    else:
        x = MackeyGlass().simulate(6000, random_state=3)
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


def measure(repeats):
    """{"build": {name: ms}, "cells": {name: [ms, digest]}}."""
    from skdelay._kdtree import build_tree
    from skdelay._scan import TREE_LEAF_SIZE, second_window_start, tree_cells, window_components

    out = {"build": {}, "cells": {}}
    for kind in ("ikeda", "mg"):
        x = _series(kind)
        data = np.ascontiguousarray(np.column_stack([x[20:-1], x[19:-2], x[10:-11], x[9:-12]]))
        out["build"][f"{kind} 6000 x 4"] = 1e3 * _best(lambda d=data: build_tree(d, 16), repeats)
        for m in (2, 4):
            starts = np.array([second_window_start(m, int(t)) for t in TAUS], dtype=np.int64)
            db = np.arange(starts.max() + m + 2, x.size - 1)
            U = window_components(x, m, db, 2)
            rng = np.random.default_rng(0)
            for nq in (0, 400, db.size):
                q = db if nq == db.size else np.sort(rng.choice(db, nq, replace=False))
                sq = np.zeros((TAUS.size, 10))

                def run(x=x, q=q, sq=sq, U=U, db=db, starts=starts, m=m):
                    sq[:] = 0.0
                    tree_cells(x, U, q, db, m, starts, 20, 5, 1e-3, 1, 0.0, TREE_LEAF_SIZE,
                               sq, 100)

                ms = 1e3 * _best(run, repeats) / TAUS.size
                label = f"{kind} m={m} " + ("all" if nq == db.size else str(nq)) + " queries"
                out["cells"][label] = [ms, hashlib.sha256(sq.tobytes()).hexdigest()[:12]]
    pts = np.random.default_rng(0).standard_normal((100_000, 4))
    out["build"]["random 1e5 x 4"] = 1e3 * _best(lambda: build_tree(pts, 16), repeats)
    return out


def _baseline(rev, repeats):
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "skdelay"],
                                 check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        env = dict(os.environ, PYTHONPATH=tmp)
        res = subprocess.run([sys.executable, __file__, "--worker", "--repeats", str(repeats)],
                             env=env, cwd=tmp, check=True, capture_output=True, text=True)
        return json.loads(res.stdout.splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--baseline", default=DEFAULT_BASELINE, metavar="REV")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:  # baseline subprocess: JSON on the last line
        print(json.dumps(measure(args.repeats)))
        return
    import skdelay

    print("command: python benchmarks/tree_build.py " + " ".join(sys.argv[1:]))
    print(f"skdelay from {Path(skdelay.__file__).parent}; {os.cpu_count()} cores; "
          f"load average at start {os.getloadavg()[0]:.2f}")
    cur = measure(args.repeats)
    base = _baseline(args.baseline, args.repeats)
    print(f"load average at end {os.getloadavg()[0]:.2f}; baseline: git revision "
          f"{args.baseline} (git archive, subprocess, same run); best of {args.repeats}")
    print(f"\n{'build_tree':<22} {'current [ms]':>13} {'baseline [ms]':>14} {'ratio':>6}")
    for name, ms in cur["build"].items():
        b = base["build"][name]
        print(f"{name:<22} {ms:13.3f} {b:14.3f} {b / ms:6.2f}")
    print(f"\n{'tree_cells, per tau':<28} {'current [ms]':>13} {'baseline [ms]':>14} "
          f"{'ratio':>6} {'bit-identical':>14}")
    for name, (ms, digest) in cur["cells"].items():
        b, b_digest = base["cells"][name]
        print(f"{name:<28} {ms:13.3f} {b:14.3f} {b / ms:6.2f} {digest == b_digest!s:>14}")


if __name__ == "__main__":
    main()
