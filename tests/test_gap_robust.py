"""Robustness of the gap diagnosis: fit outcomes, effect hooks, user-code boundaries, scale."""

import dataclasses
import re
from typing import ClassVar

import numpy as np
import pytest

from skdelay.gap import Effect, diagnose_gap, get_effect, register_effect, unregister_effect
from skdelay.gap._effects import NotApplicable
from skdelay.gap._fit import FitResult, fit_effect
from skdelay.gap._problem import GapProblem
from skdelay.gap._signature import mean_std, zscore
from skdelay.systems import MackeyGlass

MG = MackeyGlass()
N = 3000
HUM = {"frequency": 0.0831, "amplitude": 0.08, "phase": 0.3}


def hum_data(seed=4101, n=N):
    return get_effect("periodic_interference").apply(MG.simulate(n, random_state=seed), HUM)


@pytest.fixture(scope="module")
def problem():
    return GapProblem(hum_data(), MG, n_sims=3, random_state=0)


# ------------------------------------------------------------------ fit outcome
def test_fit_result_is_a_frozen_outcome(problem):
    res = fit_effect(get_effect("periodic_interference"), problem)
    assert isinstance(res, FitResult) and res.ok and res.status == "ok" and res.reason == ""
    assert abs(res.params["frequency"] - HUM["frequency"]) < 1.0 / N
    assert res.gap_after < 0.2 * problem.before.gap
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.status = "failed"
    # an effect that does not apply: a failed outcome with the effect's own reason
    bad = fit_effect(get_effect("parameter_drift"), _OnlyTauProblem(problem))
    assert bad.status == "failed" and "no numeric parameter besides tau" in bad.reason
    assert np.isnan(bad.gap_after)


class _OnlyTauProblem:
    """A problem whose simulator has no parameter but tau (parameter_drift cannot act)."""

    def __init__(self, problem):
        self.__dict__.update(problem.__dict__)
        self.simulator = type("OnlyTau", (), {"params": {"tau": 17.0}})()

    def evaluate(self, chain, tier="full"):
        raise AssertionError("never evaluated")


# ------------------------------------------------------------------ hooks on the base class
def test_effect_hooks_have_default_implementations(problem):
    for hook in ("initial", "search", "guess", "check", "describe", "search_bounds"):
        assert callable(getattr(Effect, hook))

    calls = []

    class Offset(Effect):
        name = "offset_hook_test"
        bounds: ClassVar[dict] = {"size": (0.0, 1.0)}

        def initial(self, problem):
            calls.append("initial")
            return {"size": 0.25}

        def apply(self, x, params, *, sample_dt=1.0, random_state=None):
            return x + params["size"] * x.std()

    res = fit_effect(Offset(), problem)
    assert calls == ["initial"] and res.ok
    # the default search evaluated the objective (grid + refinement), not just the guess
    assert res.n_evals >= 7


# ------------------------------------------------------------------ user-code boundary
class Exploding(Effect):
    name = "exploding_test"
    bounds: ClassVar[dict] = {"size": (0.1, 1.0)}

    def apply(self, x, params, *, sample_dt=1.0, random_state=None):
        return x / 0 if params["size"] > 2 else {}["missing"]  # a KeyError from user code


class NaNEffect(Effect):
    name = "nan_effect_test"
    bounds: ClassVar[dict] = {"size": (0.1, 1.0)}

    def apply(self, x, params, *, sample_dt=1.0, random_state=None):
        y = np.array(x, dtype=float)
        y[5] = np.nan
        return y


def test_user_effect_raising_fails_that_candidate_only():
    real = hum_data()
    rep = diagnose_gap(real, MG, effects=[Exploding(), NaNEffect(), "periodic_interference"],
                       n_sims=3, random_state=0, combine=False)
    table = rep.effects.set_index("effect")
    assert rep.best_effect == "periodic_interference"
    assert table.loc["exploding_test", "status"] == "failed"
    assert "apply() raised KeyError" in table.loc["exploding_test", "reason"]
    assert table.loc["nan_effect_test", "status"] == "failed"
    assert "non-finite" in table.loc["nan_effect_test", "reason"]
    assert list(rep.effects.effect[-2:]) in (["exploding_test", "nan_effect_test"],
                                             ["nan_effect_test", "exploding_test"])


def test_bug_in_builtin_effect_is_not_swallowed(monkeypatch):
    def broken(self, real, sim, sample_dt):
        raise TypeError("a bug in our own code")

    monkeypatch.setattr(type(get_effect("measurement_noise")), "guess", broken)
    with pytest.raises(TypeError, match="a bug in our own code"):
        diagnose_gap(hum_data(), MG, effects=["measurement_noise"], n_sims=3, random_state=0)


class BadShapeMG:
    """Returns (n, 2) or NaN output when the delay is changed, clean runs otherwise."""

    params = MG.params

    def __init__(self, mode):
        self.mode = mode

    def simulate(self, n_samples, *, sample_dt=1.0, random_state=None, **overrides):
        x = MG.simulate(n_samples, sample_dt=sample_dt, random_state=random_state,
                        **{k: v for k, v in overrides.items() if k != "tau"})
        if "tau" not in overrides:
            return x
        if self.mode == "2d":
            return np.column_stack([x, x])
        x[n_samples // 2] = np.nan
        return x


@pytest.mark.parametrize("mode, reason", [("2d", r"shape \("), ("nan", "non-finite")])
def test_simulator_bad_output_fails_that_candidate(mode, reason):
    rep = diagnose_gap(hum_data(), BadShapeMG(mode), n_sims=3, random_state=0, combine=False,
                       effects=["delay_mismatch", "periodic_interference"])
    table = rep.effects.set_index("effect")
    assert table.loc["delay_mismatch", "status"] == "failed"
    assert re.search(reason, table.loc["delay_mismatch", "reason"])
    assert rep.best_effect == "periodic_interference"


def test_simulator_2d_output_with_own_parameters_is_an_error():
    class TwoColumns:
        params = MG.params

        def simulate(self, n_samples, **kw):
            x = MG.simulate(n_samples, random_state=kw.get("random_state"))
            return np.column_stack([x, x])

    with pytest.raises(ValueError, match=r"fails with its own parameters.*shape \("):
        diagnose_gap(hum_data(), TwoColumns(), n_sims=3)


# ------------------------------------------------------------------ names
@pytest.mark.parametrize("name", ["ok_name\n", "Bad Name", None, "", "1abc", "caps_Name"])
def test_effect_names_validated_on_every_path(name):
    cls = type("Named", (Effect,), {"name": name, "bounds": {"a": (0.0, 1.0)},
                                    "apply": lambda self, x, params, **kw: x})
    with pytest.raises(ValueError, match="not valid"):
        register_effect(cls)
    with pytest.raises(ValueError, match="not valid"):
        get_effect(cls)
    with pytest.raises(ValueError, match="not valid"):
        get_effect(cls())
    with pytest.raises(ValueError, match="not valid"):
        diagnose_gap(hum_data(), MG, effects=[cls()])
    if name is not None:
        with pytest.raises(ValueError, match="not valid|no effect named"):
            unregister_effect(name)


def test_not_applicable_is_a_value_error():
    assert issubclass(NotApplicable, ValueError)


# ------------------------------------------------------------------ scale
def test_mean_std_and_zscore_at_extreme_scale():
    x = MG.simulate(N, random_state=3)
    m, s = mean_std(x)
    for k in (1e-200, 1e200, 1e-300):
        mk, sk = mean_std(k * x)
        assert mk == pytest.approx(k * m, rel=1e-12) and sk == pytest.approx(k * s, rel=1e-12)
        assert np.allclose(zscore(k * x), zscore(x), atol=1e-9)


def test_extreme_scale_is_not_constant_and_diagnosed_alike():
    real = hum_data()
    kw = {"effects": ["periodic_interference", "measurement_noise"], "n_sims": 3,
          "random_state": 0, "combine": False}
    ref = diagnose_gap(real, MG, **kw)
    for k in (1e-200, 1e200):
        rep = diagnose_gap(k * real, MG, **kw)
        assert rep.best_effect == ref.best_effect == "periodic_interference"
        assert rep.gap_before == pytest.approx(ref.gap_before, rel=1e-6)
        assert rep.info["real_std"] == pytest.approx(k * np.std(real), rel=1e-9)
        hist = rep.where[rep.where.indicator == "histogram"]
        ref_hist = ref.where[ref.where.indicator == "histogram"]
        assert np.allclose(hist.low.to_numpy() / k, ref_hist.low.to_numpy(), rtol=1e-9)
