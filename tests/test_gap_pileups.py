"""A clipped end seen as samples piled up at one value; indicators "off" against their null."""

from types import SimpleNamespace

import numpy as np
import pytest

from skdelay.gap import diagnose_gap, get_effect
from skdelay.gap._diagnose import off_indicators
from skdelay.gap._indicators import PileUps
from skdelay.gap._signature import zscore
from skdelay.systems import Ikeda

# seeds of these tests (never those of benchmarks/gap_withheld.py, which start at 9e6)
SEED = 4242


def test_pile_up_feature_counts_ties_at_each_end():
    x = np.sin(np.linspace(0, 200, 5000)) + 0.01 * np.random.default_rng(SEED).standard_normal(5000)
    ind = PileUps()
    ind.setup(x, [x], 1.0, None)
    clean = ind.compute(x)
    assert clean == pytest.approx(np.sqrt([1 / 5000, 1 / 5000]))
    y = get_effect("clipping").apply(x, {"low": -np.inf, "high": 1.0})
    held = np.count_nonzero(zscore(x) >= 1.0)
    assert held > 100  # a sine spends a fair share of its time above 1 std
    assert ind.compute(y) == pytest.approx(np.sqrt([1 / 5000, held / 5000]))
    lo, hi = ind.bounds()
    assert lo[0] == hi[0] == x.min() and lo[1] == hi[1] == x.max()


def _problem(null, gap, z):
    ev = SimpleNamespace(gaps={"segment": gap}, z={"segment": np.asarray(z, dtype=float)})
    return SimpleNamespace(null_by_indicator={"segment": null}), ev


def test_off_indicator_must_exceed_every_clean_runs_own_gap():
    # median 0, but one clean run reached 5.0 against the others: 2.0 is within the null
    prob, ev = _problem([0.0, 0.0, 5.0, 0.0, 0.1, 0.0], 2.0, [2.0, -1.0])
    assert off_indicators(prob, ev) == {}
    prob, ev = _problem([0.0, 0.0, 5.0, 0.0, 0.1, 0.0], 5.5, [3.0, -1.0])
    assert set(off_indicators(prob, ev)) == {"segment"}
    # a quiet null keeps the old rule: IND_MIN_GAP + 3 x median (20 bins: beyond chance)
    prob, ev = _problem([0.0, 0.2, 0.3, 0.1, 0.2, 0.0], 1.8, [2.0, -1.0] * 10)
    assert set(off_indicators(prob, ev)) == {"segment"}
    # one bin far off is off whatever the gap
    prob, ev = _problem([0.0, 0.0, 5.0, 0.0, 0.1, 0.0], 0.5, [9.0, 0.0])
    assert set(off_indicators(prob, ev)) == {"segment"}


def test_the_record_gap_must_exceed_every_clean_runs_own_gap_too():
    # the whole-record threshold follows the indicators' rule: the electro-optic control in
    # ADC counts of benchmark seed 16.5e6 (leave-one-out gaps, rounded) had a gap of 8.65
    # against the median rule's 5 + 3 x 0.97 = 7.9, and one clean run reached 15.8
    from skdelay.gap._diagnose import MIN_GAP, no_gap_threshold

    heavy = [0.0, 0.88, 0.89, 1.04, 5.53, 15.8]
    assert no_gap_threshold(heavy, MIN_GAP) == pytest.approx(15.8)
    assert no_gap_threshold(heavy, MIN_GAP) > 8.65
    # a quiet null keeps the median rule
    quiet = [0.42, 0.65, 0.75, 1.28, 1.39, 5.79]
    assert no_gap_threshold(quiet, MIN_GAP) == pytest.approx(MIN_GAP + 3.0 * np.median(quiet))


def test_clipped_ikeda_record_is_found_with_its_level():
    """Ikeda at step 0.5 is nearly white; 1 % clipped at the low end moved its histogram
    little (the gap was near the no-gap threshold), the tied samples stand out."""
    ik = Ikeda()
    x = ik.simulate(6000, sample_dt=0.5, random_state=SEED)
    z = (x - x.mean()) / x.std()
    low = float(np.quantile(z, 0.01))
    real = get_effect("clipping").apply(x, {"low": low, "high": np.inf})
    rep = diagnose_gap(real, ik, sample_dt=0.5, random_state=SEED + 1,
                       effects=["clipping", "measurement_noise", "outliers", "lowpass"])
    assert rep.best_effect == "clipping"
    fit = rep.effects.set_index("effect").loc["clipping", "params"]
    assert fit["low"] == pytest.approx(low, abs=0.1) and not np.isfinite(fit["high"])
    assert rep.shrink > 0.7
    top = rep.where.iloc[0]
    assert top["indicator"] == "pile_ups" and top["peak"] == pytest.approx(real.min())


def test_clipped_end_survives_noise_into_the_second_round():
    """Noise removes most of the gap first; the tied samples at the clipped end stay off
    and lead the second round to the clipping (a localised discrepancy is not masked)."""
    from skdelay.systems import MackeyGlass

    mg = MackeyGlass()
    x = mg.simulate(6000, random_state=SEED + 2)
    z = (x - x.mean()) / x.std()
    high = float(np.quantile(z, 0.99))
    y = get_effect("measurement_noise").apply(x, {"noise": 0.05}, random_state=SEED + 3)
    y = get_effect("clipping").apply(y, {"low": -np.inf, "high": high})
    rep = diagnose_gap(y, mg, random_state=SEED + 4,
                       effects=["measurement_noise", "dynamical_noise", "clipping", "lowpass"])
    assert rep.combined is not None
    assert set(rep.combined["effects"]) == {"measurement_noise", "clipping"}
    params = dict(zip(rep.combined["effects"], rep.combined["params"]))
    assert params["clipping"]["high"] == pytest.approx(high, abs=0.15)
    assert params["measurement_noise"]["noise"] == pytest.approx(0.05, rel=0.2)


def _family(gap, z, n_other=9):
    """The indicator ``segment`` among ``n_other`` quiet ones (all with an all-zero null)."""
    gaps = {f"i{j}": 0.0 for j in range(n_other)} | {"segment": gap}
    zs = {f"i{j}": np.zeros(9) for j in range(n_other)} | {"segment": np.asarray(z, float)}
    null = {k: [0.0] * 6 for k in gaps}
    return SimpleNamespace(null_by_indicator=null), SimpleNamespace(gaps=gaps, z=zs)


def test_a_few_bin_indicator_is_off_only_beyond_the_chi_square_tail():
    """Nine bins with a mean squared z of 2.43 (gap 1.43, all-zero null): twice the null
    value, but p = 0.009 by chance, above 0.05 / 10 for one of ten indicators -- not
    "still off" (an Ikeda record fitted with its true spikes, benchmark seed 9.6e6, got a
    spurious drift added on top of that).  The same excess over 100 bins is far beyond
    chance, and so is a mean squared z of 3 over nine bins (p = 0.0014)."""
    from scipy import stats

    from skdelay.gap._diagnose import OFF_ALPHA

    p = stats.chi2.sf(2.43 * 9, 9)
    assert p == pytest.approx(0.0093, abs=5e-4) and OFF_ALPHA / 10 < p < OFF_ALPHA
    assert off_indicators(*_family(1.43, np.sqrt(2.43) * np.ones(9))) == {}
    # alone it is one question at OFF_ALPHA, and off
    assert set(off_indicators(*_family(1.43, np.sqrt(2.43) * np.ones(9), 0))) == {"segment"}
    assert set(off_indicators(*_family(1.43, np.sqrt(2.43) * np.ones(100)))) == {"segment"}
    assert stats.chi2.sf(3.0 * 9, 9) < OFF_ALPHA / 10
    assert set(off_indicators(*_family(2.0, np.sqrt(3.0) * np.ones(9)))) == {"segment"}


def test_a_line_is_judged_on_its_own_not_among_all_indicators():
    """The spectral-line indicator's bins are lines the record was already shown to have:
    each is one question.  z = 2.74 (p = 0.006 for one line) among ten indicators is off,
    although a ten-bin indicator of the same mean z^2 is not; z = 1.5 (p = 0.13) is not."""
    def family(z):
        prob, ev = _family(float(np.mean(np.square(z))) - 1.0, z)
        ev.gaps["spectral_line"] = ev.gaps.pop("segment")
        ev.z["spectral_line"] = ev.z.pop("segment")
        prob.null_by_indicator["spectral_line"] = prob.null_by_indicator.pop("segment")
        return prob, ev

    assert set(off_indicators(*family([2.74]))) == {"spectral_line"}
    assert set(off_indicators(*family([0.3, 2.74]))) == {"spectral_line"}  # 0.05 / 2 lines
    assert off_indicators(*family([1.5])) == {}
    assert off_indicators(*_family(2.74**2 - 1.0, [2.74])) == {}  # "segment": one of ten
