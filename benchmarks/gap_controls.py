"""No-effect controls of the gap diagnosis: how often a record of the simulator itself is
called significantly different from the simulator's runs (a false gap).

Each record is a fresh simulator run (seed ``seed * 7919 + 13``), diagnosed against the
same simulator with ``random_state=seed``; only the significance verdict is read, so the
diagnosis is asked for one cheap candidate effect (the verdict comes before any fit and
does not depend on the candidates).  The table gives, per system, the records called
significant and the evidence behind each: ``gap`` (the gap above the no-gap threshold,
replicated against fresh ensembles), ``line`` (a spectral line), ``bin`` (one bin far off),
``dip`` (the forecast-error dip moved), ``range`` (excursions beyond the runs' range).
A diagnosis needs 20 delays of record: the laser at delay 400 needs ``--n 8000``.
With ``--baseline REV`` the same records are diagnosed by the package as of git revision
``REV`` in the same run (a subprocess on a ``git archive`` of it).

Run (2 cores)::

    python benchmarks/gap_controls.py --systems laser150:20:60 laser50:100:130 mg:0:20
    python benchmarks/gap_controls.py --systems laser150:20:60 --baseline 043520e
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

N = 6000
ROOT = Path(__file__).resolve().parents[1]


def _system(name):
    from skdelay.systems import CO2LaserFeedback, ElectroOpticOscillator, Ikeda, MackeyGlass

    if name.startswith("laser"):
        return CO2LaserFeedback(tau=float(name[5:])), 1.0
    return {"mg": (MackeyGlass(), 1.0), "ikeda": (Ikeda(), 0.5),
            "eo": (ElectroOpticOscillator(), 0.25)}[name]


def _evidence(sig):
    why = []
    if sig["gap_before"] > sig["threshold"] and (
            sig["replicated"] is None or np.nanmedian(sig["replicated"]) > sig["threshold"]):
        why.append("gap")
    if sig["lines"]:
        why.append("line")
    if sig.get("far_bin", sig["max_z"] > sig["z_local"]):
        why.append("bin")
    if sig["dip_shift"]:
        why.append("dip")
    if sig["beyond_range_p"] < 0.01 or sig["jumps_p"] < 0.01:
        why.append("range")
    return "+".join(why)


def measure(name, lo, hi, n_jobs, n=N):
    """``{seed: (significant, evidence, max_z)}`` for the records ``lo .. hi - 1`` of ``n``
    samples."""
    from skdelay.gap import diagnose_gap

    warnings.simplefilter("ignore")
    system, dt = _system(name)
    out = {}
    for seed in range(lo, hi):
        real = np.asarray(system.simulate(n, sample_dt=dt, random_state=seed * 7919 + 13))
        rep = diagnose_gap(real, system, sample_dt=dt, effects=["measurement_noise"],
                           random_state=seed, n_jobs=n_jobs)
        sig = rep.significance
        out[seed] = (bool(sig["significant"]),
                     _evidence(sig) if sig["significant"] else "", float(sig["max_z"]))
    return out


def _baseline(rev, specs, n_jobs, n):
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from _revision import export_package

    with tempfile.TemporaryDirectory() as tmp:
        export_package(rev, tmp)
        env = dict(os.environ, PYTHONPATH=tmp, NUMBA_CACHE_DIR=str(Path(tmp) / "nc"))
        cmd = [sys.executable, str(Path(__file__).resolve()), "--worker",
               "--n-jobs", str(n_jobs), "--n", str(n), "--systems", *specs]
        # not check=True: a failure raises below with the worker's own traceback
        res = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=tmp, check=False)
    if res.returncode:
        raise RuntimeError(f"the baseline run failed:\n{res.stderr[-3000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--systems", nargs="+", default=["laser150:20:60"],
                    metavar="NAME:FIRST:STOP", help="laser<delay>, mg, ikeda or eo, and seeds")
    ap.add_argument("--baseline", metavar="REV")
    ap.add_argument("--n-jobs", type=int, default=2)
    ap.add_argument("--n", type=int, default=N, help="samples per record")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    specs = [(s.split(":")[0], int(s.split(":")[1]), int(s.split(":")[2])) for s in args.systems]
    if args.worker:
        print(json.dumps({name: {str(k): v for k, v in measure(name, lo, hi, args.n_jobs, args.n).items()}
                          for name, lo, hi in specs}))
        return
    import skdelay

    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; skdelay from "
          f"{Path(skdelay.__file__).parent}; {args.n} samples per record; load average "
          f"{' / '.join(f'{v:.2f}' for v in os.getloadavg())}")
    shown = " ".join(sys.argv[1:] if argv is None else argv)
    print(f"# command: python benchmarks/gap_controls.py {shown}")
    base = _baseline(args.baseline, args.systems, args.n_jobs, args.n) if args.baseline else None
    print("| system | records | significant | evidence (seed: why) |"
          + (f" significant at {args.baseline} | evidence there |" if base else ""))
    print("|---|---|---|---|" + ("---|---|" if base else ""))
    for name, lo, hi in specs:
        t0 = time.perf_counter()
        now = measure(name, lo, hi, args.n_jobs, args.n)
        row = (f"| {name} | {hi - lo} | {sum(v[0] for v in now.values())} | "
               + ", ".join(f"{k}: {v[1]}" for k, v in now.items() if v[0]) + " |")
        if base:
            then = base[name]
            row += (f" {sum(v[0] for v in then.values())} | "
                    + ", ".join(f"{k}: {v[1]}" for k, v in then.items() if v[0]) + " |")
        print(row + f"  <!-- {time.perf_counter() - t0:.0f} s -->", flush=True)


if __name__ == "__main__":
    main()
