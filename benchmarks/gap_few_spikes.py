"""Records with only 1-3 outliers: is the cause named, and are its rate and size recovered?

For each system and sampling step (Mackey-Glass at 1 and 0.5, Ikeda at 0.5 and 0.25, the
electro-optic oscillator at 0.25 and 0.5; 6000 samples) and each spike count 1, 2, 3, one
record: the simulator's run with that many spikes (``Outliers`` at ``rate = count / n``,
size drawn in 3..10 std), diagnosed against the simulator with every library effect.
The table gives the effect named first and the recovery error of the outliers' fit (the
withheld-effect benchmark's measure: the larger relative error of rate and size against
the realised ones, in units of 20 %; <= 1 is within tolerance).  A record whose gap is
not significant reads ``None``.

Run (2 cores, ~4 min)::

    python benchmarks/gap_few_spikes.py
"""

from __future__ import annotations

import argparse
import importlib.util
import time
import warnings
from pathlib import Path

import numpy as np
from joblib import Parallel, delayed

from skdelay.gap import diagnose_gap
from skdelay.systems import ElectroOpticOscillator, Ikeda, MackeyGlass

_SPEC = importlib.util.spec_from_file_location(
    "gap_withheld", Path(__file__).resolve().parent / "gap_withheld.py")
G = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(G)

SYSTEMS = [("mackey_glass", MackeyGlass(), 1.0), ("mackey_glass", MackeyGlass(), 0.5),
           ("ikeda", Ikeda(), 0.5), ("ikeda", Ikeda(), 0.25),
           ("electro_optic", ElectroOpticOscillator(), 0.25),
           ("electro_optic", ElectroOpticOscillator(), 0.5)]


def one(label, system, dt, count, seed, n):
    warnings.simplefilter("ignore")
    G.N_RECORD = n
    G.SAMPLE_DT[0] = dt
    rng = np.random.default_rng(seed)
    chain = [("outliers", {"rate": count / n, "size": float(rng.uniform(3.0, 10.0))})]
    real = G.make_real(system, chain, n, seed, dt)
    clean = G.make_real(system, [], n, seed, dt)
    hit = real != clean
    row = {"system": f"{label}@{dt:g}", "spikes": int(hit.sum()), "found": "-", "error": np.nan}
    if not hit.any():
        return row
    truth = {"rate": float(np.mean(hit)),
             "size": float(np.median(np.abs(real - clean)[hit]) / clean.std())}
    rep = diagnose_gap(real, system, sample_dt=dt, random_state=seed % 9973)
    row["found"] = rep.best_effect or "None"
    if "outliers" in set(rep.effects["effect"]):
        fit = rep.effects.set_index("effect").loc["outliers", "params"]
        row["error"] = G.recovery_error("outliers", truth, fit, system, dt, n)
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=31_000_000)
    ap.add_argument("--n", type=int, default=6000)
    ap.add_argument("--n-jobs", type=int, default=2)
    args = ap.parse_args(argv)
    jobs = [(label, system, dt, count, args.seed + 1000 * i + 17 * count, args.n)
            for i, (label, system, dt) in enumerate(SYSTEMS) for count in (1, 2, 3)]
    t0 = time.perf_counter()
    rows = Parallel(n_jobs=args.n_jobs)(delayed(one)(*job) for job in jobs)
    print(f"{'system':<20} {'spikes':>6}  {'named first':<18} {'error':>7}")
    for r in rows:
        print(f"{r['system']:<20} {r['spikes']:>6}  {r['found']:<18} {r['error']:>7.2f}")
    named = [r for r in rows if r["found"] == "outliers"]
    errors = np.array([r["error"] for r in named])
    print(f"outliers named first: {len(named)}/{sum(r['spikes'] > 0 for r in rows)} records "
          f"with spikes; rate and size within 20 %: {int(np.sum(errors <= 1))}/{len(named)}; "
          f"median error {np.median(errors):.2f}; {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
