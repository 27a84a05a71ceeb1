"""False alarms and power of the gap diagnosis's range and jump tests (``skdelay.gap._range``).

A record counts as off when it leaves the range of the simulator runs more often than
the runs leave each other's (Poisson tail below ``RANGE_ALPHA`` at the runs' rate bound);
the jump test asks the same of the samples' jumps off the midpoint of their neighbours.
This script draws, per system and sampling step, ``--reps`` records with no effect (fresh
seeds 7.9e6 + 101 j, used nowhere else), runs the public ``diagnose_gap`` on each and
counts how often the test fires (the right answer: never), then adds isolated spikes (the library's outliers at
rate 0.002, sizes 2-6 std) to the same records and counts how often it fires (power).
Steps other than the benchmark's are included on purpose: the test has no tuned level.

Run (2 cores, about 15 minutes)::

    python benchmarks/range_false_alarms.py --n 6000 --reps 10
"""

from __future__ import annotations

import argparse
import time
import warnings

from joblib import Parallel, delayed

from skdelay.gap import diagnose_gap, get_effect
from skdelay.systems import CO2LaserFeedback, ElectroOpticOscillator, Ikeda, MackeyGlass

CASES = {"mackey_glass dt 1": (MackeyGlass, {}, 1.0),
         "mackey_glass dt 0.5": (MackeyGlass, {}, 0.5),
         "ikeda dt 0.5": (Ikeda, {}, 0.5),
         "ikeda dt 0.25": (Ikeda, {}, 0.25),
         "electro_optic dt 0.25": (ElectroOpticOscillator, {}, 0.25),
         "electro_optic dt 0.5": (ElectroOpticOscillator, {}, 0.5),
         "co2_laser tau 150 dt 1": (CO2LaserFeedback, {"tau": 150.0}, 1.0)}


def _test(real, system, dt, seed):
    # the production path: the diagnosis' own runs; one cheap candidate, no second round
    rep = diagnose_gap(real, system, sample_dt=dt, random_state=seed % 9973, n_jobs=1,
                       effects=["outliers"], combine=False, cross_validated=False)
    s = rep.significance
    return (s["beyond_range_p"] < 1e-3, s["beyond_range"], s["significant"],
            s["jumps_p"] < 1e-3, s["jumps"])


def one(label, n, j):
    warnings.simplefilter("ignore")
    cls, kw, dt = CASES[label]
    system = cls(**kw)
    seed = 7_900_000 + 101 * j
    real = system.simulate(n, sample_dt=dt, random_state=seed)
    fires, count, significant, jfires, jcount = _test(real, system, dt, seed)
    size = 2.0 + 4.0 * ((j * 0.618) % 1.0)
    spiked = get_effect("outliers").apply(real, {"rate": 0.002, "size": size},
                                          sample_dt=dt, random_state=seed + 99)
    power, _, found, jpower, _ = _test(spiked, system, dt, seed)
    return {"case": label, "fires": fires, "count": count, "significant": significant,
            "power": power, "found": found, "size": size, "jfires": jfires, "jcount": jcount,
            "jpower": jpower}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=6000)
    ap.add_argument("--reps", type=int, default=10)
    ap.add_argument("--n-jobs", type=int, default=2)
    args = ap.parse_args()
    t0 = time.perf_counter()
    rows = Parallel(n_jobs=args.n_jobs)(delayed(one)(c, args.n, j)
                                        for c in CASES for j in range(args.reps))
    print(f"# n = {args.n}, {args.reps} records per case; spikes: rate 0.002, sizes 2-6 std; "
          "range and jump tests at p < 1e-3 (RANGE_ALPHA)")
    print("| case | range test fires (no effect) | largest count | jump test fires (no "
          "effect) | largest jump count | gap significant (no effect) | range test fires "
          "(spikes) | jump test fires (spikes) | significant (spikes) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for c in CASES:
        r = [x for x in rows if x["case"] == c]
        n = len(r)
        print(f"| {c} | {sum(x['fires'] for x in r)}/{n} | {max(x['count'] for x in r)} | "
              f"{sum(x['jfires'] for x in r)}/{n} | {max(x['jcount'] for x in r)} | "
              f"{sum(x['significant'] for x in r)}/{n} | {sum(x['power'] for x in r)}/{n} | "
              f"{sum(x['jpower'] for x in r)}/{n} | {sum(x['found'] for x in r)}/{n} |")
    print(f"\nfalse alarms: range test {sum(x['fires'] for x in rows)}, jump test "
          f"{sum(x['jfires'] for x in rows)} of {len(rows)}; {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
