"""Paper-scale delay scan: candidate neighbour search versus a plain k-d tree rebuild.

Scans sigma_m(tau) for m = 2..5 and tau = 1..500 (2000 models) on measured
Mackey-Glass data (delay 150 samples, 0.5 % noise, 12-bit ADC, sample step 1)
of N = 1e5 and 1e6 points, forecasting a random subset of ``--queries`` points
against the full database, and prints wall time and peak memory (RSS of the
main process plus its joblib workers, sampled every 0.2 s) of the whole scan.

The plain method rebuilds a 2m-dimensional k-d tree for every (m, tau); it is
timed on ``--plain-taus`` delays spread over 1..500 (same queries) and
extrapolated linearly to the 500 delays, which the table says.  Its curve also
serves as the reference for the accuracy of the candidate search.

Run (2 cores)::

    python benchmarks/delay_scan.py --sizes 100000 1000000 --queries 10000 --n-jobs 2
"""

from __future__ import annotations

import argparse
import threading
import time

import numpy as np
import psutil

from skdelay._selection import forecast_error_curve, locate_dips
from skdelay.systems import MackeyGlass, measure


class PeakRSS:
    """Peak resident memory of this process and all its children (sampled)."""

    def __init__(self, interval=0.2):
        self.interval = interval
        self.peak = 0
        self._stop = threading.Event()

    def _sample(self):
        me = psutil.Process()
        while not self._stop.is_set():
            total = me.memory_info().rss
            for child in me.children(recursive=True):
                try:
                    total += child.memory_info().rss
                except psutil.Error:
                    pass
            self.peak = max(self.peak, total)
            self._stop.wait(self.interval)

    def __enter__(self):
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()


def timed(fn, **kwargs):
    with PeakRSS() as mem:
        t0 = time.perf_counter()
        out = fn(**kwargs)
        wall = time.perf_counter() - t0
    return out, wall, mem.peak / 2**30


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[1e5, 1e6])
    parser.add_argument("--queries", type=int, default=10_000)
    parser.add_argument("--max-tau", type=int, default=500)
    parser.add_argument("--plain-taus", type=int, default=10)
    parser.add_argument("--delay", type=int, default=150)
    parser.add_argument("--n-jobs", type=int, default=2)
    args = parser.parse_args()
    ms = (2, 3, 4, 5)
    taus = range(1, args.max_tau + 1)
    sub = np.unique(np.linspace(1, args.max_tau, args.plain_taus).round().astype(int))
    sub = np.unique(np.r_[sub, args.delay])
    rows = []
    for n in (int(v) for v in args.sizes):
        x = MackeyGlass(tau=float(args.delay)).simulate(n, random_state=0)
        s = measure(x, noise=0.005, bits=12, random_state=0)
        common = {"m": ms, "n_queries": args.queries, "random_state": 0, "n_jobs": args.n_jobs}
        fast, t_fast, mem_fast = timed(forecast_error_curve, series=s, tau=taus, **common)
        plain, t_plain, mem_plain = timed(forecast_error_curve, series=s, tau=sub,
                                          search="exact", **common)
        t_plain_all = t_plain * len(taus) / len(sub)
        rel = (fast.loc[sub] / plain - 1).abs()
        dips = locate_dips(fast.loc[max(1, args.delay - 40):args.delay + 40])
        rows.append((n, t_fast, mem_fast, t_plain, len(sub), t_plain_all, mem_plain,
                     t_plain_all / t_fast, float(rel.max().max()), float(rel.median().median()),
                     fast.attrs["exact_fraction"], dips))
        print(f"N={n}: candidates {t_fast:.0f} s, plain {t_plain:.0f} s for {len(sub)} taus",
              flush=True)
    print()
    print(f"Delay scan m=2..5, tau=1..{args.max_tau} ({4 * len(taus)} models), "
          f"{args.queries} random query points, n_jobs={args.n_jobs}; Mackey-Glass delay "
          f"{args.delay}, 0.5 % noise, 12 bits.")
    print("| N | candidates: wall | peak RSS | plain rebuild: measured | extrapolated to "
          "all taus | peak RSS | speed-up | max / median rel. diff of sigma |")
    print("|---|---|---|---|---|---|---|---|")
    for (n, tf, mf, tp, ns, tpa, mp, ratio, rmax, rmed, _, _) in rows:
        print(f"| {n:.0e} | {tf:.0f} s | {mf:.2f} GB | {tp:.0f} s ({ns} taus) | {tpa:.0f} s "
              f"(x{len(taus) / ns:.0f}, extrapolated) | {mp:.2f} GB | {ratio:.1f}x | "
              f"{rmax:.3f} / {rmed:.3f} |")
    for (n, *_, exact, dips) in rows:
        print(f"\nN={n:.0e}: certified-exact fraction of queries (min over tau): {exact}")
        print(f"delay by m (true {args.delay}):")
        print(dips.round(2).to_string())


if __name__ == "__main__":
    main()
