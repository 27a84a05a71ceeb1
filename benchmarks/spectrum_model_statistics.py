"""Do the free runs' statistics separate the spectrum-model settings their errors cannot?

Run: ``python benchmarks/spectrum_model_statistics.py --delay 50`` (about 2 minutes per
delay on 2 cores; ``--seed S`` simulates a fresh laser record instead of the embedded
one).

The second stage of :func:`skdelay.model_selection.select_spectrum_model_staged`
(neighbours x ridge at step 1, window m = 14, the choice at every delay of the
embedded laser) scores its settings within about one standard error of each other,
while their largest Lyapunov exponents differ by nearly a factor of two.  For each
setting this script fits the model on the whole record, runs it freely
(``--runs`` runs of ``--length`` steps after 500 steps of transient, values clipped
to the data's range) and prints the median histogram (Hellinger) and power-spectrum
distances of the runs to data segments of the same length, beside the same
distances between pairs of data segments (the band a faithful model stays in), and
the setting's lambda_max (per ms).  The exact spectrum is printed only for
comparison: nothing here is chosen.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from sklearn.pipeline import Pipeline

from skdelay import LocalLinearDelayMap, TwoWindowEmbedding, lagged_windows, required_lags
from skdelay.datasets import (
    LASER_BITS,
    LASER_DYNAMICAL_NOISE,
    LASER_MEASUREMENT_NOISE,
    laser_exact_spectrum,
    load_laser,
)
from skdelay.dynamics import iterate, lyapunov_spectrum
from skdelay.systems import measure
from skdelay.validation import histogram_distance, spectrum_distance


def record(delay, seed):
    if seed is None:
        return np.asarray(load_laser(delay=delay, n_samples=100_000).series, dtype=float)
    system = load_laser(delay, n_samples=1000, cache=False).system
    x = system.simulate(100_000, sample_dt=1.0, random_state=seed,
                        dynamical_noise=LASER_DYNAMICAL_NOISE)
    return measure(x, noise=LASER_MEASUREMENT_NOISE, bits=LASER_BITS, normalise=True,
                   random_state=seed + 1)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--delay", type=int, default=50, help="50, 150 or 400 (us)")
    parser.add_argument("--seed", type=int, default=None,
                        help="simulate a fresh record with this seed (default: embedded data)")
    parser.add_argument("--m", type=int, default=14, help="window length (step 1)")
    parser.add_argument("--k", default="50,100,200", help="neighbourhood sizes")
    parser.add_argument("--ridge", default="1e-3,1e-2,1e-1", help="relative ridges")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--length", type=int, default=10_000)
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    s = record(args.delay, args.seed)
    segs = [s[i * args.length:(i + 1) * args.length] for i in range(s.size // args.length)]
    pairs = [(i, j) for i in range(len(segs)) for j in range(i + 1, len(segs))][:28]
    ref_h = [histogram_distance(segs[i], segs[j]).distance for i, j in pairs]
    ref_s = [spectrum_distance(segs[i], segs[j]).distance for i, j in pairs]
    print(f"tau0 = {args.delay} us, {'embedded data' if args.seed is None else 'seed ' + str(args.seed)}"
          f", m = {args.m} at step 1, {args.runs} runs of {args.length} steps per setting")
    print(f"data segment vs data segment ({len(pairs)} pairs): histogram median "
          f"{np.median(ref_h):.4f}, max {np.max(ref_h):.4f}; spectrum median "
          f"{np.median(ref_s):.4f}, max {np.max(ref_s):.4f}")
    n_lags = required_lags(args.m, args.delay)
    X, y = lagged_windows(s, n_lags)
    rng = np.random.default_rng(0)
    print(" k      ridge  histogram  spectrum  stopped  lambda_max [1/ms]  seconds")
    for k in (int(v) for v in args.k.split(",")):
        for ridge in (float(v) for v in args.ridge.split(",")):
            t0 = time.perf_counter()
            model = Pipeline([("embedding", TwoWindowEmbedding(m=args.m, tau=args.delay)),
                              ("model", LocalLinearDelayMap(n_neighbors=k, ridge=ridge))])
            model.fit(X, y)
            hs, ss, stopped = [], [], 0
            for _ in range(args.runs):
                start = int(rng.integers(0, s.size - n_lags))
                run = np.asarray(iterate(model, s[start:start + n_lags], args.length + 500,
                                         on_escape="ignore", clip_to_range=True))[500:]
                if run.size < args.length:
                    stopped += 1
                    continue
                seg = segs[int(rng.integers(0, len(segs)))]
                hs.append(histogram_distance(run, seg).distance)
                ss.append(spectrum_distance(run, seg).distance)
            spec = lyapunov_spectrum(model, s, n_exponents=5, n_steps=20_000, flow=True)
            med = (lambda v: f"{np.median(v):9.4f}" if v else "      nan")
            print(f"{k:3d} {ridge:10g} {med(hs)}  {med(ss)}  {stopped:7d}  "
                  f"{1e3 * spec.exponents[0]:17.2f}  {time.perf_counter() - t0:7.0f}",
                  flush=True)
    exact = laser_exact_spectrum(args.delay)
    if exact is not None:
        print(f"exact lambda_max {1e3 * exact.exponents[0]:.2f} per ms")


if __name__ == "__main__":
    main()
