"""A clock mismatch as a real recorder makes it: records sampled at ``factor * sample_dt``.

For each case the simulator runs at the true step ``factor * sample_dt`` (no
resampling: what a slow or fast clock records), and
:func:`skdelay.gap.diagnose_gap` is told the nominal ``sample_dt``.  Prints,
per case, whether the gap is significant, the effect named first, and the
timebase candidate's fitted factor and the gap it leaves.  A factor of 1 is a
control (no effect).

Run it with the ``skdelay`` to be measured first on the path (``PYTHONPATH`` set
to a checkout of an earlier commit) to compare two versions on the same records.

Usage::

    python benchmarks/gap_timebase.py [--cases mg:1:1.015 eo:0.25:0.985 ...]
        [--n 6000] [--seed 7000]
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import pandas as pd

import skdelay
from skdelay.gap import diagnose_gap
from skdelay.systems import ElectroOpticOscillator, Ikeda, MackeyGlass

SYSTEMS = {"mg": MackeyGlass, "eo": ElectroOpticOscillator, "ikeda": Ikeda}
#: system:step:factor; the factor-1 cases are controls
CASES = ("mg:1:1.015", "mg:1:0.98", "mg:1:1.03", "mg:1:0.99", "eo:0.25:1.015", "eo:0.25:0.985",
         "ikeda:0.5:1.04", "mg:1:1.0", "eo:0.25:1.0")


def run_case(name, step, factor, n, seed):
    system = SYSTEMS[name]()
    real = system.simulate(n, sample_dt=step * factor, random_state=seed)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        rep = diagnose_gap(real, system, sample_dt=step, random_state=seed % 9973)
    eff = rep.effects
    tb = eff[eff["effect"] == "timebase_mismatch"]
    sig = rep.significance
    return {"system": name, "step": step, "factor": factor, "seed": seed,
            "significant": bool(sig["significant"]),
            "gap/threshold": round(sig["gap_before"] / sig["threshold"], 2),
            "first": eff.iloc[0]["effect"] if sig["significant"] else "None",
            "tb factor": round(float(tb.iloc[0]["params"]["factor"]), 4) if len(tb) else None,
            "tb gap after": round(float(tb.iloc[0]["gap_after"]), 3) if len(tb) else None,
            "tie": (rep.tie["effects"][1] if rep.tie and not rep.tie["decided"] else "-"),
            "seconds": round(time.perf_counter() - t0, 1)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES), metavar="SYSTEM:STEP:FACTOR",
                    help=f"systems: {', '.join(SYSTEMS)}")
    ap.add_argument("--n", type=int, default=6000, help="samples per record")
    ap.add_argument("--seed", type=int, default=7000, help="seed of case 1 (then + 1 each)")
    args = ap.parse_args(argv)
    print(f"# skdelay from {os.path.dirname(skdelay.__file__)}; load average at start "
          f"{os.getloadavg()[0]:.2f} on {os.cpu_count()} cores", flush=True)
    rows = []
    for i, spec in enumerate(args.cases):
        name, step, factor = spec.split(":")
        if name not in SYSTEMS:
            ap.error(f"--cases: unknown system {name!r}; choose from {sorted(SYSTEMS)}")
        rows.append(run_case(name, float(step), float(factor), args.n, args.seed + 1 + i))
        print(" ".join(f"{k}={v}" for k, v in rows[-1].items()), flush=True)
    print()
    print(pd.DataFrame(rows).to_string(index=False))


if __name__ == "__main__":
    main()
