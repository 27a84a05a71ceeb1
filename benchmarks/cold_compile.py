"""Cold start: what a fresh process spends compiling numba kernels, against a baseline revision.

Run (prints the exact command, the load average and the table)::

    python benchmarks/cold_compile.py [--baseline REV] [--repeats 2]

A fresh checkout, a CI run, every joblib worker and every CLI subprocess start
with an empty numba cache (or one that other processes are still filling), so
each compiles the kernels it needs before computing anything.  This script runs
the reduced demo (``skdelay demo --delays 50 --n-samples 8000``: the delay scan,
model selection, free runs, the models' Lyapunov spectra, the classic
cross-checks) in a subprocess with an empty ``NUMBA_CACHE_DIR``, for the current
package and for git revision ``REV`` (default ``aece4f4``, before the compile
savings), exported with ``git archive``, alternating the two ``--repeats``
times, and prints per run the wall time, the seconds spent compiling (numba's
``numba:compile`` events of the outermost dispatchers, so nested compiles are
not counted twice), the five costliest kernels and a digest of the demo's
``table.csv`` (the same digest: the same results).

The embedded example data are generated once, outside the timing
(``SKDELAY_DATA`` points both runs at the same cache).
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

from _revision import export_package

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_BASELINE = "aece4f4"
DEMO = ["demo", "--delays", "50", "--n-samples", "8000", "--quiet"]

# Runs in the subprocess: the demo through the public CLI, with numba's compile events
# recorded (outermost dispatchers only).
_CHILD = r"""
import json, sys, time
from numba.core import event

starts = []  # compile events nest: a stack of start times
totals = {}

class Listener(event.Listener):
    def on_start(self, ev):
        starts.append(time.perf_counter())

    def on_end(self, ev):
        t0 = starts.pop()
        if not starts:
            name = ev.data["dispatcher"].py_func.__qualname__
            totals[name] = totals.get(name, 0.0) + time.perf_counter() - t0

event.register("numba:compile", Listener())
t0 = time.perf_counter()
from skdelay.cli import main
code = main(sys.argv[2:] + ["--out", sys.argv[1]])
wall = time.perf_counter() - t0
print(json.dumps({"code": code, "wall": wall, "compile": totals}))
"""


def _run(pythonpath, out_dir, data_cache):
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, PYTHONPATH=str(pythonpath), NUMBA_CACHE_DIR=cache,
                   SKDELAY_DATA=str(data_cache))
        res = subprocess.run([sys.executable, "-c", _CHILD, str(out_dir), *DEMO], env=env,
                             cwd=str(pythonpath), check=True, capture_output=True, text=True)
    got = json.loads(res.stdout.splitlines()[-1])
    if got["code"] != 0:
        raise RuntimeError(f"the demo failed under {pythonpath}: {res.stderr[-2000:]}")
    table = (Path(out_dir) / "table.csv").read_bytes()
    got["digest"] = hashlib.sha256(table).hexdigest()[:12]
    return got


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--baseline", default=DEFAULT_BASELINE, metavar="REV")
    args = parser.parse_args(argv)
    print("command: python benchmarks/cold_compile.py " + " ".join(sys.argv[1:]))
    print(f"{os.cpu_count()} cores; load average at start {os.getloadavg()[0]:.2f}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        base_src = tmp / "baseline"
        base_src.mkdir()
        export_package(args.baseline, str(base_src))
        data_cache = tmp / "data"
        # the embedded example data, generated (or read) once outside the timing
        preload = "from skdelay.datasets import load_laser; load_laser(delay=50, n_samples=8000)"
        subprocess.run([sys.executable, "-c", preload], check=True, capture_output=True,
                       env=dict(os.environ, PYTHONPATH=str(ROOT), SKDELAY_DATA=str(data_cache)))
        for rep in range(args.repeats):
            for label, src in (("current", ROOT), (args.baseline, base_src)):
                t0 = time.time()
                got = _run(src, tmp / f"out-{label}-{rep}", data_cache)
                rows.append((label, rep + 1, got, time.time() - t0))
    print(f"load average at end {os.getloadavg()[0]:.2f}; baseline: git revision "
          f"{args.baseline} (git archive, subprocess); runs alternate current / baseline")
    print(f"\n{'package':<10} {'run':>3} {'wall [s]':>9} {'compiling [s]':>14} "
          f"{'table.csv':>13}  costliest kernels to compile [s]")
    for label, rep, got, _ in rows:
        top = sorted(got["compile"].items(), key=lambda kv: -kv[1])[:5]
        kernels = ", ".join(f"{name} {sec:.1f}" for name, sec in top)
        print(f"{label:<10} {rep:>3} {got['wall']:9.1f} {sum(got['compile'].values()):14.1f} "
              f"{got['digest']:>13}  {kernels}")


if __name__ == "__main__":
    main()
