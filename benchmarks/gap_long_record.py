"""One gap diagnosis of a long record: wall time against the package at another revision.

A Mackey-Glass record sampled at 1 us with a 50 Hz hum of 3 % of its standard
deviation (20 000 samples per cycle: the paper's own mains hum), diagnosed with
:func:`skdelay.gap.diagnose_gap` at each ``--n`` (default 4e4 and 4e5 samples).
The record's length sets the cost of the whole-record line scan (multitaper
spectra of every run, their leave-one-out nulls, the refined frequencies) and of
the indicators, not of the forecast-error curves (their first 10^4 samples).

``--baseline REV`` also runs the package as of git revision ``REV``, exported
with ``git archive`` into a temporary directory and run in a subprocess by this
script, after the current one in the same run (each first diagnoses a 6000-sample record
untimed, which compiles the kernels); the table gives both times, their
ratio and whether the two diagnoses read the same (best effect, its fitted
parameters and the summary text).

Run (2 cores)::

    python benchmarks/gap_long_record.py --baseline 5554573
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def record(n):
    """Mackey-Glass at 1 us plus a 50 Hz hum of 0.03 std (phase 0.4)."""
    from skdelay.systems import MackeyGlass

    x = MackeyGlass().simulate(n, random_state=7)
    t = np.arange(n) * 1e-6
    return x + 0.03 * x.std() * np.sin(2.0 * np.pi * 50.0 * t + 0.4)


def measure(sizes, n_jobs):
    from skdelay.gap import diagnose_gap
    from skdelay.systems import MackeyGlass

    warnings.simplefilter("ignore")
    # untimed: compiles the kernels (a baseline exported to a fresh directory starts with
    # an empty numba cache)
    diagnose_gap(record(6000), MackeyGlass(), sample_dt="1 us", random_state=0,
                 n_jobs=n_jobs)
    out = {}
    for n in sizes:
        real = record(n)
        t0 = time.perf_counter()
        rep = diagnose_gap(real, MackeyGlass(), sample_dt="1 us", random_state=0,
                           n_jobs=n_jobs)
        seconds = time.perf_counter() - t0
        params = {}
        if rep.best_effect:
            params = rep.effects.set_index("effect").loc[rep.best_effect, "params"]
        out[n] = {"seconds": seconds, "best": rep.best_effect or "None",
                  "params": {k: (float(v) if isinstance(v, (int, float)) else str(v))
                             for k, v in params.items()},
                  "summary": rep.summary()}
    return out


def _baseline(rev, sizes, n_jobs):
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "skdelay"],
                                 check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        env = dict(os.environ, PYTHONPATH=tmp)
        res = subprocess.run([sys.executable, __file__, "--worker", "--n", *map(str, sizes),
                              "--n-jobs", str(n_jobs)], env=env, cwd=tmp, check=True,
                             capture_output=True, text=True)
        return {int(k): v for k, v in json.loads(res.stdout.splitlines()[-1]).items()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[40_000, 400_000])
    parser.add_argument("--n-jobs", type=int, default=2)
    parser.add_argument("--baseline", metavar="REV", default=None,
                        help="also time git revision REV, after the current package")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:  # baseline subprocess: JSON on the last line
        print(json.dumps(measure(args.n, args.n_jobs)))
        return
    import skdelay

    print("command: python benchmarks/gap_long_record.py "
          + " ".join(sys.argv[1:] if argv is None else argv))
    print(f"skdelay from {Path(skdelay.__file__).parent}; {os.cpu_count()} cores; "
          f"load average at start {os.getloadavg()[0]:.2f}")
    current = measure(args.n, args.n_jobs)
    base = _baseline(args.baseline, args.n, args.n_jobs) if args.baseline else None
    print(f"load average at end {os.getloadavg()[0]:.2f}")
    print(f"Mackey-Glass at 1 us + a 50 Hz hum of 0.03 std; diagnose_gap(random_state=0, "
          f"n_jobs={args.n_jobs}); one run each")
    head = f"{'samples':>8} {'seconds':>8} {'best effect':>22}"
    if base:
        head += f" {'baseline [s]':>13} {'ratio':>6} {'same diagnosis':>15}"
    print(head)
    for n in args.n:
        r = current[n]
        line = f"{n:>8} {r['seconds']:8.1f} {r['best']:>22}"
        if base:
            b = base[n]
            same = (b["best"], b["params"], b["summary"]) == (r["best"], r["params"],
                                                              r["summary"])
            line += f" {b['seconds']:13.1f} {b['seconds'] / r['seconds']:6.2f} {same!s:>15}"
        print(line)
    if base:
        print(f"baseline: git revision {args.baseline} (git archive, subprocess, same run); "
              "ratio = baseline / current")


if __name__ == "__main__":
    main()
