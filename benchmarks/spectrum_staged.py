"""Staged choice of the spectrum model on the embedded laser data, and its spectrum.

Run: ``python benchmarks/spectrum_staged.py --delay 50 --runs 40 --seed 0`` (15-100 s
per delay with 40 runs on 2 cores).

:func:`skdelay.model_selection.select_spectrum_model` scores every setting of its grid
(model step x window span x neighbours x ridge) by cross-validated free runs; on the
full grid that took 8-30 minutes per delay (``benchmarks/out/spectrum_settings.txt``).
:func:`skdelay.model_selection.select_spectrum_model_staged` makes the choice in two
cheaper stages, and this script prints them:

1. model step and window span, at one neighbourhood size and ridge (``--k1``,
   ``--ridge1``);
2. neighbours and ridge (``--k2`` x ``--ridge2``) at the chosen step and span.

It prints both stages' tables (``error``: the cross-validated RMS error of the free
runs, in standard deviations), the selection's time, and the chosen model's spectrum
beside the shipped exact one (per ms).  The exact spectrum is only printed: nothing
here is chosen against it.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from skdelay.datasets import laser_exact_spectrum, load_laser
from skdelay.model_selection import select_spectrum_model_staged, spectrum_of_selection


def _floats(text):
    return tuple(float(v) for v in text.split(","))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--delay", type=int, default=50, help="50, 150 or 400 (us)")
    parser.add_argument("--runs", type=int, default=40, help="free runs scored per fold")
    parser.add_argument("--seed", type=int, default=0, help="seeds the scored start points")
    parser.add_argument("--k1", type=int, default=100, help="neighbours in stage 1")
    parser.add_argument("--ridge1", type=float, default=1e-2, help="ridge in stage 1")
    parser.add_argument("--k2", default="50,100,200", help="neighbours tried in stage 2")
    parser.add_argument("--ridge2", default="1e-3,1e-2,1e-1", help="ridges tried in stage 2")
    parser.add_argument("--horizon", type=int, default=None,
                        help="samples of the scored free runs (default: the selection's, "
                             "HORIZON_DELAYS delays)")
    parser.add_argument("--n-jobs", type=int, default=2)
    args = parser.parse_args(argv)

    data = load_laser(delay=args.delay, n_samples=100_000)
    s = np.asarray(data.series, dtype=float)
    t0 = time.perf_counter()
    sel = select_spectrum_model_staged(
        s, args.delay, n_neighbors=tuple(int(k) for k in _floats(args.k2)),
        ridge=_floats(args.ridge2), first=(args.k1, args.ridge1), horizon=args.horizon,
        n_runs=args.runs, random_state=args.seed, n_jobs=args.n_jobs)
    t2 = time.perf_counter()
    n_exp = 20 if args.delay < 300 else 45
    spec = spectrum_of_selection(s, sel, n_exponents=n_exp, n_steps=40_000 // sel.step,
                                 sample_dt=float(data.sample_dt), flow=True,
                                 n_jobs=args.n_jobs)
    exact = laser_exact_spectrum(args.delay)
    cols = ["step", "m", "span", "n_neighbors", "ridge", "error", "chosen"]
    print(f"tau0 = {args.delay} us, {s.size} samples, {args.runs} runs per fold, seed "
          f"{args.seed}; dominant period {sel.period} samples")
    for stage in (1, 2):
        print(f"stage {stage}:")
        print(sel.table[sel.table.stage == stage].sort_values("error")[cols]
              .to_string(index=False))
    print(f"selection: {t2 - t0:.0f} s")
    print("chosen:", sel.describe())
    rows = [("model", spec)] + ([("exact", exact)] if exact is not None else [])
    for name, sp in rows:
        print(f"{name:>5}: N+ {sp.n_positive:3d}  lambda_max {1e3 * sp.exponents[0]:6.2f}  "
              f"D_KY {sp.kaplan_yorke_dimension:6.2f}  h_KS {1e3 * sp.ks_entropy:6.2f}  (per ms)")


if __name__ == "__main__":
    main()
