"""The scan's refinement driven by the batch or the redraw centre error, in one run.

``forecast_error_curve`` refines the taus around each dip until the centre's
standard error is below 0.2 samples (``centre_error="batches"``: the query
batches resampled, the default; ``"redraws"``: each cell redrawn within its
own standard error, the gap diagnosis's calibration).  For each case
(Mackey-Glass, 12 bit, m = 2..5, 2000 coarse queries) both modes run
alternately (``--repeats`` times each, after one warm-up scan that compiles
the kernels) and the table prints the median wall time, the refined cells,
the forecasts, and per m the centres and centre errors of both, with the
ratio of the times.

Cases: tau = 17 clean scanned to 384 (a wide scan, as the analysis's default
range to 1.25x the strongest autocorrelation revival asks) and tau = 100 with
1 % noise scanned to 250.

Usage::

    python benchmarks/refine_centre_error.py [--n 100000] [--repeats 1]
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
import pandas as pd

from skdelay import forecast_error_curve, locate_dips
from skdelay.systems import MackeyGlass, measure

CASES = [("mackey_glass tau=17 clean", 17.0, 0.0, 384), ("mackey_glass tau=100 1 %", 100.0, 0.01, 250)]
MODES = ("redraws", "batches")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100_000)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--queries", type=int, default=2000)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    forecast_error_curve(np.sin(0.3 * np.arange(3000)) + 0.01 * np.cos(np.arange(3000) ** 1.5),
                         m=(2, 3), tau=range(1, 30), n_queries=200, random_state=0)  # compile
    rows = []
    for name, tau, noise, tmax in CASES:
        s = measure(MackeyGlass(tau=tau).simulate(args.n, random_state=5), noise=noise, bits=12,
                    random_state=6)
        times = {mode: [] for mode in MODES}
        out = {}
        for _ in range(args.repeats):
            for mode in MODES:
                t0 = time.perf_counter()
                fe = forecast_error_curve(s, m=(2, 3, 4, 5), tau=range(1, tmax + 1),
                                          n_queries=args.queries, centre_error=mode,
                                          random_state=0)
                times[mode].append(time.perf_counter() - t0)
                out[mode] = fe
        for mode in MODES:
            fe = out[mode]
            dips = locate_dips(fe)
            rows.append({
                "case": name, "centre_error": mode,
                "seconds": round(float(np.median(times[mode])), 1),
                "refined cells": int((~fe.attrs["coarse"]).to_numpy().sum()),
                "forecasts": int(fe.attrs["queries"].to_numpy().sum()),
                "centres": " ".join(f"{v:.2f}" for v in dips["delay"]),
                "centre_se": " ".join(f"{v:.2f}" for v in dips["centre_se"]),
            })
        print(pd.DataFrame(rows[-2:]).to_string(index=False), flush=True)
        print(f"time redraws / batches: "
              f"{np.median(times['redraws']) / np.median(times['batches']):.2f}", flush=True)
    print()
    print(f"# python benchmarks/refine_centre_error.py --n {args.n} --repeats {args.repeats}")
    print(pd.DataFrame(rows).to_string(index=False))


if __name__ == "__main__":
    main()
