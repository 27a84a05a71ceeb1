"""Does the minimal faithful m depend on the draw of the free runs' starting histories?

For Mackey-Glass with tau = 17, 23, 30 at 10^5 samples, clean and with 1 % and 5 %
Gaussian measurement noise (the records of ``benchmarks/faithful_noise.py``, same
seeds), runs :func:`skdelay.dynamics.minimal_embedding` (m = 1..5, delays from the
data's own dips, default model settings) once per ``random_state`` and prints m_d, each
model's verdict (``+`` faithful, ``~`` marginal, ``-`` not), the runs behind each
verdict and the time.  A trustworthy verdict is the same for every ``random_state``;
the must-show of the issue is m_d within +-1 across the noise levels of one system.

Run it with the ``skdelay`` to be measured first on the path (e.g. ``PYTHONPATH`` set to
a checkout of an earlier commit) to compare two versions on the same records.

Usage::

    python benchmarks/faithful_runs.py [--n 100000] [--taus 17 23 30]
        [--noise 0 0.01 0.05] [--random-states 1 2 3]
"""

from __future__ import annotations

import argparse
import os
import time

import pandas as pd

import skdelay
from skdelay import forecast_error_curve, locate_dips
from skdelay.dynamics import minimal_embedding
from skdelay.systems import MackeyGlass, measure


def _verdicts(table):
    marginal = table["marginal"] if "marginal" in table else pd.Series(False, table.index)
    return " ".join("+" if f else ("~" if g else "-")
                    for f, g in zip(table["faithful"], marginal))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100_000)
    parser.add_argument("--taus", type=int, nargs="+", default=[17, 23, 30])
    parser.add_argument("--noise", type=float, nargs="+", default=[0.0, 0.01, 0.05])
    parser.add_argument("--random-states", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--seed", type=int, default=2024, help="seed of the records")
    args = parser.parse_args(argv)
    print(f"skdelay from {os.path.dirname(skdelay.__file__)}; load average at start "
          f"{os.getloadavg()[0]:.2f}", flush=True)
    rows = []
    for tau in args.taus:
        clean = MackeyGlass(tau=float(tau)).simulate(args.n, random_state=args.seed)
        for noise in args.noise:
            x = measure(clean, noise=noise, random_state=args.seed + 1) if noise else clean
            grid = range(max(1, tau - 12), tau + 13)
            dips = locate_dips(forecast_error_curve(x, m=(1, 2, 3, 4, 5), tau=grid,
                                                    n_queries=5000, random_state=args.seed))
            taus = {int(m): int(dips.loc[m, "tau_best"]) for m in dips.index}
            for rs in args.random_states:
                t0 = time.perf_counter()
                res = minimal_embedding(x, tau=taus, m_max=5, random_state=rs)
                tab = res.table
                runs = list(tab["n_runs"]) if "n_runs" in tab else [len(res.runs[m]) for m in tab.index]
                rows.append({"tau": tau, "noise": noise, "random_state": rs,
                             "m_d": "none" if res.m_d is None else res.m_d,
                             "verdicts m=1..5": _verdicts(tab),
                             "runs m=1..5": " ".join(map(str, runs)),
                             "seconds": round(time.perf_counter() - t0, 1)})
                print(" ".join(f"{k}={v}" for k, v in rows[-1].items()), flush=True)
                for m in tab.index:
                    if not tab.loc[m, "faithful"]:
                        print(f"    m={m}: {tab.loc[m, 'status']}", flush=True)
    table = pd.DataFrame(rows)
    print()
    print(table.to_string(index=False))
    print()
    summary = (table.groupby(["tau", "noise"])["m_d"]
               .agg(lambda v: " ".join(map(str, v))).unstack("noise"))
    print("m_d per random_state (columns: noise):")
    print(summary.to_string())
    print(f"load average at end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
