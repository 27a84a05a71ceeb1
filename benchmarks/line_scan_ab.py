"""The spectral-line scan alone (``skdelay.gap._lines.line_scan``), this checkout against a
baseline revision, on the same records and runs: false lines and weak hums found.

Per case (system and sampling step) and record ``j`` (seed ``--seed`` + 101 j): a record
with no effect and the same record plus a weak hum (0.02-0.06 of the std, 3 cycles per
record to 0.9 Nyquist, log-spaced over ``j``); six clean runs as the diagnosis draws them
and, for a ``line_scan`` that takes ``more_runs``, further runs from the first run's seed
(as ``GapProblem`` does).  A record "has a false line" when any line is found in the
no-effect record; a hum is "found" when a line lies within two bins of it.  The baseline's
``_lines.py`` is read from git (``git show REV:skdelay/gap/_lines.py``), so no second
checkout is needed; both scans are loaded from their files (the scan is private).  This
is cheaper than ``line_false_alarms.py`` (no diagnosis, about 90 s for 320 records on 2
cores) and isolates the scan's calibration.

Run (2 cores)::

    python benchmarks/line_scan_ab.py --baseline 92a4439 --n 6000 --reps 40 --seed 9100000
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import os
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np
from joblib import Parallel, delayed
from range_false_alarms import CASES as RANGE_CASES

from skdelay.gap import get_effect
from skdelay.systems import CO2LaserFeedback

# the range tests' systems and steps (one home for the case list), and the laser at delay 50
CASES = {**RANGE_CASES, "co2_laser tau 50 dt 1": (CO2LaserFeedback, {"tau": 50.0}, 1.0)}
EXTRA_RUNS = 24


def _module(path, name):
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, path)
        mod = importlib.util.module_from_spec(spec)
        mod.__package__ = "skdelay.gap"
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
    return sys.modules[name]


def one(label, n, j, base, baseline_path, head_path):
    warnings.simplefilter("ignore")
    cls, kw, dt = CASES[label]
    system = cls(**kw)
    seed = base + 101 * j
    real = system.simulate(n, sample_dt=dt, random_state=seed)
    seeds = np.random.RandomState(seed % 9973).randint(0, 2**31 - 1, size=6)
    runs = [np.asarray(system.simulate(n, sample_dt=dt, random_state=int(s))) for s in seeds]
    extra_seeds = np.random.RandomState(int(seeds[0])).randint(0, 2**31 - 1, size=EXTRA_RUNS)
    cache = {}

    def more(k):
        if k not in cache:
            cache[k] = [np.asarray(system.simulate(n, sample_dt=dt, random_state=int(s)))
                        for s in extra_seeds[:k]]
        return cache[k]

    lo, hi = 3.0 / (n * dt), 0.45 / dt
    freq = lo * math.exp(((j * 0.618 + 0.1) % 1.0) * math.log(hi / lo))
    amp = 0.02 + 0.04 * ((j * 0.382) % 1.0)
    hummed = get_effect("periodic_interference").apply(
        real, {"frequency": freq, "amplitude": amp, "phase": 0.3 * j}, sample_dt=dt,
        random_state=seed + 7)
    out = {"case": label, "j": j, "cycles": freq * n * dt, "amp": amp}
    bin_width = 1.0 / (n * dt)
    for name, mod in (("baseline", _module(baseline_path, "skdelay.gap._lines_baseline")),
                      ("head", _module(head_path, "skdelay.gap._lines_head"))):
        extra = {"more_runs": more} if "more_runs" in mod.line_scan.__code__.co_varnames else {}
        false = mod.line_scan(real, runs, dt, **extra)[0]
        found = mod.line_scan(hummed, runs, dt, **extra)[0]
        out[name + "_false"] = [round(line.frequency * n * dt, 1) for line in false]
        out[name + "_hum"] = any(abs(line.frequency - freq) <= 2 * bin_width + line.half_width
                                 for line in found)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", required=True, help="git revision of the baseline scan")
    ap.add_argument("--n", type=int, default=6000)
    ap.add_argument("--reps", type=int, default=40)
    ap.add_argument("--seed", type=int, default=9_100_000)
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated, of: "
                    + ", ".join(CASES))
    ap.add_argument("--n-jobs", type=int, default=2)
    args = ap.parse_args()
    cases = [c.strip() for c in args.cases.split(",")]
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    text = subprocess.run(["git", "show", f"{args.baseline}:skdelay/gap/_lines.py"], cwd=root,
                          check=True, capture_output=True, text=True).stdout
    with tempfile.NamedTemporaryFile("w", suffix="_lines.py", delete=False) as fh:
        fh.write(text)
    t0 = time.time()
    head = os.path.join(root, "skdelay", "gap", "_lines.py")
    rows = Parallel(n_jobs=args.n_jobs)(delayed(one)(c, args.n, j, args.seed, fh.name, head)
                                        for c in cases for j in range(args.reps))
    os.unlink(fh.name)
    print(f"line scan, baseline {args.baseline} -> this checkout: n {args.n}, "
          f"seeds {args.seed} + 101 j, {args.reps} records per case\n")
    print(f"{'case':24s} {'records':>7s} {'false lines':>14s} {'hums found':>12s}")
    tot = np.zeros(4, dtype=int)
    for c in cases:
        r = [x for x in rows if x["case"] == c]
        v = np.array([sum(bool(x["baseline_false"]) for x in r),
                      sum(bool(x["head_false"]) for x in r),
                      sum(x["baseline_hum"] for x in r), sum(x["head_hum"] for x in r)])
        tot += v
        print(f"{c:24s} {len(r):7d} {v[0]:6d} -> {v[1]:3d} {v[2]:6d} -> {v[3]:3d}")
    print(f"{'all':24s} {len(rows):7d} {tot[0]:6d} -> {tot[1]:3d} {tot[2]:6d} -> {tot[3]:3d}")
    print("\nrecords whose result changed (cycles per record):")
    for x in rows:
        if (bool(x["baseline_false"]) != bool(x["head_false"])
                or x["baseline_hum"] != x["head_hum"]):
            print(f"  {x['case']:24s} j {x['j']:3d}  false {x['baseline_false']} -> "
                  f"{x['head_false']}  hum {x['cycles']:.1f} ({x['amp']:.3f} std) "
                  f"{x['baseline_hum']} -> {x['head_hum']}")
    print(f"\n{time.time() - t0:.0f} s")


if __name__ == "__main__":
    main()
