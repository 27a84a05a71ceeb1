"""Blind estimates on fresh laser data against the simulator's shipped exact spectra.

Run: ``python benchmarks/blind_laser.py --seed 7`` (about 10 minutes on 2 cores).

What a user would do, through the command line only: simulate the laser of
:func:`skdelay.datasets.load_laser` with a seed that is *not* the embedded
data's (``skdelay simulate co2_laser --param tau=... --seed S`` with the same
acquisition chain: 12-bit ADC, 0.5 % measurement and 0.3 % dynamical noise),
then ``skdelay analyze --flow --time-unit us`` with default settings (plus
``--select-model`` unless ``--no-select-model``; nothing is chosen by looking
at an exact spectrum), and compare the summary in ``results.json`` with
:func:`skdelay.datasets.laser_exact_spectrum` (the exact spectrum does not
depend on the seed).  The tolerances are those of issue 12: N+ within 1 at 50
and 150 us and within 3 at 400 us; lambda_max within 20 %; D_KY within 15 %;
h_KS within 25 %; D_KY / tau and h_KS the same at every delay within 15 %.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from skdelay.datasets import (
    LASER_BITS,
    LASER_DYNAMICAL_NOISE,
    LASER_MEASUREMENT_NOISE,
    laser_exact_spectrum,
    load_laser,
)

OUT = Path(__file__).resolve().parent / "out" / "blind_laser.txt"
TOL = {"lambda_max": 0.20, "D_KY": 0.15, "h_KS": 0.25}
N_TOL = {50: 1, 150: 1, 400: 3}
SPREAD_TOL = 0.15


def run(cmd):
    subprocess.run([sys.executable, "-m", "skdelay", *map(str, cmd)], check=True)


def exact_row(delay):
    spec = laser_exact_spectrum(delay)
    if spec is None:
        raise SystemExit("no shipped exact spectrum for the current laser parameters: "
                         "run benchmarks/exact_spectra.py first")
    lam = spec.exponents
    return {"N": spec.n_positive, "lambda_max": 1e3 * lam[0],
            "D_KY": spec.kaplan_yorke_dimension, "h_KS": 1e3 * spec.ks_entropy,
            "D_KY/tau": 1e3 * spec.kaplan_yorke_dimension / delay}


def blind_row(delay, seed, n_samples, select_model, work):
    system = load_laser(delay, n_samples=1000, cache=False).system
    data = work / f"laser_{delay}_{seed}.npy"
    params = [f"--param={k}={v!r}" for k, v in system.params.items()]
    run(["simulate", "co2_laser", *params, "--n", n_samples, "--dt", 1.0, "--seed", seed,
         "--noise", LASER_MEASUREMENT_NOISE, "--bits", LASER_BITS,
         "--dynamical-noise", LASER_DYNAMICAL_NOISE, "-o", data])
    out = work / f"analysis_{delay}_{seed}"
    t0 = time.perf_counter()
    run(["analyze", data, "--flow", "--time-unit", "us", "--quiet", "--out", out,
         "--seed", seed, *(["--select-model"] if select_model else [])])
    seconds = time.perf_counter() - t0
    summary = json.loads((out / "results.json").read_text())["summary"]
    row = {"N": summary["N"], "lambda_max": 1e3 * summary["lambda_max"],
           "D_KY": summary["D_KY"], "h_KS": 1e3 * summary["h_KS"],
           "D_KY/tau": 1e3 * summary["D_KY/tau"], "delay": summary["delay"],
           "m_d": summary.get("minimal_m"), "sec": seconds}
    sel = out / "model_selection.csv"
    if sel.exists():
        import pandas as pd

        chosen = pd.read_csv(sel).query("chosen")
        row["k, ridge"] = (f"{int(chosen['n_neighbors'].iloc[0])}, "
                           f"{float(chosen['ridge'].iloc[0]):g}")
    return row


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--delays", type=int, nargs="+", default=[50, 150, 400])
    parser.add_argument("--n-samples", type=int, default=100_000)
    parser.add_argument("--no-select-model", action="store_true")
    args = parser.parse_args(argv)
    lines = [f"# {time.strftime('%Y-%m-%d %H:%M')} UTC, load average "
             f"{os.getloadavg()[0]:.1f}; " + " ".join(["python", *sys.argv]),
             ("blind = skdelay simulate (fresh seed) + skdelay analyze "
             f"({'default settings' if args.no_select_model else '--select-model'}); "
             "exact = shipped spectrum (per ms)"), ""]
    rows, ok_all = {}, True
    with tempfile.TemporaryDirectory() as tmp:
        for delay in args.delays:
            blind = blind_row(delay, args.seed, args.n_samples, not args.no_select_model,
                              Path(tmp))
            exact = exact_row(delay)
            rows[delay] = blind
            checks = {"N": abs(blind["N"] - exact["N"]) <= N_TOL[delay]}
            for key, tol in TOL.items():
                checks[key] = abs(blind[key] / exact[key] - 1.0) <= tol
            ok_all &= all(checks.values())
            lines.append(
                f"tau0 = {delay}: delay {blind['delay']}, m_d {blind['m_d']}, settings "
                f"{blind.get('k, ridge', 'default')}, {blind['sec']:.0f} s")
            for key in ("N", "lambda_max", "D_KY", "h_KS", "D_KY/tau"):
                mark = "" if key not in checks else ("  ok" if checks[key] else "  MISS")
                lines.append(f"  {key:>10}: blind {blind[key]:8.3g}   exact "
                             f"{exact[key]:8.3g}{mark}")
            print("\n".join(lines[-6:]), flush=True)
    if len(rows) > 1:
        for key in ("D_KY/tau", "h_KS"):
            v = np.array([r[key] for r in rows.values()])
            spread = float(v.std() / v.mean())
            ok_all &= spread <= SPREAD_TOL
            lines.append(f"{key} over delays: spread {spread:.0%} of the mean "
                         f"({'ok' if spread <= SPREAD_TOL else 'MISS'}, tolerance 15 %)")
    lines.append(f"all tolerances met: {ok_all}")
    OUT.parent.mkdir(exist_ok=True)
    OUT.write_text("\n".join(lines) + "\n")
    print("\n".join(lines[-3:]))


if __name__ == "__main__":
    main()
