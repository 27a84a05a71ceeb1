"""The scan's tree search against the plain k-d tree per delay: same bits, time per curve.

One forecast-error curve (m = 2, 20 neighbours, 400 queries, 40 delays, refined at the
dip) per system and noise level, as the gap diagnosis computes it on each run, with
``search="tree"`` and ``search="exact"`` in the same process, alternating, best of
``--repeat``.  Prints whether sigma and its standard error are bit-identical, and the
time ratio.

    python benchmarks/tree_search_bits.py [--repeat 3]
"""

import argparse
import time

import numpy as np

from skdelay import forecast_error_curve
from skdelay.systems import ElectroOpticOscillator, Ikeda, MackeyGlass


def curve(z, search):
    t = time.perf_counter()
    c = forecast_error_curve(z, m=(2,), tau=list(range(1, 120, 3)), n_queries=400,
                             n_neighbors=20, search=search, random_state=0, refine=True)
    return (np.asarray(c.iloc[:, 0]), np.asarray(c.attrs["se"].iloc[:, 0]),
            time.perf_counter() - t)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    systems = [("Ikeda, step 0.25", Ikeda(), 0.25), ("Mackey-Glass", MackeyGlass(), 1.0),
               ("electro-optic, step 0.25", ElectroOpticOscillator(), 0.25)]
    warm = MackeyGlass().simulate(2000, random_state=1)
    curve(warm, "tree"), curve(warm, "exact")  # compile outside the timings
    print(f"{'system (6000 samples)':26s} {'noise':>5s} {'exact ms':>9s} {'tree ms':>8s} "
          f"{'ratio':>6s}  bit-identical (sigma, se)")
    for name, system, dt in systems:
        x = system.simulate(6000, sample_dt=dt, random_state=3)
        for noise in (0.0, 0.1):
            y = x + noise * x.std() * rng.standard_normal(x.size)
            z = (y - y.mean()) / y.std()
            best = {"exact": np.inf, "tree": np.inf}
            out = {}
            for _ in range(args.repeat):
                for search in ("exact", "tree"):
                    out[search] = curve(z, search)
                    best[search] = min(best[search], out[search][2])
            same = (np.array_equal(out["exact"][0], out["tree"][0]),
                    np.array_equal(out["exact"][1], out["tree"][1]))
            print(f"{name:26s} {noise:5.2f} {best['exact'] * 1e3:9.0f} "
                  f"{best['tree'] * 1e3:8.0f} {best['exact'] / best['tree']:6.2f}  {same}")


if __name__ == "__main__":
    main()
