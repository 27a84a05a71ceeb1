"""The gap diagnosis's forecast-error curves: plain k-d tree against the scan's tree search.

The diagnosis reads sigma_2(tau) of every run it compares (400 queries, 20
neighbours, refined at the dip, on at most 10^4 samples): its ``forecast_error``
indicator and the dips of the record and the clean runs.  Both searches return
the exact neighbourhoods; this prints the time of one curve with each (median of
``--repeats``, the two alternating in one run) and the largest relative
difference of sigma and of its standard error.

    python benchmarks/fe_curve_search.py
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd

from skdelay import forecast_error_curve
from skdelay.systems import CO2LaserFeedback, Ikeda, MackeyGlass

CASES = [("co2_laser tau 150", CO2LaserFeedback(tau=150.0), 1.0, 10_000),
         ("ikeda step 0.25", Ikeda(), 0.25, 6000),
         ("mackey_glass tau 17", MackeyGlass(tau=17.0), 1.0, 6000)]


def grid(delay):
    """The indicator's lags: every lag within 5 of the delay, and 7 geometric ones."""
    t0 = round(delay)
    dense = np.arange(max(1, t0 - 5), t0 + 6)
    return np.unique(np.r_[dense, np.geomspace(1, 2.2 * t0 + 2, 7).astype(int)]).tolist()


def curve(z, taus, search):
    c = forecast_error_curve(z, m=(2,), tau=taus, n_queries=400, n_neighbors=20,
                             search=search, random_state=0, refine=True)
    return np.asarray(c.iloc[:, 0]), np.asarray(c.attrs["se"].iloc[:, 0])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    rows = []
    for name, system, dt, n in CASES:
        clean = system.simulate(n, sample_dt=dt, random_state=1)
        for noise in (0.0, 0.1):
            x = clean + np.random.default_rng(0).normal(0, noise * clean.std(), n)
            z = (x - x.mean()) / x.std()
            taus = grid(system.params["tau"] / dt)
            times = {"exact": [], "tree": []}
            for _ in range(args.repeats):
                for search, spent in times.items():
                    t0 = time.perf_counter()
                    out = curve(z, taus, search)
                    spent.append(time.perf_counter() - t0)
                    if search == "exact":
                        ref = out
            rows.append({"system": name, "noise (std)": noise, "taus": len(taus),
                         "exact ms": 1e3 * np.median(times["exact"]),
                         "tree ms": 1e3 * np.median(times["tree"]),
                         "exact / tree": np.median(times["exact"]) / np.median(times["tree"]),
                         "sigma max rel diff": np.max(np.abs(out[0] / ref[0] - 1)),
                         "se max rel diff": np.max(np.abs(out[1] / ref[1] - 1))})
    with pd.option_context("display.width", 160, "display.float_format", "{:.3g}".format):
        print(pd.DataFrame(rows).to_string(index=False))


if __name__ == "__main__":
    main()
