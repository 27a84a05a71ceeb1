"""Paper-scale delay scan: candidate neighbour search versus a plain k-d tree rebuild.

Scans sigma_m(tau) for m = 2..5 and tau = 1..500 (2000 models) on measured
Mackey-Glass data (delay 150 samples, 0.5 % noise, 12-bit ADC, sample step 1)
of N = 1e5 and 1e6 points, forecasting a random subset of ``--queries`` points
against the full database, and prints wall time and peak memory (RSS of the
main process plus its joblib workers, sampled every 0.2 s) and CPU time (main
plus workers; on a shared machine wall time alone depends on the other load)
of the whole scan.

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


class Usage:
    """Peak resident memory and CPU time of this process and its children (sampled).

    Memory is the peak of the summed RSS (every 0.2 s); CPU time is the user +
    system time spent during the block by this process and by every child seen
    (joblib's loky workers persist between calls, so their times are deltas).
    """

    def __init__(self, interval=0.2):
        self.interval = interval
        self.peak = 0
        self._first, self._last = {}, {}
        self._stop = threading.Event()

    @staticmethod
    def _cpu(proc):
        t = proc.cpu_times()
        return t.user + t.system

    def _poll(self):
        me = psutil.Process()
        total = me.memory_info().rss
        for proc in [me, *me.children(recursive=True)]:
            try:
                cpu = self._cpu(proc)
                if proc is not me:
                    total += proc.memory_info().rss
            except psutil.Error:
                continue
            self._first.setdefault(proc.pid, cpu)
            self._last[proc.pid] = cpu
        self.peak = max(self.peak, total)

    def _run(self):
        while not self._stop.wait(self.interval):
            self._poll()

    def __enter__(self):
        self._poll()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self._poll()

    @property
    def cpu(self):
        return sum(self._last[p] - self._first[p] for p in self._last)


def timed(fn, **kwargs):
    with Usage() as usage:
        t0 = time.perf_counter()
        out = fn(**kwargs)
        wall = time.perf_counter() - t0
    return out, wall, usage.peak / 2**30, usage.cpu


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
    warm = measure(MackeyGlass(tau=20.0).simulate(3000, random_state=1), noise=0.005)
    for search in ("candidates", "exact"):  # start the workers and load compiled kernels
        forecast_error_curve(warm, m=ms, tau=range(1, 30), n_queries=100, search=search,
                             n_jobs=args.n_jobs)
    for n in (int(v) for v in args.sizes):
        x = MackeyGlass(tau=float(args.delay)).simulate(n, random_state=0)
        s = measure(x, noise=0.005, bits=12, random_state=0)
        common = {"m": ms, "n_queries": args.queries, "random_state": 0, "n_jobs": args.n_jobs}
        fast, t_fast, mem_fast, cpu_fast = timed(forecast_error_curve, series=s, tau=taus,
                                                 **common)
        print(f"N={n}: candidates {t_fast:.0f} s wall, {cpu_fast:.0f} s CPU", flush=True)
        plain, t_plain, mem_plain, cpu_plain = timed(forecast_error_curve, series=s, tau=sub,
                                                     search="exact", **common)
        scale = len(taus) / len(sub)
        rel = (fast.loc[sub] / plain - 1).abs()
        dips = locate_dips(fast.loc[max(1, args.delay - 40):args.delay + 40])
        rows.append((n, t_fast, cpu_fast, mem_fast, t_plain, len(sub), t_plain * scale,
                     cpu_plain * scale, mem_plain, float(rel.max().max()),
                     float(rel.median().median()), fast.attrs["exact_fraction"], dips))
        print(f"N={n}: plain {t_plain:.0f} s wall, {cpu_plain:.0f} s CPU for {len(sub)} taus",
              flush=True)
    print()
    print(f"Delay scan m=2..5, tau=1..{args.max_tau} ({4 * len(taus)} models), "
          f"{args.queries} random query points, n_jobs={args.n_jobs}; Mackey-Glass delay "
          f"{args.delay}, 0.5 % noise, 12 bits.")
    print("| N | candidates: wall / CPU | peak RSS | plain rebuild: measured wall | "
          "all taus, extrapolated: wall / CPU | peak RSS | speed-up wall / CPU | "
          "rel. diff of sigma max / median |")
    print("|---|---|---|---|---|---|---|---|")
    for (n, tf, cf, mf, tp, ns, tpa, cpa, mp, rmax, rmed, _, _) in rows:
        print(f"| {n:.0e} | {tf:.0f} s / {cf:.0f} s | {mf:.2f} GB | {tp:.0f} s ({ns} taus) | "
              f"{tpa:.0f} s / {cpa:.0f} s (x{len(taus) / ns:.0f}) | {mp:.2f} GB | "
              f"{tpa / tf:.1f}x / {cpa / cf:.1f}x | {rmax:.3f} / {rmed:.3f} |")
    for (n, *_, exact, dips) in rows:
        print(f"\nN={n:.0e}: queries whose candidate neighbours are provably the exact k-NN (mean over tau): {exact}")
        print(f"delay by m (true {args.delay}):")
        print(dips.round(2).to_string())


if __name__ == "__main__":
    main()
