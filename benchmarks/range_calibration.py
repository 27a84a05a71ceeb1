"""The gap diagnosis's excursion tests (range and jumps, ``skdelay.gap._range``) against six
clean runs alone and as the diagnosis runs them: repeated against its 24 calibration runs
where a test fires or more runs could make it fire (``excursion_tests``).

Per case (the systems and steps of ``range_false_alarms.py``) and record ``j`` (seed
``--seed`` + 101 j): a record with no effect, and the same record with isolated spikes (the
library's outliers at ``--rate`` and ``--size``: each spike ``size * U(0.5, 1.5)`` std).  The
six runs are seeded as the diagnosis seeds them and the 18 further runs as its calibration
runs are.  A record "fires" when the range test or the jump test is off (p < RANGE_ALPHA).
The right answer: never on the no-effect records, as often as possible with spikes.  The
module is loaded from this checkout's file (the tests are private).

Run (2 cores, about 4 minutes)::

    python benchmarks/range_calibration.py --n 6000 --reps 150 --seed 31100000
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import numpy as np
from joblib import Parallel, delayed
from line_scan_ab import _module
from range_false_alarms import CASES

from skdelay.gap import get_effect

CALIBRATION_RUNS = 24  # skdelay.gap._lines.CALIBRATION_RUNS
HERE = os.path.dirname(os.path.abspath(__file__))


def _range_module():
    path = os.path.join(HERE, os.pardir, "skdelay", "gap", "_range.py")
    return _module(path, "skdelay_gap_range_bench")


def one(label, n, j, base, rate, size):
    warnings.simplefilter("ignore")
    rg = _range_module()
    cls, kw, dt = CASES[label]
    system = cls(**kw)
    seed = base + 101 * j
    real = system.simulate(n, sample_dt=dt, random_state=seed)
    # as GapProblem seeds them: the six runs from random_state = seed % 9973 (the benchmarks'
    # convention), the calibration runs from the first run's seed
    seeds = np.random.RandomState(seed % 9973).randint(0, 2**31 - 1, size=6)
    runs = [system.simulate(n, sample_dt=dt, random_state=int(s)) for s in seeds]
    extra_seeds = np.random.RandomState(int(seeds[0])).randint(0, 2**31 - 1,
                                                               size=CALIBRATION_RUNS)
    extra = []

    def calibration():
        if not extra:
            extra.extend(system.simulate(n, sample_dt=dt, random_state=int(s))
                         for s in extra_seeds[:CALIBRATION_RUNS - len(runs)])
        return runs + extra

    spiked = get_effect("outliers").apply(real, {"rate": rate, "size": size}, sample_dt=dt,
                                          random_state=seed + 5)
    out = {}
    for name, rec in (("null", real), ("spikes", spiked)):
        six = rg.range_test(rec, runs)["off"] or rg.jump_test(rec, runs)["off"]
        beyond, jumps, used = rg.excursion_tests(rec, runs, calibration, CALIBRATION_RUNS)
        out[name] = (bool(six), bool(beyond["off"] or jumps["off"]), used > len(runs),
                     beyond["count"], jumps["count"])
    return label, j, out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=6000)
    parser.add_argument("--reps", type=int, default=150)
    parser.add_argument("--seed", type=int, default=31_100_000)
    parser.add_argument("--rate", type=float, default=0.0005)
    parser.add_argument("--size", type=float, default=4.0)
    parser.add_argument("--n-jobs", type=int, default=2)
    args = parser.parse_args(argv)
    t0 = time.time()
    res = Parallel(n_jobs=args.n_jobs)(
        delayed(one)(label, args.n, j, args.seed, args.rate, args.size)
        for label in CASES for j in range(args.reps))
    print(f"excursion tests: n {args.n}, seeds {args.seed} + 101 j, {args.reps} records per "
          f"case; spikes at rate {args.rate} of size {args.size} std x U(0.5, 1.5); "
          f"{time.time() - t0:.0f} s")
    print("fires = range or jump test off (p < RANGE_ALPHA); 'six' = against the six runs "
          "alone, 'diagnosis' = as the diagnosis judges it; 'drew' = records judged on the "
          f"{CALIBRATION_RUNS} calibration runs; 'lost' = spiked records that fire against six "
          "runs but not as the diagnosis judges them")
    head = (f"{'case':26s} {'no effect: six':>15s} {'diagnosis':>10s} {'drew':>5s} | "
            f"{'spikes: six':>12s} {'diagnosis':>10s} {'drew':>5s} {'lost':>5s}")
    print(head)
    total = np.zeros(7, int)
    for label in CASES:
        rows = [o for lab, _, o in res if lab == label]
        c = np.array([sum(r["null"][0] for r in rows), sum(r["null"][1] for r in rows),
                      sum(r["null"][2] for r in rows), sum(r["spikes"][0] for r in rows),
                      sum(r["spikes"][1] for r in rows), sum(r["spikes"][2] for r in rows),
                      sum(r["spikes"][0] and not r["spikes"][1] for r in rows)])
        total += c
        print(f"{label:26s} {c[0]:15d} {c[1]:10d} {c[2]:5d} | {c[3]:12d} {c[4]:10d} {c[5]:5d} "
              f"{c[6]:5d}   (of {len(rows)})")
    c = total
    print(f"{'all':26s} {c[0]:15d} {c[1]:10d} {c[2]:5d} | {c[3]:12d} {c[4]:10d} {c[5]:5d} "
          f"{c[6]:5d}   (of {len(res)})")


if __name__ == "__main__":
    main()
