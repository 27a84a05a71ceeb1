"""The minimal faithful embedding's cost, against a baseline revision.

Run (prints the exact command, the load average and the table)::

    python benchmarks/faithful_speed.py [--baseline REV] [--repeats 2]

:func:`skdelay.dynamics.minimal_embedding` on the record of
``tests/test_faithful.py`` (Mackey-Glass tau = 17, 10^5 samples, 1 % measurement
noise, the dips' delays per m, m = 1..5, ``random_state=2``), called twice in one
process: the first call pays the noise reduction and builds the data segments'
support references; the second finds the noise reduction already done for the
same series.  Measured for the current package and for git revision ``REV``
(default ``d92424b``: support trees rebuilt for every distance, the noise
reduction redone on every call), exported with ``git archive`` and run in a
subprocess by this same script, alternating the two ``--repeats`` times.

The table gives both calls' wall times, the verdict (m_d) and a digest of the
per-m table: the same digest means the same runs, distances and verdicts.
Numba kernels are compiled (or loaded) outside the timing by a short call first.
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

from _revision import ab_parser, export_package

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_BASELINE = "d92424b"
TAUS = {1: 18, 2: 17, 3: 18, 4: 18, 5: 18}  # the record's dips (tests/test_faithful.py)


def measure():
    """Wall times of two calls, m_d and the table's digest."""
    from skdelay.dynamics import minimal_embedding
    from skdelay.systems import MackeyGlass
    from skdelay.systems import measure as observe

    clean = MackeyGlass(tau=17.0).simulate(100_000, random_state=2024)
    x = observe(clean, noise=0.01, random_state=2025)
    minimal_embedding(x[:6000], tau={1: 17, 2: 17}, m_max=2, random_state=0)  # compile
    out = {}
    for call in ("first", "second"):
        t0 = time.perf_counter()
        res = minimal_embedding(x, tau=TAUS, m_max=5, random_state=2)
        out[call] = time.perf_counter() - t0
    table = res.table.drop(columns="status").to_csv(float_format="%.10g")
    out["m_d"] = res.m_d
    out["digest"] = hashlib.sha256(table.encode()).hexdigest()[:12]
    return out


def _in_subprocess(pythonpath):
    env = dict(os.environ, PYTHONPATH=str(pythonpath))
    res = subprocess.run([sys.executable, __file__, "--worker"], env=env, cwd=str(pythonpath),
                         check=True, capture_output=True, text=True)
    return json.loads(res.stdout.splitlines()[-1])


def main(argv=None):
    args = ab_parser(__doc__, repeats=2, baseline=DEFAULT_BASELINE).parse_args(argv)
    if args.worker:  # one measurement, JSON on the last line
        print(json.dumps(measure(), default=str))
        return
    print("command: python benchmarks/faithful_speed.py " + " ".join(sys.argv[1:]))
    print(f"{os.cpu_count()} cores; load average at start {os.getloadavg()[0]:.2f}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        export_package(args.baseline, tmp)
        for rep in range(args.repeats):
            for label, src in (("current", ROOT), (args.baseline, tmp)):
                rows.append((label, rep + 1, _in_subprocess(src)))
    print(f"load average at end {os.getloadavg()[0]:.2f}; baseline: git revision "
          f"{args.baseline} (git archive, subprocess); runs alternate current / baseline")
    print(f"\n{'package':<10} {'run':>3} {'first call [s]':>15} {'second call [s]':>16} "
          f"{'m_d':>4} {'table digest':>13}")
    for label, rep, got in rows:
        print(f"{label:<10} {rep:>3} {got['first']:15.1f} {got['second']:16.1f} "
              f"{got['m_d']!s:>4} {got['digest']:>13}")


if __name__ == "__main__":
    main()
