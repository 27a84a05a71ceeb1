"""Minimal faithful m across measurement noise (issue: verdicts a scientist can trust).

For Mackey-Glass with tau = 17, 23, 30 at 10^5 samples, clean and with 1 % and
5 % Gaussian measurement noise, runs :func:`skdelay.dynamics.minimal_embedding`
(m = 1..5, delay from the data's own forecast-error dips; with ``--select``
every m's neighbourhood size and ridge from time-series cross-validation on the
series its model is fitted on, as ``skdelay analyze`` does; with
``--select-m5-raw`` the m = 5 model's, chosen on the raw record, for every m,
as analyses did before stop 74; otherwise the defaults) and prints m_d with every model's verdict and, per m, every criterion with its band (the
runs behind each verdict), the estimated noise level and whether the models were fitted
on noise-reduced data.  What must hold: m_d within +-1 across
the noise levels of one system, and "faithful at m" implies "faithful at m+1".

Usage::

    python benchmarks/faithful_noise.py [--n 100000] [--taus 17 23 30] [--out FILE]
"""

from __future__ import annotations

import argparse
import os
import time

import pandas as pd

from skdelay import forecast_error_curve, locate_dips
from skdelay.dynamics import minimal_embedding
from skdelay.model_selection import select_model_options
from skdelay.systems import MackeyGlass, measure

NOISE_LEVELS = (0.0, 0.01, 0.05)
COLUMNS = ["tau", "n_neighbors", "ridge", "faithful", "histogram", "histogram_band", "spectrum", "spectrum_band",
           "chi", "chi_band", "support", "support_band", "clipped", "lyapunov", "lambda_1", "d_ky"]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100_000)
    parser.add_argument("--taus", type=int, nargs="+", default=[17, 23, 30])
    parser.add_argument("--seed", type=int, default=2024)
    parser.add_argument("--out", default=None)
    parser.add_argument("--noise", type=float, nargs="+", default=list(NOISE_LEVELS))
    parser.add_argument("--select", action="store_true",
                        help="model settings by cross-validation per m on the series the "
                             "models are fitted on, as analyze does (else the defaults)")
    parser.add_argument("--select-m5-raw", action="store_true",
                        help="the settings of the m = 5 model cross-validated on the raw "
                             "record, for every m (analyze's choice before stop 74)")
    args = parser.parse_args(argv)
    rows, lines = [], []
    pd.set_option("display.width", 200)
    for tau in args.taus:
        clean = MackeyGlass(tau=float(tau)).simulate(args.n, random_state=args.seed)
        for noise in args.noise:
            x = measure(clean, noise=noise, random_state=args.seed + 1) if noise else clean
            t0 = time.perf_counter()
            grid = range(max(1, tau - 12), tau + 13)
            dips = locate_dips(forecast_error_curve(x, m=(1, 2, 3, 4, 5), tau=grid,
                                                    n_queries=5000, random_state=args.seed))
            taus = {int(m): int(dips.loc[m, "tau_best"]) for m in dips.index}
            if args.select_m5_raw:  # the analyses' choice before stop 74 (for A/B runs)
                res = minimal_embedding(x, tau=taus, m_max=5, random_state=args.seed,
                                        model=select_model_options(
                                            x, 5, taus[5], random_state=args.seed).options)
            else:
                res = minimal_embedding(x, tau=taus, m_max=5, select_model=args.select,
                                        random_state=args.seed)
            dt = time.perf_counter() - t0
            verdicts = " ".join("+" if f else "-" for f in res.table["faithful"])
            rows.append({"tau": tau, "noise": noise, "m_d": "none" if res.m_d is None else res.m_d,
                         "verdicts m=1..5": verdicts,
                         "k (m=1..5), ridge": "/".join(map(str, res.table["n_neighbors"]))
                         + ", " + "/".join(f"{r:g}" for r in res.table["ridge"]),
                         "noise est.": round(res.noise_level / x.std(), 4),
                         "denoised": res.denoised,
                         "seconds": round(dt, 1), "load": round(os.getloadavg()[0], 2)})
            lines.append(f"tau={tau} noise={noise:g}: m_d={res.m_d} ({res.reason or 'ok'})")
            for m, st in res.table["status"].items():
                lines.append(f"    m={m}: {st}")
            lines.append(res.table[COLUMNS].round(4).to_string())
            print(lines[-len(res.table) - 2], flush=True)
    table = pd.DataFrame(rows)
    text = table.to_string(index=False) + "\n\n" + "\n".join(lines) + "\n"
    print(text)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write(f"nice -n 10 python benchmarks/faithful_noise.py --n {args.n} --taus "
                     f"{' '.join(map(str, args.taus))} --seed {args.seed}"
                     f"{' --select' if args.select else ''}"
                     f"{' --select-m5-raw' if args.select_m5_raw else ''}"
                     f"\n\n" + text)


if __name__ == "__main__":
    main()
