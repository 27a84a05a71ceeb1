"""Delay scan: the project's compiled scan versus a plain k-d tree rebuild per cell.

(a) ``--part a``: 10^5 measured Mackey-Glass points (delay 100 samples, 0.5 %
noise, 12-bit ADC, sample step 1), m = 2..5, tau = 1..200, every point a
query.  Three scans, timed in the same run with the same ``--n-jobs``:

* **baseline** -- written here, independent of skdelay's kernels: for every
  (m, tau) a ``scipy.spatial.cKDTree`` on the 2m-dimensional vectors, a k-NN
  query of every point (Theiler-excluded) and a batched local linear fit in
  numpy (centred normal equations with the same relative ridge), one joblib
  task per cell.  It is run on ``--baseline-taus`` delays spread over the
  grid (plus the dip) and extrapolated linearly to all 200 (the table says so);
* **project, full precision** -- ``forecast_error_curve(..., n_queries=None,
  refine=False)`` on the whole grid (every point a query; the default
  ``search="auto"`` runs the exact tree search there), compared with the
  baseline (the exact search) on the baseline's cells;
* **project, default** -- the whole grid with a coarse pass of
  ``--queries`` random queries and refinement at the dips (every point a
  query there, until the dip centre's standard error is below 0.2 samples).

(c) ``--part c``: the coarse pass alone (``refine=False``) with the tree search,
the candidate lists and ``search="auto"``, at several record lengths and query
counts: the cost model behind the automatic choice.

(b) ``--part b``: the paper-scale run, 10^6 points (delay 150), m = 2..5, tau =
1..500, coarse 10^4 queries, refined at the dip: wall time, CPU time and peak
memory (PSS of the main process plus its joblib workers, sampled every 0.2 s).

The machine may be shared: the header records the load average before each run.

Run (2 cores)::

    nice -n 10 python benchmarks/delay_scan.py --part a --n-jobs 2
    nice -n 10 python benchmarks/delay_scan.py --part a --n-jobs 2 --quick   # ratios only
    nice -n 10 python benchmarks/delay_scan.py --part b --n-jobs 2
    nice -n 10 python benchmarks/delay_scan.py --part c --n-jobs 1
"""

from __future__ import annotations

import argparse
import os
import threading
import time

import numpy as np
import psutil
from joblib import Parallel, delayed
from scipy.spatial import cKDTree

from skdelay import forecast_error_curve, locate_dips, required_lags, two_window_columns
from skdelay.systems import MackeyGlass, measure

RIDGE = 1e-3
K = 30


class Usage:
    """Peak memory and CPU time of this process and its children (sampled).

    Memory is the peak of the summed PSS (proportional set size, every 0.2 s:
    pages shared between processes -- the memory-mapped candidate lists the
    workers read -- are split between them, so the sum is the physical memory
    used; RSS where PSS is not available); CPU time is
    the user + system time spent during the block by this process and by every
    child seen (joblib's loky workers persist between calls, so their times are
    deltas).  ``timeline`` holds ``(wall, CPU so far)`` at every sample, from
    which :meth:`idle_time` reads how long fewer cores than given were busy.
    """

    def __init__(self, interval=0.2):
        self.interval = interval
        self.peak = 0
        self._first, self._last = {}, {}
        self.timeline = []
        self._stop = threading.Event()

    @staticmethod
    def _cpu(proc):
        t = proc.cpu_times()
        return t.user + t.system

    @staticmethod
    def _memory(proc):
        try:
            return proc.memory_full_info().pss
        except (AttributeError, psutil.Error):
            return proc.memory_info().rss

    def _poll(self):
        me = psutil.Process()
        total = 0
        for proc in [me, *me.children(recursive=True)]:
            try:
                cpu = self._cpu(proc)
                total += self._memory(proc)
            except psutil.Error:
                continue
            self._first.setdefault(proc.pid, cpu)
            self._last[proc.pid] = cpu
        self.peak = max(self.peak, total)
        self.timeline.append((time.perf_counter(), self.cpu))

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

    def idle_time(self, n_cores):
        """Seconds (wall) of the sampling intervals in which fewer than ``n_cores - 0.5``
        cores were busy on average, and the mean busy cores in them."""
        low_wall = low_cpu = 0.0
        for (t0, c0), (t1, c1) in zip(self.timeline, self.timeline[1:]):
            if t1 > t0 and (c1 - c0) / (t1 - t0) < n_cores - 0.5:
                low_wall += t1 - t0
                low_cpu += c1 - c0
        return low_wall, (low_cpu / low_wall if low_wall else float("nan"))


def timed(fn, *args, **kwargs):
    out, wall, usage = timed_usage(fn, *args, **kwargs)
    return out, wall, usage.peak / 2**30, usage.cpu


def timed_usage(fn, *args, **kwargs):
    """``(result, wall seconds, Usage)`` of one call."""
    with Usage() as usage:
        t0 = time.perf_counter()
        out = fn(*args, **kwargs)
        wall = time.perf_counter() - t0
    return out, wall, usage


# ----------------------------------------------------------------------------- baseline
def baseline_cell(s, m, tau, k, theiler, ridge, first, chunk=20_000):
    """rms one-step error of one cell: k-d tree rebuild + batched local linear fits (numpy).

    Rows are the times ``first .. len(s) - 2`` (``first``: the largest lag of the grid,
    as in the project's scan); every row is a query and a neighbour.
    """
    cols = two_window_columns(m, tau)
    t = np.arange(first, s.size - 1)
    V = s[t[:, None] - cols]
    tree = cKDTree(V)
    kq = k + 2 * theiler + 1
    p = cols.size
    sq = 0.0
    for lo in range(0, t.size, chunk):
        q = slice(lo, min(lo + chunk, t.size))
        _, pos = tree.query(V[q], k=kq)
        keep = np.abs(pos - np.arange(q.start, q.stop)[:, None]) > theiler
        pos = np.take_along_axis(pos, np.argsort(~keep, axis=1, kind="stable")[:, :k], 1)
        Vn, yn = V[pos], s[t[pos] + 1]
        mu, ybar = Vn.mean(axis=1), yn.mean(axis=1)
        D = Vn - mu[:, None, :]
        G = np.einsum("nki,nkj->nij", D, D)
        rhs = np.einsum("nki,nk->ni", D, yn - ybar[:, None])
        lam = ridge * np.trace(G, axis1=1, axis2=2) / p
        G[:, np.arange(p), np.arange(p)] += lam[:, None]
        a = np.linalg.solve(G, rhs[..., None])[..., 0]
        pred = ybar + np.einsum("ni,ni->n", a, V[q] - mu)
        sq += float(np.sum((pred - s[t[q] + 1]) ** 2))
    return np.sqrt(sq / t.size) / s.std()


def baseline_scan(s, ms, taus, theiler, n_jobs, first):
    cells = [(m, tau) for m in ms for tau in taus]
    out = Parallel(n_jobs=n_jobs)(delayed(baseline_cell)(s, m, tau, K, theiler, RIDGE, first)
                                  for m, tau in cells)
    return np.array(out).reshape(len(ms), len(taus)).T


def load():
    return " / ".join(f"{v:.1f}" for v in os.getloadavg())


def series(n, delay):
    x = MackeyGlass(tau=float(delay)).simulate(n, random_state=0)
    return measure(x, noise=0.005, bits=12, random_state=0)


# ----------------------------------------------------------------------------- parts
def part_a(args):
    ms, taus = (2, 3, 4, 5), np.arange(1, 201)
    s = series(args.n_a, 100)
    sub = np.unique(np.r_[np.linspace(1, 200, args.baseline_taus).round().astype(int), 100])
    warm = series(4000, 20)  # start the workers and load the compiled kernels
    forecast_error_curve(warm, m=ms, tau=range(1, 30), n_queries=300, n_jobs=args.n_jobs)
    baseline_cell(warm, 2, 5, K, 5, RIDGE, 10)
    common = {"m": ms, "n_neighbors": K, "ridge": RIDGE, "random_state": 0,
              "n_jobs": args.n_jobs}
    print(f"# (a) load average before: {load()}", flush=True)
    default = None
    if not args.quick:
        default, t_def, mem_def, cpu_def = timed(forecast_error_curve, s, tau=taus,
                                                 n_queries=args.queries, **common)
        print(f"project default: {t_def:.1f} s wall, {cpu_def:.1f} s CPU, "
              f"{mem_def:.2f} GB peak; load average after {load()}", flush=True)
    if args.default_only:
        print(locate_dips(default)[["delay", "delay_error", "centre_se", "tau_best", "z",
                                    "significant"]].round(3).to_string())
        print(f"provably exact neighbourhoods (per m): "
              f"{ {k: round(v, 4) for k, v in default.attrs['exact_fraction'].items()} }; "
              f"refined cells: {int((~default.attrs['coarse']).sum().sum())}")
        return
    full_taus = sub if args.quick else taus
    full, t_full, _, cpu_full = timed(forecast_error_curve, s, tau=full_taus, refine=False,
                                      **common)
    w = int(full.attrs["theiler_window"])
    print(f"project full precision ({full_taus.size} taus): {t_full:.1f} s wall", flush=True)
    first = required_lags(5, 200) - 1  # the rows of the project's scan of this grid
    base, t_base, _, cpu_base = timed(baseline_scan, s, ms, sub, w, args.n_jobs, first)
    print(f"baseline ({sub.size} taus): {t_base:.1f} s wall", flush=True)
    base = np.asarray(base)
    scale, full_scale = taus.size / sub.size, taus.size / full_taus.size
    rel_full = np.abs(full.loc[sub].to_numpy() / base - 1)
    print()
    print(f"(a) N = {s.size}, m = 2..5, tau = 1..200 (800 cells), k = {K}, Theiler {w}, "
          f"n_jobs = {args.n_jobs}; Mackey-Glass delay 100, 0.5 % noise, 12 bits; "
          f"load average before the run {load()} (2 shared cores).")
    print("| scan | cells timed | wall | CPU | wall / CPU for 800 cells | "
          "speed-up vs baseline, wall / CPU |")
    print("|---|---|---|---|---|---|")
    tb, cb = t_base * scale, cpu_base * scale
    print(f"| baseline: cKDTree rebuild + numpy fit, every point a query | {sub.size * 4} | "
          f"{t_base:.1f} s | {cpu_base:.1f} s | {tb:.0f} s / {cb:.0f} s (extrapolated "
          f"x{scale:.1f}) | 1 |")
    tf, cf = t_full * full_scale, cpu_full * full_scale
    how = "(measured)" if full_scale == 1 else f"(extrapolated x{full_scale:.1f})"
    print(f"| project, full precision (every point a query) | {full_taus.size * 4} | "
          f"{t_full:.1f} s | {cpu_full:.1f} s | {tf:.0f} s / {cf:.0f} s {how} | "
          f"{tb / tf:.1f}x / {cb / cf:.1f}x |")
    if default is not None:
        print(f"| project, default ({args.queries} coarse queries, refined at the dip) | 800 | "
              f"{t_def:.1f} s | {cpu_def:.1f} s | {t_def:.0f} s / {cpu_def:.0f} s (measured) | "
              f"{tb / t_def:.1f}x / {cb / cpu_def:.1f}x |")
    print()
    print("accuracy against the baseline (the exact k-NN), |sigma / sigma_exact - 1| over the "
          "timed cells:")
    print(f"  full precision: median {np.median(rel_full):.4f}, max {rel_full.max():.4f}")
    print(f"  provably exact neighbourhoods (full precision, per m): "
          f"{ {k: round(v, 4) for k, v in full.attrs['exact_fraction'].items()} }")
    if default is None:
        return
    rel_def = np.abs(default.loc[sub].to_numpy() / base - 1)
    refined = ~default.attrs["coarse"].loc[sub].to_numpy()
    print(f"  default, refined cells ({refined.sum()}): "
          f"{_summary(rel_def[refined])}; coarse cells ({(~refined).sum()}): "
          f"{_summary(rel_def[~refined])} (includes the query subsampling; median "
          f"se/sigma of those cells "
          f"{np.median((default.attrs['se'] / default).loc[sub].to_numpy()[~refined]):.4f})")
    print(f"  peak memory (PSS, main + workers) of the default scan: {mem_def:.2f} GB")
    print("dips of the default scan (true delay 100):")
    print(locate_dips(default)[["delay", "delay_error", "centre_se", "tau_best", "z",
                                "significant"]].round(3).to_string())


def part_c(args):
    """The coarse pass under each search, and the choice of ``search="auto"``."""
    ms, taus = (2, 3, 4, 5), np.arange(1, args.c_taus + 1)
    cases = [tuple(int(float(v)) for v in c.split(":")) for c in args.c_cases]
    warm = series(4000, 20)  # load the compiled kernels
    for search in ("tree", "candidates"):
        forecast_error_curve(warm, m=ms, tau=range(1, 30), n_queries=300, search=search,
                             n_jobs=args.n_jobs)
    print(f"# (c) load average before: {load()}", flush=True)
    print(f"(c) coarse pass only (refine=False): Mackey-Glass delay 100, 0.5 % noise, 12 bits; "
          f"m = 2..5, tau = 1..{taus[-1]}, k = {K}, n_jobs = {args.n_jobs}.")
    print("| rows | queries | rows per query | tree | candidates | auto | auto chose | "
          "auto / faster of the two |")
    print("|---|---|---|---|---|---|---|---|")
    series_of = {}
    for n, q in cases:
        if n not in series_of:
            series_of[n] = series(n, 100)
        s = series_of[n]
        wall, chose = {}, ""
        for search in ("tree", "candidates", "auto"):
            curve, wall[search], _, _ = timed(forecast_error_curve, s, m=ms, tau=taus,
                                             n_queries=q, search=search, refine=False,
                                             n_neighbors=K, ridge=RIDGE, random_state=0,
                                             n_jobs=args.n_jobs)
            if search == "auto":  # the tree search is exact in every cell, the lists rarely
                exact = curve.attrs["exact"].to_numpy()
                chose = "tree" if bool((exact == 1).all()) else "candidates"
        best = min(wall["tree"], wall["candidates"])
        print(f"| {n} | {q} | {n / q:.0f} | {wall['tree']:.1f} s | {wall['candidates']:.1f} s | "
              f"{wall['auto']:.1f} s | {chose} | {wall['auto'] / best:.2f} |", flush=True)
    print(f"# load average after: {load()}")


def _summary(values):
    if values.size == 0:
        return "none"
    return f"median {np.median(values):.4f}, max {values.max():.4f}"


def part_b(args):
    ms, taus = (2, 3, 4, 5), range(1, 501)
    s = series(args.n_b, 150)
    warm = series(4000, 20)
    forecast_error_curve(warm, m=ms, tau=range(1, 30), n_queries=300, n_jobs=args.n_jobs)
    print(f"# (b) load average before: {load()}", flush=True)
    fe, wall, mem, cpu = timed(forecast_error_curve, s, m=ms, tau=taus, n_queries=args.queries,
                               random_state=0, n_jobs=args.n_jobs)
    from skdelay import locate_dips

    dips = locate_dips(fe)
    q = fe.attrs["queries"]
    print()
    print(f"(b) N = {s.size}, m = 2..5, tau = 1..500 (2000 cells), {args.queries} coarse queries, "
          f"refined at the dip, n_jobs = {args.n_jobs}; Mackey-Glass delay 150, 0.5 % noise, "
          f"12 bits; load average after the run {load()} (2 shared cores).")
    print("| wall | CPU | peak memory (PSS, main + workers) | refined cells | "
          "most queries in a cell |")
    print("|---|---|---|---|---|")
    print(f"| {wall:.0f} s | {cpu:.0f} s | {mem:.2f} GB | {int((~fe.attrs['coarse']).sum().sum())} "
          f"| {int(q.max().max())} |")
    print(f"provably exact neighbourhoods (per m): "
          f"{ {k: round(v, 4) for k, v in fe.attrs['exact_fraction'].items()} }")
    print(dips[["delay", "delay_error", "centre_se", "tau_best", "z", "significant"]]
          .round(3).to_string())
    if args.check_ms:
        check_dip(args, s, fe, dips)


def check_dip(args, s, fe, dips):
    """Dip centre and half-width against a full-precision scan of the dip region.

    For the m of ``--check-m``, every point is a query on ``tau = 150 -
    --check-reach .. 150 + --check-reach`` (``refine=False``); those cells replace the
    default scan's, and :func:`skdelay.locate_dips` runs on the spliced curve.
    """
    from skdelay import locate_dips

    lo, hi = 150 - args.check_reach, 150 + args.check_reach
    ms = tuple(args.check_ms)
    print(f"# full-precision check: m = {ms}, tau = {lo}..{hi}, every point a query; "
          f"load average before: {load()}", flush=True)
    full, wall, mem, cpu = timed(forecast_error_curve, s, m=ms, tau=range(lo, hi + 1),
                                 n_queries=None, refine=False, random_state=0,
                                 n_jobs=args.n_jobs)
    spliced = fe.loc[:, list(ms)].copy()
    spliced.loc[lo:hi, list(ms)] = full.to_numpy()
    se = fe.attrs["se"].loc[:, list(ms)].copy()
    se.loc[lo:hi, list(ms)] = full.attrs["se"].to_numpy()
    spliced.attrs["se"] = se
    ref = locate_dips(spliced)
    print(f"full-precision scan of the dip region: {wall:.0f} s wall, {cpu:.0f} s CPU, "
          f"{mem:.2f} GB; load average after {load()}")
    print("| m | centre (default) | centre (full precision) | difference | half-width "
          "(default) | half-width (full precision) | difference |")
    print("|---|---|---|---|---|---|---|")
    for m in ms:
        a, b = dips.loc[m], ref.loc[m]
        print(f"| {m} | {a['delay']:.3f} | {b['delay']:.3f} | {a['delay'] - b['delay']:+.3f} | "
              f"{a['half_width']:.3f} | {b['half_width']:.3f} | "
              f"{a['half_width'] - b['half_width']:+.3f} |")
    rel = np.abs(fe.loc[lo:hi, list(ms)].to_numpy() / full.to_numpy() - 1)
    print(f"|sigma_default / sigma_full - 1| on those cells: median {np.median(rel):.4f}, "
          f"max {rel.max():.4f}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--part", choices=["a", "b", "c"], default="a")
    parser.add_argument("--n-a", type=int, default=100_000)
    parser.add_argument("--n-b", type=int, default=1_000_000)
    parser.add_argument("--queries", type=int, default=10_000)
    parser.add_argument("--baseline-taus", type=int, default=6)
    parser.add_argument("--n-jobs", type=int, default=2)
    parser.add_argument("--quick", action="store_true",
                        help="(a) the full-precision scan on the baseline's taus only "
                             "(extrapolated like the baseline), no default scan")
    parser.add_argument("--default-only", action="store_true",
                        help="(a) time only the default scan (no full-precision or baseline rows)")
    parser.add_argument("--check-m", dest="check_ms", type=int, nargs="*", default=[],
                        help="(b) m values checked against a full-precision dip scan")
    parser.add_argument("--check-reach", type=int, default=10,
                        help="(b) the check scans tau = 150 +- this")
    parser.add_argument("--c-cases", nargs="*", metavar="ROWS:QUERIES",
                        default=["30000:500", "30000:2000", "100000:1000", "100000:4000",
                                 "100000:10000"],
                        help="(c) record lengths and coarse queries per cell")
    parser.add_argument("--c-taus", type=int, default=200, help="(c) scan tau = 1..this")
    args = parser.parse_args()
    {"a": part_a, "b": part_b, "c": part_c}[args.part](args)


if __name__ == "__main__":
    main()
