"""Speed of the delay-system simulators and of the exact Lyapunov spectrum.

Prints a table:

- Mackey-Glass (tau=17), 10**6 samples at sample step 1, integration step 0.05
  (RK4, 2*10**7 steps);
- the four systems of the gap benchmark (Mackey-Glass, Ikeda, the electro-optic
  oscillator at sample step 0.25, the CO2 laser at tau=150), 2*10**4 samples
  with their default transient: what one ensemble run of a gap diagnosis costs;
- the exact spectrum (20 exponents) of Mackey-Glass at tau=100;
- the same integration with ``jitcdde`` (adaptive RK + Hermite history, C code)
  if it is installed, measured in the same run, with the speed ratio.

Run: ``python benchmarks/simulate.py [--n 1000000] [--jit-n 100000]``.
Timings include numba cache loading but not compilation (a warm-up call
compiles first); jitcdde's C compilation is reported separately.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from skdelay.systems import CO2LaserFeedback, ElectroOpticOscillator, Ikeda, MackeyGlass


def _time(func, repeat=1):
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = func()
        best = min(best, time.perf_counter() - t0)
    return best, out


def _jitcdde_run(n_samples, tau=17.0):
    try:
        from jitcdde import jitcdde, t, y
    except ImportError as exc:  # pragma: no cover - optional
        return None, f"jitcdde not installed ({exc.__class__.__name__})"
    f = [0.2 * y(0, t - tau) / (1 + y(0, t - tau) ** 10) - 0.1 * y(0)]
    try:
        t0 = time.perf_counter()
        dde = jitcdde(f, verbose=False)
        dde.compile_C(verbose=False)
        compile_time = time.perf_counter() - t0
        dde.constant_past([1.2])
        dde.adjust_diff()
        start = dde.t + 1000.0
        dde.integrate(start)  # transient

        def run():
            with warnings.catch_warnings():  # "target time is smaller": harmless here
                warnings.simplefilter("ignore", UserWarning)
                return np.array([dde.integrate(start + i)[0] for i in range(1, n_samples + 1)])

        elapsed, x = _time(run)
    except Exception as exc:  # noqa: BLE001 - any compiler/platform failure is reported
        return None, f"jitcdde failed: {exc.__class__.__name__}: {exc}"
    return (elapsed, compile_time, x), None


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000, help="samples for skdelay")
    parser.add_argument("--jit-n", type=int, default=100_000, help="samples for the comparison")
    args = parser.parse_args(argv)

    mg = MackeyGlass(tau=17.0)
    t0 = time.perf_counter()
    mg.simulate(10, random_state=0, transient=0)
    warm = time.perf_counter() - t0
    t_big, x = _time(lambda: mg.simulate(args.n, sample_dt=1.0, dt=0.05, random_state=0))
    t_cmp, _ = _time(lambda: mg.simulate(args.jit_n, sample_dt=1.0, dt=0.05, random_state=0),
                     repeat=3)

    per_run = []
    for name, system, step in [("Mackey-Glass", mg, 1.0), ("Ikeda", Ikeda(), 1.0),
                               ("electro-optic", ElectroOpticOscillator(), 0.25),
                               ("CO2 laser tau=150", CO2LaserFeedback(tau=150.0), 1.0)]:
        system.simulate(10, sample_dt=step, random_state=0, transient=0)  # compile / load
        t_run, _ = _time(lambda s=system, h=step: s.simulate(20_000, sample_dt=h, random_state=1),
                         repeat=5)
        per_run.append((f"{name}, 2e4 samples at step {step:g} (+ transient)",
                        f"{t_run * 1e3:.0f} ms", "best of 5"))

    mg100 = MackeyGlass(tau=100.0)
    mg100.lyapunov_spectrum(2, dt=0.5, duration=10, transient=0)  # compile / load
    t_spec, spec = _time(lambda: mg100.lyapunov_spectrum(
        20, dt=0.1, duration=20_000, qr_interval=2.0, random_state=0))

    rows = [
        ("numba cache load + first call", f"{warm:.2f} s", ""),
        (f"MG tau=17, {args.n:.0e} samples, dt=0.05 (RK4)", f"{t_big:.2f} s",
         f"{t_big / (args.n * 20) * 1e9:.0f} ns/step"),
        (f"MG tau=17, {args.jit_n:.0e} samples, dt=0.05", f"{t_cmp:.3f} s", ""),
        *per_run,
        ("spectrum MG tau=100, 20 exponents, dt=0.1, T=2e4", f"{t_spec:.1f} s",
         (f"N={spec.extra['n_dim']}, lambda1={spec.exponents[0]:.5f}, "
         f"D_KY={spec.kaplan_yorke_dimension:.2f}")),
    ]
    res, err = _jitcdde_run(args.jit_n)
    if res is None:
        rows.append(("jitcdde", "n/a", err))
    else:
        t_jit, t_compile, xj = res
        rows.append(("jitcdde C compilation", f"{t_compile:.1f} s", ""))
        rows.append((f"jitcdde MG tau=17, {args.jit_n:.0e} samples (adaptive)",
                     f"{t_jit:.3f} s", f"skdelay is {t_jit / t_cmp:.1f}x faster"))
        rows.append(("  (same statistics?)", "",
                     (f"mean/std skdelay {x.mean():.4f}/{x.std():.4f}, "
                     f"jitcdde {xj.mean():.4f}/{xj.std():.4f}")))
    width = max(len(r[0]) for r in rows)
    print(f"{'benchmark':<{width}}  {'time':>9}  notes")
    for name, tm, note in rows:
        print(f"{name:<{width}}  {tm:>9}  {note}")


if __name__ == "__main__":
    main()
