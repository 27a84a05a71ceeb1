"""How long the CO2 laser takes to build up its spiking, and whether the default transient
of ``CO2LaserFeedback.simulate`` discards it.

The laser starts from a quiet history.  Per delay, this script simulates ``--seeds`` runs
of ``--length`` time units with no transient at all and reads off each run's build-up
time: the end of the last 500-sample stretch whose standard deviation is below half the
median of the run's last ten stretches.  It then simulates the same seeds with the
default transient and counts the runs whose quietest 500-sample stretch lies below half
their median one (the build-up left in the record; the right answer: none), and the
same with the former default, ``max(3000, 10 tau)``.  Seeds
``--first`` .. ``--first + --seeds - 1``; the default transient was chosen on seeds 0-199,
so the default ``--first`` 1000 checks it on others.

Run (2 cores, about a minute)::

    python benchmarks/laser_transient.py --seeds 200
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from joblib import Parallel, delayed

from skdelay.systems import CO2LaserFeedback

WIDTH = 500  # samples per stretch (sample_dt = 1 microsecond)


def _stretch_std(x):
    return np.array([x[i:i + WIDTH].std() for i in range(0, x.size - WIDTH + 1, WIDTH)])


def _build_up(tau, seed, length):
    """Build-up time (time units) of a run recorded from time 0."""
    x = CO2LaserFeedback(tau=tau).simulate(length, random_state=seed, transient=0.0)
    s = _stretch_std(x)
    quiet = np.flatnonzero(s < 0.5 * np.median(s[-10:]))
    return (int(quiet.max()) + 1) * WIDTH if quiet.size else 0


#: the default transient before stop 46, for comparison
FORMER = (3000.0, 10.0)


def _left(tau, seed, n, transient=None):
    """Quietest stretch over the median one (default transient unless given)."""
    s = _stretch_std(CO2LaserFeedback(tau=tau).simulate(n, random_state=seed,
                                                        transient=transient))
    return float(s.min() / np.median(s))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=200, help="runs per delay")
    ap.add_argument("--first", type=int, default=1000, help="first seed")
    ap.add_argument("--delays", default="50,150,400", help="feedback delays (microseconds)")
    ap.add_argument("--n", type=int, default=10_000, help="samples of the default-transient runs")
    ap.add_argument("--n-jobs", type=int, default=2)
    args = ap.parse_args(argv)
    seeds = range(args.first, args.first + args.seeds)
    print(f"# {args.seeds} seeds from {args.first} per delay; stretches of {WIDTH} samples")
    print(f"{'tau':>6} {'build-up median':>16} {'90 %':>8} {'max':>8} {'max/tau':>8} "
          f"{'default transient':>18} {'runs left quiet':>16} {'former default':>15} "
          f"{'left quiet':>12} {'seconds':>8}")
    for tau in (float(d) for d in args.delays.split(",")):
        t0 = time.perf_counter()
        length = int(max(16_000, 40 * tau))
        build = np.array(Parallel(n_jobs=args.n_jobs)(
            delayed(_build_up)(tau, s, length) for s in seeds))
        left = np.array(Parallel(n_jobs=args.n_jobs)(
            delayed(_left)(tau, s, args.n) for s in seeds))
        former = max(FORMER[0], FORMER[1] * tau)
        old = np.array(Parallel(n_jobs=args.n_jobs)(
            delayed(_left)(tau, s, args.n, former) for s in seeds))
        transient = max(CO2LaserFeedback.transient_time, CO2LaserFeedback.transient_delays * tau)
        print(f"{tau:6.0f} {np.median(build):16.0f} {np.percentile(build, 90):8.0f} "
              f"{build.max():8.0f} {build.max() / tau:8.1f} {transient:18.0f} "
              f"{int(np.sum(left < 0.5)):>7d} / {left.size:<6d} {former:15.0f} "
              f"{int(np.sum(old < 0.5)):>5d} / {old.size:<4d} {time.perf_counter() - t0:8.1f}")


if __name__ == "__main__":
    main()
