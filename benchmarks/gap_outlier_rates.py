"""How well is the rate of outliers recovered when part of the spikes hides in the signal?

For each system and sampling step (Mackey-Glass at 1 and 0.5, Ikeda at 0.5 and 0.25, the
electro-optic oscillator at 0.25 and 0.5; 6000 samples), records with 5, 25 and 60 spikes
of size 3.5, 5 and 8 std (heights ``size * U(0.5, 1.5)``), three seeds each: the outliers'
starting guess (``get_effect("outliers").guess``, what the diagnosis measures and does not
search when the spikes clear the threshold) against the realised rate and median height.
On rough records (Ikeda at step 0.5) part of the heights fall below the detection
threshold or are hidden by the signal's own roughness, and the guess must put them back.

The table gives, per system, the median ratio guess / realised and the share of records
within 20 % (the withheld-effect benchmark's tolerance), for the rate and the size.
Compare versions by running the script from each (``git archive``); the seeds are fixed.

Run (2 cores, ~1 min)::

    python benchmarks/gap_outlier_rates.py
"""

from __future__ import annotations

import argparse
import importlib.util
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from joblib import Parallel, delayed

from skdelay.gap import get_effect

# the systems and steps of the few-spike benchmark, and the withheld-effect benchmark's
# record maker (gap_few_spikes.G)
_SPEC = importlib.util.spec_from_file_location(
    "gap_few_spikes", Path(__file__).resolve().parent / "gap_few_spikes.py")
FEW = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(FEW)
G = FEW.G
SYSTEMS = {f"{label}@{dt:g}": (system, dt) for label, system, dt in FEW.SYSTEMS}


def one(label, count, size, seed, n):
    warnings.simplefilter("ignore")
    system, dt = SYSTEMS[label]
    G.N_RECORD = n
    G.SAMPLE_DT[0] = dt
    real = G.make_real(system, [("outliers", {"rate": count / n, "size": size})], n, seed, dt)
    clean = G.make_real(system, [], n, seed, dt)
    # the clean runs the diagnosis would compare with: other seeds of the simulator
    sims = np.array([G.make_real(system, [], n, seed + 1 + i, dt) for i in range(2)])
    hit = real != clean
    rate = float(np.mean(hit))
    height = float(np.median(np.abs(real - clean)[hit]) / clean.std())
    guess = get_effect("outliers").guess(real, sims, dt)
    return {"system": label, "spikes": int(hit.sum()), "size": size,
            "rate": guess["rate"] / rate, "height": guess["size"] / height}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=77_000)
    ap.add_argument("--n", type=int, default=6000)
    ap.add_argument("--n-jobs", type=int, default=2)
    args = ap.parse_args(argv)
    jobs = [(label, count, size, args.seed + 91 * i, args.n) for label in SYSTEMS
            for count in (5, 25, 60) for size in (3.5, 5.0, 8.0) for i in range(3)]
    t0 = time.perf_counter()
    df = pd.DataFrame(Parallel(n_jobs=args.n_jobs)(delayed(one)(*job) for job in jobs))
    for col in ("rate", "height"):
        df[f"{col} within 20 %"] = (df[col] > 0.8) & (df[col] < 1.2)
    table = df.groupby("system", sort=False).agg(
        records=("rate", "size"), rate_median=("rate", "median"),
        rate_within=("rate within 20 %", "mean"), size_median=("height", "median"),
        size_within=("height within 20 %", "mean"))
    print(table.to_string(float_format=lambda v: f"{v:.2f}"))
    print(f"all {len(df)} records: rate within 20 % {df['rate within 20 %'].mean():.3f}, "
          f"size within 20 % {df['height within 20 %'].mean():.3f}; "
          f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
