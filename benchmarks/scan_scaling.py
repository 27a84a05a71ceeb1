"""Parallel scaling of the delay scan: 1 vs n workers (Amdahl serial fraction) and Dask.

For each record length (``--n``, default 10^5 with tau = 1..200 and 10^6 with
tau = 1..500; Mackey-Glass, 0.5 % noise, 12 bits, delay 100 / 150) the
default scan (``forecast_error_curve``, m = 2..5, 10^4 coarse queries,
refined at the dip) is timed in the same run

* with ``n_jobs=1`` (T1) and ``n_jobs=n`` (Tn) for each ``n`` of ``--workers``
  (in the order given, after T1), the scan's default
  backend (``threading``: every task is a nogil compiled kernel) or, with
  ``--backend loky``, loky processes (the lists go out as memory maps);
* with ``--dask-workers`` Dask workers (``dask.distributed.LocalCluster``, one
  thread each, ``joblib.parallel_config(backend="dask")``), unless dask is
  missing (the row then says so) or ``--no-dask``.

The serial fraction is Amdahl's ``f`` from ``Tn = T1 (f + (1 - f) / n)``,
i.e. ``f = (n Tn / T1 - 1) / (n - 1)``.  Every row's sigma table is compared
with the ``n_jobs=1`` table (``max |sigma / sigma_1 - 1|``; 0 means the same
table).  CPU time is user + system of this process and all its children
(loky or Dask workers).  Timings on a shared machine are upper bounds: the
load average is printed before and after each row.

The parallel efficiency is ``T1 / (n Tn)``.  The column "wall with < n - 0.5
cores busy" sums the 0.2 s sampling intervals in which the process tree used
fewer than ``n - 0.5`` cores on average (and their mean busy cores): the
part of Tn that did not run in parallel, where it sits.

Run (2 cores)::

    nice -n 10 python benchmarks/scan_scaling.py --n 100000 1000000

and on a 16-core machine (largest count first, so a run cut short keeps it)::

    python benchmarks/scan_scaling.py --n 1000000 --workers 16 8 4 2
"""

from __future__ import annotations

import argparse
import os
import time

import joblib
import numpy as np
from delay_scan import series, timed_usage

from skdelay import forecast_error_curve

GRIDS = {100_000: (range(1, 201), 100), 1_000_000: (range(1, 501), 150)}


def load():
    return " / ".join(f"{v:.1f}" for v in os.getloadavg())


def scan(s, taus, n_jobs, queries):
    return forecast_error_curve(s, m=(2, 3, 4, 5), tau=taus, n_queries=queries,
                                random_state=0, n_jobs=n_jobs)


def dask_client(n_workers):
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError as exc:
        return None, f"dask.distributed is not installed ({exc}); pip install dask distributed"
    cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                           dashboard_address=None)
    return Client(cluster), None


def row(label, n, workers, wall, usage, t1, ref, fe, ld):
    cpu = usage.cpu
    low, busy = usage.idle_time(workers)
    idle = "-" if workers == 1 else f"{low:.1f} s ({busy:.1f} cores)"
    if t1 is None or workers == 1:
        speed, eff, f = "1", "1", "-"
    else:
        speed = f"{t1 / wall:.2f}x"
        eff = f"{t1 / (workers * wall):.0%}"
        f = f"{(workers * wall / t1 - 1) / (workers - 1):.3f}"
    diff = float(np.nanmax(np.abs(fe.to_numpy() / ref.to_numpy() - 1)))
    print(f"| {n} | {label} | {workers} | {wall:.1f} s | {cpu:.1f} s | {speed} | {eff} | {f} | "
          f"{idle} | {diff:.1e} | {ld} |", flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--workers", type=int, nargs="+", default=[2],
                        help="worker counts timed after n_jobs = 1 (default: 2)")
    parser.add_argument("--dask-workers", type=int, default=None,
                        help="Dask LocalCluster workers (default: the first of --workers)")
    parser.add_argument("--queries", type=int, default=10_000)
    parser.add_argument("--no-dask", action="store_true")
    parser.add_argument("--backend", choices=("threading", "loky"), default="threading",
                        help="joblib backend of the T1 / Tn rows (default: the scan's own, "
                             "threads)")
    parser.add_argument("--dask-n", type=int, nargs="*", default=None,
                        help="record lengths with a Dask row (default: all of --n)")
    args = parser.parse_args()
    dask_n = args.n if args.dask_n is None else args.dask_n
    dask_workers = args.workers[0] if args.dask_workers is None else args.dask_workers
    warm = series(4000, 20)
    print(f"# scan_scaling: m = 2..5, {args.queries} coarse queries, refined at the dip, "
          f"k = 30; load average at start {load()}")
    print(f"# {os.cpu_count()} CPUs, {len(os.sched_getaffinity(0))} usable by this process")
    print("| N | backend | workers | wall | CPU | T1 / Tn | efficiency T1 / (n Tn) | "
          "serial fraction f | wall with < n - 0.5 cores busy | max abs(sigma / sigma_1 - 1) | "
          "load before -> after |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    client, why = (None, "skipped (--no-dask)") if args.no_dask else (None, None)
    try:
        for n in args.n:
            taus, delay = GRIDS.get(n, (range(1, 201), 100))
            s = series(n, delay)
            results = {}
            for workers in [1] + [w for w in args.workers if w != 1]:
                with joblib.parallel_config(backend=args.backend):
                    scan(warm, range(1, 30), workers, 300)  # workers up, kernels loaded
                    ld = load()
                    fe, wall, usage = timed_usage(scan, s, taus, workers, args.queries)
                results[workers] = (fe, wall)
                row(args.backend, n, workers, wall, usage, results[1][1], results[1][0], fe,
                    f"{ld} -> {load()}")
            if args.no_dask or n not in dask_n:
                continue
            if client is None and why is None:
                client, why = dask_client(dask_workers)
            if client is None:
                print(f"| {n} | dask | {dask_workers} | {why} | | | | | | |", flush=True)
                continue
            with joblib.parallel_config(backend="dask"):
                scan(warm, range(1, 30), -1, 300)
                ld = load()
                fe, wall, usage = timed_usage(scan, s, taus, -1, args.queries)
            row("dask LocalCluster", n, dask_workers, wall, usage, results[1][1],
                results[1][0], fe, f"{ld} -> {load()}")
            same = np.array_equal(fe.to_numpy(), results[1][0].to_numpy()) and \
                np.array_equal(fe.attrs["se"].to_numpy(), results[1][0].attrs["se"].to_numpy())
            print(f"# N = {n}: dask table identical to n_jobs = 1 (sigma and se, bit for bit): "
                  f"{same}", flush=True)
    finally:
        if client is not None:
            client.close()
    print(f"# load average at end {load()}; run {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")


if __name__ == "__main__":
    main()
