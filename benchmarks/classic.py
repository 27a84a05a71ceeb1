"""Classic tools of ``skdelay.classic`` on 1e5 points, against ``nolds`` in the same run.

Run:  python benchmarks/classic.py [--n 100000] [--nolds-n 5000]

Prints one row per tool: skdelay's CPU time and result on ``--n`` points, the
reference value, and for D2 and the maximal exponent nolds' ``corr_dim`` /
``lyap_r`` time and result.  nolds builds the full N x N distance matrix
(memory 8 N^2 bytes: 80 GB at N = 1e5), so it runs on the first
``--nolds-n`` points; its time at N is extrapolated as ``t * (N / n)^2``.

nolds 0.6.3 cannot be imported on Python 3.11 (``nolds/datasets.py`` calls
``importlib.resources.files`` on a module); its ``measures.py`` is loaded
directly, which is the same code.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import site
import time

import numpy as np

from skdelay.classic import (
    correlation_dimension,
    false_nearest_neighbors,
    maximal_lyapunov_exponent,
    noise_reduction,
    poincare_section,
)
from skdelay.datasets import henon, lorenz
from skdelay.systems import MackeyGlass


def load_nolds_measures():
    try:
        import nolds

        return nolds
    except Exception:  # noqa: BLE001 - broken nolds import, load the measures module itself
        for base in site.getsitepackages() + [site.getusersitepackages()]:
            path = os.path.join(base, "nolds", "measures.py")
            if os.path.exists(path):
                spec = importlib.util.spec_from_file_location("nolds_measures", path)
                mod = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(mod)
                return mod
    return None


def timed(func, *args, **kwargs):
    """Result and CPU seconds of this process (robust on a shared machine)."""
    t0 = time.process_time()
    out = func(*args, **kwargs)
    return out, time.process_time() - t0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100_000)
    parser.add_argument("--nolds-n", type=int, default=5000)
    args = parser.parse_args()
    n, nn = args.n, args.nolds_n
    nolds = load_nolds_measures()

    print(f"generating data (N = {n}) ...", flush=True)
    data = {
        "henon": henon(n, random_state=0),
        "lorenz": lorenz(n, sample_dt=0.02, random_state=0),
        "mg17": MackeyGlass(tau=17.0).simulate(n, random_state=0),
        "mg23": MackeyGlass(tau=23.0).simulate(n, random_state=0),
    }
    # warm the numba caches so that compile time is not measured
    correlation_dimension(data["henon"][:2000], dims=[2], random_state=0)
    maximal_lyapunov_exponent(data["henon"][:2000], dim=2, max_steps=5, fit_range=(0, 3))

    rows = []

    def add(tool, system, seconds, value, reference, nolds_row=None):
        nolds_row = nolds_row or ("-", "-", "-")
        rows.append((tool, system, f"{seconds:.2f}", value, reference) + nolds_row)

    # --- correlation dimension
    for name, kw, ref, nolds_dim, nolds_lag in (
        ("henon", {"dims": range(1, 6)}, "1.21", 4, 1),
        ("mg23", {"dims": range(4, 9), "lag": 10, "theiler_window": 50}, "2.44", 7, 10),
    ):
        res, t = timed(correlation_dimension, data[name], random_state=0, **kw)
        nrow = None
        if nolds is not None:
            sub = data[name][:nn]
            val, tn = timed(nolds.corr_dim, sub, nolds_dim, lag=nolds_lag, fit="poly")
            nrow = (f"{tn:.2f} (n={nn})", f"{tn * (n / nn) ** 2:.0f}", f"{val:.3f}")
        add("correlation_dimension", name, t, f"{res.dimension:.3f}", ref, nrow)

    # --- maximal Lyapunov exponent (Kantz) vs nolds lyap_r (Rosenstein)
    for name, kw, ref, dt in (
        ("lorenz", {"dim": 5, "lag": 5, "theiler_window": 50, "sample_dt": 0.02, "max_steps": 250,
                        "n_neighbors": 5}, "0.906", 0.02),
        ("mg17", {"dim": 6, "lag": 6, "theiler_window": 100, "max_steps": 800, "n_neighbors": 5},
         "0.0054", 1.0),
    ):
        res, t = timed(maximal_lyapunov_exponent, data[name], n_reference=2000,
                       random_state=0, **kw)
        nrow = None
        if nolds is not None:
            sub = data[name][:nn]
            traj = 100 if name == "lorenz" else 200
            val, tn = timed(nolds.lyap_r, sub, emb_dim=kw["dim"], lag=kw["lag"],
                            min_tsep=kw["theiler_window"], trajectory_len=traj, fit="poly")
            nrow = (f"{tn:.2f} (n={nn})", f"{tn * (n / nn) ** 2:.0f}", f"{val / dt:.4f}")
        add("maximal_lyapunov_exponent", name, t, f"{res.exponent:.4f}", ref, nrow)

    # --- noise reduction (5 % noise on Henon)
    clean = data["henon"]
    noisy = clean + 0.05 * clean.std() * np.random.default_rng(1).normal(size=clean.size)
    out, t = timed(noise_reduction, noisy, dim=7, q=2, iterations=3)
    gain = np.std(noisy - clean) / np.std(out - clean)
    add("noise_reduction", "henon 5%", t, f"error / {gain:.1f}", ">= 2")

    # --- false nearest neighbours, Poincare section
    fnn, t = timed(false_nearest_neighbors, data["henon"], max_dim=4, n_reference=20_000,
                   random_state=0)
    add("false_nearest_neighbors", "henon", t,
        f"d1 {fnn.loc[1, 'fraction']:.2f}, d2 {fnn.loc[2, 'fraction']:.3f}", "d2 ~ 0")
    (_times, values), t = timed(poincare_section, data["lorenz"], sample_dt=0.02)
    add("poincare_section", "lorenz", t, f"{values.size} maxima", "-")

    header = ("tool", "data", "skdelay cpu s", "skdelay value", "reference",
              "nolds cpu s", f"nolds cpu s @N={n} (extrap.)", "nolds value")
    table = [header] + rows
    widths = [max(len(str(r[i])) for r in table) for i in range(len(header))]
    print(f"\nN = {n} points per series; nolds on the first {nn} points "
          "(corr_dim: default radii, poly fit; lyap_r: Rosenstein, poly fit). "
          "Times are CPU seconds of this process.")
    for r in table:
        print("  ".join(str(c).ljust(w) for c, w in zip(r, widths)))


if __name__ == "__main__":
    main()
