"""Extensive chaos of Mackey-Glass: the Lyapunov dimension grows linearly with the delay.

For tau = 50, 100, 200 (a=0.2, b=0.1, n=10) the exact spectrum of the
discretised DDE gives the Kaplan-Yorke dimension D_KY, the dimension density
D_KY / tau, lambda_1 * tau and the KS entropy.  Long-delay theory (Farmer
1982; Giacomelli & Politi 1996): D_KY grows about linearly with tau (constant
density) while lambda_1 * tau and h_KS * tau stay of the same order.

Run: ``python benchmarks/dimension_density.py [--duration 20000] [--dt 0.2]``.
"""

from __future__ import annotations

import argparse
import math
import time

from skdelay.systems import MackeyGlass


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--taus", type=float, nargs="+", default=[50.0, 100.0, 200.0])
    parser.add_argument("--duration", type=float, default=20_000.0)
    parser.add_argument("--dt", type=float, default=0.2)
    args = parser.parse_args(argv)
    print(f"{'tau':>6} {'k':>4} {'lambda_1':>9} {'+-':>8} {'lambda_1*tau':>12} {'D_KY':>7} "
          f"{'D_KY/tau':>9} {'h_KS':>8} {'h_KS*tau':>9} {'n_pos':>5} {'time':>7}")
    for tau in args.taus:
        k = math.ceil(0.15 * tau) + 6  # D_KY is ~0.1 tau: enough exponents to close the sum
        t0 = time.perf_counter()
        sp = MackeyGlass(tau=tau).lyapunov_spectrum(
            k, dt=args.dt, duration=args.duration, qr_interval=2.0, random_state=0)
        dky = sp.kaplan_yorke_dimension
        print(f"{tau:6.0f} {k:4d} {sp.exponents[0]:9.5f} {sp.spread[0]:8.5f} "
              f"{sp.exponents[0] * tau:12.3f} {dky:7.2f} {dky / tau:9.4f} {sp.ks_entropy:8.5f} "
              f"{sp.ks_entropy * tau:9.3f} {sp.n_positive:5d} {time.perf_counter() - t0:6.1f}s",
              flush=True)


if __name__ == "__main__":
    main()
