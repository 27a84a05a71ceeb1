"""Oversampled records: the sampling step chosen from the data, the coarser steps tried
when it shows no dip, and the delay found, against the truth.

``skdelay analyze`` takes every ``h``-th sample of a record whose second difference
drowns in measurement noise (``skdelay.model_selection.sampling_step``); where that step
still shows no significant forecast-error dip in a record that is smooth at its sampling
step, it tries 2, 4, 8 and 16 times the step, each at a stricter level, and keeps the
first with a significant dip.  This script runs ``analyze_series`` (the default scan: 4000
forecasts per cell, refined at the dip; the quick model stage) on records of systems,
steps and noise levels that no test uses, with fresh seeds (8.8e6 + j), and prints per
record the chosen step, the steps tried, the step used and, per window length, the delay
in record samples with its error bar against the truth.  Smooth noise without a delay is
included: its right answer is "no significant dip" at every step.

Run (2 cores, about 10 minutes)::

    python benchmarks/oversampled.py            # the default scan
    python benchmarks/oversampled.py --quick    # the quick preset's scan
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from skdelay import analyze_series
from skdelay.model_selection import sampling_step
from skdelay.systems import ElectroOpticOscillator, Ikeda, MackeyGlass, measure

SEED = 8_800_000


def delayed_only(g, n, per_delay, seed, substeps=5):
    """Heun steps of dx/dt = x(t-1) (g exp(-x(t-1)^2) - 1) (the right-hand side depends only
    on the delayed value), ``per_delay`` samples per delay, a random start."""
    rng = np.random.default_rng(seed)
    h = 1.0 / per_delay / substeps
    d = per_delay * substeps
    steps = (n + 4000) * substeps
    x = np.empty(steps + d + 1)
    x[: d + 1] = 1.0 + 0.1 * rng.standard_normal(d + 1)
    for i in range(d, d + steps):
        a, b = x[i - d], x[i - d + 1]
        x[i + 1] = x[i] + 0.5 * h * (a * (g * np.exp(-a * a) - 1.0)
                                     + b * (g * np.exp(-b * b) - 1.0))
    return x[d + 4000 * substeps::substeps][:n]


def smooth_noise(n, seed, width=20.0):
    """White noise through a Gaussian filter of ``width`` samples: smooth, no delay."""
    rng = np.random.default_rng(seed)
    half = int(4 * width)
    kernel = np.exp(-0.5 * (np.arange(-half, half + 1) / width) ** 2)
    return np.convolve(rng.standard_normal(n + 2 * half), kernel, mode="valid")


#: label -> (make(seed), delay in record samples or None, noise, sample_dt)
CASES = {
    "ikeda dt 0.01, 0.5 %": (lambda s: Ikeda().simulate(40_000, sample_dt=0.01, random_state=s),
                             500, 0.005, 0.01),
    "ikeda dt 0.02, 1 %": (lambda s: Ikeda().simulate(40_000, sample_dt=0.02, random_state=s),
                           250, 0.01, 0.02),
    "electro_optic dt 0.05, 0.5 %": (
        lambda s: ElectroOpticOscillator().simulate(40_000, sample_dt=0.05, random_state=s),
        400, 0.005, 0.05),
    "mackey_glass tau 23 dt 0.1, 2 %": (
        lambda s: MackeyGlass(tau=23.0).simulate(40_000, sample_dt=0.1, random_state=s),
        230, 0.02, 0.1),
    "delayed-only g 4.8, 60 per delay, 0.5 %": (lambda s: delayed_only(4.8, 30_000, 60, s),
                                                60, 0.005, 1.0),
    "smooth noise, no delay, 0.5 %": (lambda s: smooth_noise(40_000, s), None, 0.005, 1.0),
}


def run(label, seed, quick=False):
    make, delay, noise, dt = CASES[label]
    x = measure(make(seed), noise=noise, random_state=seed + 1)
    lo, hi = (40, 300) if delay is None else (int(0.7 * delay), int(1.3 * delay))
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scan = {} if quick else {"n_queries": 4000, "refine": True}
        res = analyze_series(x, m=(2, 3), tau_min=lo, tau_max=hi, sample_dt=dt, quick=True,
                             **scan)
    rows = []
    for m, r in res.delays.iterrows():
        est, err = r["delay"] * res.step, r["delay_error"] * res.step
        if not r["significant"]:
            rows.append(f"m={m}: no dip")
            continue
        if delay is None:
            rows.append(f"m={m}: {est:.1f} +- {err:.1f} FALSE DIP")
            continue
        off = est - delay
        rows.append(f"m={m}: {est:.1f} +- {err:.1f} ({off / res.step:+.2f} coarse"
                    f"{', outside its error bar' if abs(off) > err else ''})")
    return (f"| {label} | {seed} | {sampling_step(x)} | {', '.join(map(str, res.steps_tried))} "
            f"| {res.step} | {'-' if delay is None else delay} | {'; '.join(rows)} "
            f"| {time.perf_counter() - t0:.0f} s |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2, help="records per case")
    ap.add_argument("--only", default="", help="run the cases whose label contains this")
    ap.add_argument("--quick", action="store_true",
                    help="the quick preset's scan too (1500 forecasts per cell, no refinement)")
    args = ap.parse_args()
    print(f"# scan: {'quick (1500 forecasts per cell, no refinement)' if args.quick else 'default (4000 forecasts per cell, refined at the dip)'}")
    print("| record | seed | step chosen | steps tried | step used | delay (samples) "
          "| significant dips per m (record samples) | time |")
    print("|---|---|---|---|---|---|---|---|")
    for label in CASES:
        if args.only and args.only not in label:
            continue
        for j in range(args.seeds):
            print(run(label, SEED + j, args.quick), flush=True)


if __name__ == "__main__":
    main()
