"""Measurement or dynamical noise? Both candidates fitted on the benchmark's electro-optic cases.

The withheld-effect benchmark (``gap_withheld.py``, moderate strength, seed
9e6) calls its electro-optic dynamical-noise case measurement noise.  This
script rebuilds that case and the measurement-noise case, fits both noise
effects on each (``GapProblem`` + ``fit_effect``, as ``diagnose_gap`` does) and
prints the gap left per indicator.  Then it evaluates dynamical noise at its
true strength, to separate a biased indicator from one that scatters with the
noise realisation.

Run (about two minutes on one core)::

    python benchmarks/gap_noise_types.py
"""

from __future__ import annotations

import warnings

import numpy as np
from gap_withheld import build_cases, make_real

from skdelay.gap._effects import get_effect
from skdelay.gap._fit import fit_effect
from skdelay.gap._problem import GapProblem
from skdelay.systems import ElectroOpticOscillator, Ikeda, MackeyGlass

DT = 0.25


def _fmt(gaps):
    return ", ".join(f"{k} {v:.2f}" for k, v in gaps.items() if v > 0.05) or "nothing off"


def main():
    warnings.simplefilter("ignore")
    chosen = [("mackey_glass", MackeyGlass(), 1.0), ("ikeda_dt0.5", Ikeda(), 0.5),
              ("electro_optic_dt0.25", ElectroOpticOscillator(), DT)]
    cases = build_cases(chosen, 1, 1, 2, 9_000_000, 6000, 1, "moderate")
    for true in ("dynamical_noise", "measurement_noise"):
        case = next(c for c in cases if c["label"].startswith("electro") and c["true"] == true)
        (name, params), = case["chain"]
        real = make_real(case["system"], case["chain"], 6000, case["seed"], DT)
        problem = GapProblem(real, case["system"], sample_dt=DT,
                             random_state=case["seed"] % 9973, n_jobs=1)
        print(f"== hidden {name} {params}; gap before {problem.before.gap:.2f}")
        for effect in ("measurement_noise", "dynamical_noise"):
            fit = fit_effect(get_effect(effect), problem)
            print(f"   fitted {effect} {fit.params}: gap {fit.gap_after:.2f} ({_fmt(fit.gaps)})")
        if name == "dynamical_noise":
            ev = problem.evaluate([(get_effect(name), dict(params))], "full")
            ratio = ev.std["histogram"] / np.sqrt(problem.base_var["histogram"])
            print(f"   at the true strength: gap {ev.gap:.2f} ({_fmt(ev.gaps)}); histogram "
                  f"spread / clean spread {ratio.min():.2f}-{ratio.max():.2f}, largest |z| "
                  f"{np.abs(ev.z['histogram']).max():.1f}")


if __name__ == "__main__":
    main()
