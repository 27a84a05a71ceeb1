"""Scan of the CO2 laser model's free parameters for the paper's dynamical regime (issue 12).

Run: ``nice -n 19 python benchmarks/laser_regime.py`` (all stages, about
45 minutes on 2 shared cores; results are cached in
``benchmarks/out/laser_regime.json``, so an interrupted run resumes).
``--stage scan50|check150|check400|final`` runs one stage only.

Buenner et al. (2000, Tab. 3) measured, per ms, at the delays 50, 150 and
400 microseconds: N+ = 1, 4, 11 positive exponents; lambda_max = 2.5, 1.4,
0.55; D_KY = 3.4, 10.2, 23.8; h_KS = 2.5, 3.3, 3.0, on a Hopf oscillation
of about 25 microseconds.  The parameters of
:class:`skdelay.systems.CO2LaserFeedback` that the published six-variable
model (Pisarchik, Meucci & Arecchi 2001) does not fix for this experiment --
the feedback gain ``r``, the bias ``b0`` (the experiment's control
parameter B), the amplifier bandwidth ``beta``, the detector saturation
``alpha`` and the spontaneous-emission source ``sp`` -- are scanned in
stages of increasing cost:

``scan50``
    a grid at tau = 50 (8 exponents over 20 000 microseconds, ~1 s a point);
``check150``
    the points whose tau = 50 spectrum is within the tolerances, at
    tau = 150 (20 exponents, 20 000 microseconds, ~10 s a point);
``check400``
    the best of those at tau = 400 (32 exponents, 20 000 microseconds);
``final``
    the chosen parameter set (``CO2LaserFeedback.from_preset("buenner2000")``) at all
    three delays with enough exponents to close the Kaplan-Yorke sum and
    longer averages (spreads: standard errors over 10 blocks).

Each row gives the parameters, N+ (exponents above their block spread, not
counting the flow's zero exponent), lambda_max (with its spread), D_KY
(``>=`` when the computed exponents do not close the sum), h_KS, and the
dominant period of the intensity (peak of its power spectrum at periods
below 100 microseconds, from 40 000 samples at 1 microsecond).  The table is
printed and written to ``benchmarks/out/laser_regime.txt``.

Result: no scanned set meets the tolerances at all three delays.  The
closest, ``r = 120, b0 = 0.1`` (preset ``"buenner2000"``), matches N+,
D_KY / tau and the oscillation at tau = 400 and N+ at 150, but its largest
exponent is about half the measured one at 150 and 400 and tau = 50 is about
1.5 times too chaotic (D_KY, h_KS).  Sets weak enough at tau = 50 are too
weakly chaotic at 400; beta = 0.3 matches 50 and 150 but not 400;
beta = 0.36-0.39 gives the same flat spectra as beta = 0.4286, or none (its
best, r = 130, b0 = 0.1025, beta = 0.36, has total misfit 10.0 against 9.9).
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import numpy as np
from joblib import Parallel, delayed
from scipy.signal import welch

from skdelay.dynamics import kaplan_yorke_dimension
from skdelay.systems import CO2LaserFeedback

OUT = Path(__file__).resolve().parent / "out"
CACHE = OUT / "laser_regime.json"
DELAYS = (50.0, 150.0, 400.0)

# Buenner et al. 2000, Tab. 3 (per ms) and the tolerances of issue 12
TARGET = {50.0: {"N": 1, "lambda_max": 2.5, "D_KY": 3.4, "h_KS": 2.5},
          150.0: {"N": 4, "lambda_max": 1.4, "D_KY": 10.2, "h_KS": 3.3},
          400.0: {"N": 11, "lambda_max": 0.55, "D_KY": 23.8, "h_KS": 3.0}}
N_RANGE = {50.0: (0, 2), 150.0: (3, 6), 400.0: (8, 15)}
REL_TOL = {"lambda_max": 0.4, "D_KY": 0.3, "h_KS": 0.5}

# (exponents, averaging time in microseconds) per stage and delay
SCAN_SPECTRUM = {50.0: (8, 20_000.0), 150.0: (20, 20_000.0), 400.0: (32, 20_000.0)}
FINAL_SPECTRUM = {50.0: (12, 100_000.0), 150.0: (24, 60_000.0), 400.0: (44, 40_000.0)}
# at tau = 50 chaotic and periodic attractors coexist: the final stage tries more seeds
FINAL_SEEDS_50 = (1, 2, 3)
PERIOD_SAMPLES = 40_000
PERIOD_CUTOFF = 100.0  # longest period considered for the dominant oscillation (us)
SEED = 1

# the scan50 grid: r x b0 around the onset of chaos, for five (beta, sp) pairs
GRID_R = (110.0, 115.0, 120.0, 125.0, 130.0)
GRID_B0 = (0.09, 0.0925, 0.095, 0.0975, 0.1, 0.1025, 0.105)
GRID_BETA_SP = ((0.4286, 2e-5), (0.3, 2e-5), (0.6, 2e-5), (0.4286, 1e-5), (0.4286, 4e-5))
# a lower amplifier bandwidth needs more gain for chaos (beta = 0.3 at r <= 130 is not
# chaotic); it makes fewer degrees of freedom per delay, for the steeper spectra of the paper
# (betas, gains, biases) blocks; the second fills the gap between 0.3 and 0.4286
GRID_LOW_BETA = (((0.3, 0.35), (140.0, 160.0, 180.0, 200.0), (0.095, 0.1, 0.105, 0.11, 0.12)),
                 ((0.36, 0.39), (120.0, 130.0, 140.0), (0.0975, 0.1, 0.1025)))
GRID_ALPHA = (20.0, 32.8767, 50.0)  # only around the best (r, b0) of the default alpha
N_CHECK150 = 16  # best tau = 50 points checked at tau = 150
N_CHECK400 = 4   # best tau = 150 points checked at tau = 400


def n_positive_flow(lam, spread):
    """Exponents above their spread, not counting the flow's zero (closest to 0)."""
    lam = np.array(lam, dtype=float)
    lam[np.argmin(np.abs(lam))] = 0.0
    return int(np.sum(lam > np.maximum(spread, 0.0)))


def dominant_period(system, seed=SEED):
    """Period (us) of the largest power-spectral peak at periods below PERIOD_CUTOFF."""
    x = system.simulate(PERIOD_SAMPLES, random_state=seed)
    f, psd = welch(x - x.mean(), nperseg=4096)
    band = f > 1.0 / PERIOD_CUTOFF
    return float(1.0 / f[band][np.argmax(psd[band])])


def evaluate(params, tau, n_exponents, duration, seed=SEED):
    """Spectrum summary (per ms) and dominant period of one parameter set at one delay."""
    system = CO2LaserFeedback(tau=tau, **params)
    t0 = time.perf_counter()
    row = {"tau": tau, **params, "k": n_exponents, "duration": duration, "seed": seed}
    try:
        period = dominant_period(system, seed)
        spec = system.lyapunov_spectrum(n_exponents, duration=duration, random_state=seed)
    except ValueError as exc:  # a diverging parameter set is a result of the scan too
        return {**row, "error": str(exc)[:120]}
    lam, spread = spec.exponents, spec.spread
    d_ky = kaplan_yorke_dimension(lam)
    return {**row, "N": n_positive_flow(lam, spread), "lambda_max": 1e3 * lam[0],
            "spread_max": 1e3 * spread[0], "D_KY": d_ky, "closed": d_ky < lam.size,
            "h_KS": 1e3 * float(lam[lam > 0].sum()), "period": period,
            "exponents": (1e3 * lam).tolist(), "spreads": (1e3 * spread).tolist(),
            "seconds": time.perf_counter() - t0}


def misfit(row):
    """Sum over the paper's quantities of |log(value / target)| / log(1 + tolerance).

    Below 1 for each term means within the issue's tolerance; N+ outside its
    range adds 1 per missing or extra exponent.
    """
    if "error" in row:
        return np.inf
    target = TARGET[row["tau"]]
    total = 0.0
    for key, tol in REL_TOL.items():
        value = max(row[key], 1e-3)
        total += abs(np.log(value / target[key])) / np.log1p(tol)
    lo, hi = N_RANGE[row["tau"]]
    total += max(lo - row["N"], 0) + max(row["N"] - hi, 0)
    return float(total)


def within_targets(row):
    """All quantities within the issue's tolerances (and D_KY closed)."""
    if "error" in row:
        return False
    target = TARGET[row["tau"]]
    lo, hi = N_RANGE[row["tau"]]
    ok = lo <= row["N"] <= hi and row["closed"]
    return ok and all(abs(row[k] / target[k] - 1.0) <= tol for k, tol in REL_TOL.items())


def key_of(params, tau, n_exponents, duration, seed=SEED):
    return json.dumps({"tau": tau, **params, "k": n_exponents, "duration": duration,
                       "seed": seed}, sort_keys=True)


def run_points(cache, stage, jobs):
    """Evaluate (params, tau, k, duration[, seed]) jobs not yet cached, two at a time."""
    jobs = list({key_of(*j): j for j in jobs}.values())
    todo = [j for j in jobs if key_of(*j) not in cache]
    if todo:
        rows = Parallel(n_jobs=2)(delayed(evaluate)(*j) for j in todo)
        for job, row in zip(todo, rows):
            cache[key_of(*job)] = {**row, "stage": stage}
        save(cache)
    return [cache[key_of(*j)] for j in jobs]


def save(cache):
    OUT.mkdir(exist_ok=True)
    tmp = CACHE.with_suffix(".tmp")
    tmp.write_text(json.dumps(cache, indent=0))
    tmp.replace(CACHE)


def params_of(row):
    return {k: row[k] for k in ("r", "b0", "beta", "alpha", "sp")}


def stage_scan50(cache):
    grid = [{"r": r, "b0": b0, "beta": beta, "alpha": 32.8767, "sp": sp}
            for (beta, sp), r, b0 in itertools.product(GRID_BETA_SP, GRID_R, GRID_B0)]
    grid += [{"r": r, "b0": b0, "beta": beta, "alpha": 32.8767, "sp": 2e-5}
             for block in GRID_LOW_BETA for beta, r, b0 in itertools.product(*block)]
    k, duration = SCAN_SPECTRUM[50.0]
    rows = run_points(cache, "scan50", [(p, 50.0, k, duration) for p in grid])
    best = min(rows, key=misfit)
    alpha_grid = [{**params_of(best), "alpha": a, "b0": b0}
                  for a in GRID_ALPHA for b0 in GRID_B0]
    rows += run_points(cache, "scan50", [(p, 50.0, k, duration) for p in alpha_grid])
    return list({id(r): r for r in rows}.values())  # the alpha grid repeats the default alpha


def stage_check(cache, rows, tau, n_best, stage):
    """Evaluate at the delay tau the n_best parameter sets of rows, ranked by their
    misfit summed over all delays computed so far (cached rows of any stage)."""
    def total(row):
        p = params_of(row)
        return sum(misfit(c) for c in cache.values() if c["tau"] < tau and params_of(c) == p)

    best = sorted((r for r in rows if np.isfinite(total(r))), key=total)[:n_best]
    k, duration = SCAN_SPECTRUM[tau]
    return run_points(cache, stage, [(params_of(r), tau, k, duration) for r in best])


def stage_final(cache):
    params = CO2LaserFeedback.PRESETS["buenner2000"]
    # the longest delay first: it takes most of the time, the others fill the second process
    jobs = [(params, tau, *FINAL_SPECTRUM[tau]) for tau in reversed(DELAYS)]
    jobs += [(params, 50.0, *FINAL_SPECTRUM[50.0], seed) for seed in FINAL_SEEDS_50[1:]]
    return run_points(cache, "final", jobs)


def all_delays(cache):
    """Parameter sets computed at every delay (scan durations), by their summed misfit."""
    by_params = {}
    for row in cache.values():
        if row["stage"] != "final":
            by_params.setdefault(json.dumps(params_of(row), sort_keys=True), {})[row["tau"]] = row
    complete = [rows for rows in by_params.values() if set(rows) == set(DELAYS)]
    complete.sort(key=lambda rows: sum(misfit(r) for r in rows.values()))
    lines = []
    for rows in complete:
        total = sum(misfit(r) for r in rows.values())
        lines += [f"{fmt_row(rows[tau])}  total {total:5.1f}" for tau in DELAYS] + [""]
    return lines


def fmt_row(row):
    p = f"r={row['r']:5.1f} b0={row['b0']:.4f} beta={row['beta']:.4f} " \
        f"alpha={row['alpha']:6.2f} sp={row['sp']:.0e}"
    head = f"{row['tau']:5.0f} {p}"
    if "error" in row:
        return f"{head}  diverged ({row['error']})"
    dky = f"{'' if row['closed'] else '>='}{row['D_KY']:.1f}"
    return (f"{head} {row['k']:3d} {row['duration']:7.0f} {row['seed']:4d} {row['N']:3d} "
            f"{row['lambda_max']:6.2f}+-{row['spread_max']:4.2f} {dky:>6} {row['h_KS']:6.2f} "
            f"{row['period']:6.1f} {misfit(row):6.1f} {'yes' if within_targets(row) else 'no':>4} "
            f"{row['seconds']:5.0f}")


HEADER = ("  tau parameters" + " " * 50 + "  k  T(us) seed  N+  lam_max/ms  D_KY h_KS/ms "
          "period misfit  ok  sec")


def report(sections):
    lines = [
        "CO2LaserFeedback: scan of the free parameters for the regime of Buenner et al. (2000)",
        ("paper (per ms): tau=50: N+ 1, lambda_max 2.5, D_KY 3.4, h_KS 2.5; "
         "tau=150: 4, 1.4, 10.2, 3.3; tau=400: 11, 0.55, 23.8, 3.0; Hopf period ~25 us"),
        ("tolerances (issue 12): N+ <=2 / 3-6 / 8-15, lambda_max +-40 %, D_KY +-30 %, "
         "h_KS +-50 %; misfit = sum |log(x/target)| / log(1+tol) (+1 per N+ outside)"),
        ("k exponents averaged over T microseconds (dt = 0.02, QR every 2 us); "
         "+- is the block standard error of lambda_max; period: dominant one (us)"),
    ]
    for title, rows in sections:
        lines += ["", title, HEADER]
        if isinstance(rows[0], str):
            lines += rows
        else:
            lines += [fmt_row(r) for r in sorted(rows, key=lambda r: (r["tau"], misfit(r)))]
    text = "\n".join(lines) + "\n"
    print(text)
    OUT.mkdir(exist_ok=True)
    (OUT / "laser_regime.txt").write_text(text)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stage", choices=("all", "scan50", "check150", "check400", "final"),
                        default="all")
    args = parser.parse_args()
    cache = json.loads(CACHE.read_text()) if CACHE.exists() else {}
    stages = ("scan50", "check150", "check400", "final") if args.stage == "all" \
        else (args.stage,)
    t0 = time.perf_counter()
    rows50 = stage_scan50(cache)
    sections = [(f"scan at tau = 50 (best 25 of {len(rows50)})",
                 sorted(rows50, key=misfit)[:25])]
    if "check150" in stages or "check400" in stages:
        rows150 = stage_check(cache, rows50, 150.0, N_CHECK150, "check150")
        sections.append(("best tau = 50 points at tau = 150", rows150))
    if "check400" in stages:
        rows400 = stage_check(cache, rows150, 400.0, N_CHECK400, "check400")
        sections.append(("best tau = 150 points at tau = 400", rows400))
    if "check400" in stages or "final" in stages:
        sections.append(("parameter sets computed at all three delays, by total misfit",
                         all_delays(cache)))
    if "final" in stages:
        sections.append(("preset 'buenner2000' (CO2LaserFeedback.from_preset), final spectra",
                         stage_final(cache)))
    report(sections)
    print(f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
