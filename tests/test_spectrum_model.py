"""The cross-validated spectrum model: dominant period, free-run score, chosen settings."""

import numpy as np
import pytest

from skdelay._model_selection import (
    dominant_period,
    select_spectrum_model,
    spectrum_of_selection,
)
from skdelay.systems import MackeyGlass, measure


@pytest.fixture(scope="module")
def mg():
    x = MackeyGlass(tau=17.0).simulate(8000, random_state=0)
    return measure(x, noise=0.005, random_state=1)


def test_dominant_period_of_a_sine_and_of_white_noise():
    t = np.arange(4000)
    assert dominant_period(np.sin(2 * np.pi * t / 31.0), 100) == 31
    rng = np.random.default_rng(0)
    p = dominant_period(rng.standard_normal(4000), 50)
    # white noise has no oscillation: either no maximum or one at a random short lag whose
    # autocorrelation is at the noise level
    assert p is None or p < 50


def test_dominant_period_of_mackey_glass_is_its_quasi_period(mg):
    # Mackey-Glass tau = 17 oscillates with a period of about 50 time units
    assert 40 <= dominant_period(mg, 120) <= 60


def test_selection_picks_the_smallest_cross_validated_free_run_error(mg):
    sel = select_spectrum_model(mg, 17, steps=(1, 2), spans=(0.1, 0.2), n_neighbors=(15, 40),
                                ridge=(1e-3,), horizon=20, n_runs=15, random_state=0)
    table = sel.table
    assert int(table["chosen"].sum()) == 1
    best = table[table["chosen"]].iloc[0]
    assert best["error"] == pytest.approx(table["error"].min())
    assert (sel.step, sel.m, sel.options.n_neighbors) == (
        int(best["step"]), int(best["m"]), int(best["n_neighbors"]))
    assert sel.tau == round(17 / sel.step)
    assert set(table["step"]) == {1, 2}
    # free runs from the true history over 20 steps track Mackey-Glass far better than a
    # guess from its distribution (sqrt(2) std)
    assert 0 < best["error"] < 0.5
    assert "step" in sel.describe()


def test_spectrum_of_the_selection_has_the_mackey_glass_exponent(mg):
    sel = select_spectrum_model(mg, 17, steps=(1,), spans=(0.1,), n_neighbors=(20,),
                                ridge=(1e-3,), horizon=20, n_runs=10)
    spec = spectrum_of_selection(mg, sel, n_exponents=4)
    # lambda_1 of Mackey-Glass tau = 17 is about 0.006-0.009 per time unit
    assert 0.002 < spec.exponents[0] < 0.012
    assert spec.sample_dt == pytest.approx(sel.step)


def test_too_short_a_series_for_the_horizon_is_refused():
    x = MackeyGlass(tau=17.0).simulate(600, random_state=0)
    with pytest.raises(ValueError, match="too short"):
        select_spectrum_model(x, 17, steps=(1,), spans=(0.2,), n_neighbors=(10,),
                              ridge=(1e-3,), horizon=400)


def test_the_staged_selection_fits_neighbours_and_ridge_at_the_first_stage_time_scale(mg):
    from skdelay.model_selection import select_spectrum_model_staged

    sel = select_spectrum_model_staged(mg, 17, steps=(1, 2), spans=(0.1, 0.2),
                                       n_neighbors=(15, 40), ridge=(1e-3, 1e-1),
                                       first=(15, 1e-3), horizon=20, n_runs=15,
                                       random_state=0)
    one, two = sel.table[sel.table.stage == 1], sel.table[sel.table.stage == 2]
    assert len(one) == 4 and len(two) == 4 and int(sel.table["chosen"].sum()) == 1
    # stage 2 runs at the step and window of stage 1's best row
    best1 = one.loc[one["error"].idxmin()]
    assert set(two["step"]) == {best1["step"]} and set(two["m"]) == {best1["m"]}
    # the chosen setting is stage 2's best, with a standard error from the folds
    chosen = sel.table[sel.table["chosen"]].iloc[0]
    assert chosen["stage"] == 2 and chosen["error"] == two["error"].min()
    assert (sel.step, sel.m, sel.options.n_neighbors, sel.options.ridge) == (
        chosen["step"], chosen["m"], chosen["n_neighbors"], chosen["ridge"])
    assert np.all(sel.table["error_se"] > 0)
    with pytest.raises(ValueError, match=r"first must be \(n_neighbors, ridge\) of stage 1"):
        select_spectrum_model_staged(mg, 17, first=100)


def test_the_demo_spectrum_ranges_over_the_settings_the_data_cannot_tell_apart(mg):
    from skdelay._demo import spectrum_model

    sel, spec, ranges = spectrum_model(mg, 17, sample_dt=1.0, n_steps=3000, random_state=0)
    two = sel.table[sel.table.stage == 2]
    best = two.loc[two["error"].idxmin()]
    alike = two[two["error"] <= best["error"] + best["error_se"]]
    for key, value in (("lambda_max", spec.exponents[0]), ("D_KY", spec.kaplan_yorke_dimension),
                       ("N", spec.n_positive)):
        lo, hi = ranges[key]
        assert lo <= value <= hi
    if len(alike) > 1:  # other settings as good as the best: their spectra differ
        assert ranges["lambda_max"][1] > ranges["lambda_max"][0]
    else:
        assert ranges["lambda_max"][0] == ranges["lambda_max"][1] == spec.exponents[0]


@pytest.mark.parametrize("factor", [1e-300, 1e300])
def test_selections_at_extreme_scales_equal_those_at_unit_scale(mg, factor):
    # the scorers divide by the series' standard deviation, which underflowed to 0 at 1e-300
    # (a ZeroDivisionError) and overflowed to inf at 1e300 (every score 0, any choice)
    from skdelay._model_selection import select_model_options

    kw = {"per_parameter": (2, 8), "ridge": (1e-3, 1e-1), "n_scored": 150}
    ref, got = select_model_options(mg, 2, 17, **kw), select_model_options(mg * factor, 2, 17, **kw)
    assert got.options == ref.options
    np.testing.assert_allclose(got.table[["one_step", "iterated"]],
                               ref.table[["one_step", "iterated"]], rtol=1e-12)
    assert 0 < ref.table["one_step"].min() < 0.5
    kw = {"steps": (1,), "spans": (0.1,), "n_neighbors": (15, 40), "ridge": (1e-3,),
          "horizon": 20, "n_runs": 8}
    ref, got = select_spectrum_model(mg, 17, **kw), select_spectrum_model(mg * factor, 17, **kw)
    assert got.options == ref.options
    np.testing.assert_allclose(got.table["error"], ref.table["error"], rtol=1e-12)


def _cv_results(one, few):
    """A GridSearchCV ``cv_results_`` of the forecast selection: per-fold errors of the
    settings (k, ridge) = (10, 1e-3), (20, 1e-3), (40, 1e-3), (20, 1e-1)."""
    one, few = np.asarray(one, dtype=float), np.asarray(few, dtype=float)  # (folds, settings)
    res = {"param_model__n_neighbors": np.array([10, 20, 40, 20]),
           "param_model__ridge": np.array([1e-3, 1e-3, 1e-3, 1e-1]),
           "mean_test_one_step": -one.mean(axis=0), "mean_test_iterated": -few.mean(axis=0)}
    for i in range(one.shape[0]):
        res[f"split{i}_test_one_step"], res[f"split{i}_test_iterated"] = -one[i], -few[i]
    return res


def test_the_one_standard_error_rule_takes_the_smoothest_tie_and_nothing_worse():
    from skdelay._model_selection import _one_se, _pick

    few = [[1.0, 1.0, 1.0, 1.0]] * 3
    # k = 10 is best on average; k = 20 is within the folds' spread of it, k = 40 and the
    # large ridge are clearly worse: the rule takes k = 20, the smoothest of the tie
    one = [[1.00, 1.02, 1.50, 1.60], [1.10, 1.12, 1.60, 1.70], [0.90, 0.92, 1.40, 1.50]]
    total, se, within = _one_se(_cv_results(one, few))
    np.testing.assert_allclose(total, [2.0, 2.02, 2.5, 2.6])
    assert se == pytest.approx(np.std([2.0, 2.1, 1.9], ddof=1) / np.sqrt(3), rel=1e-9)
    assert list(within) == [True, True, False, False]
    assert _pick(_cv_results(one, few)) == 1
    # the same means with folds that agree closely: k = 20 is no longer a tie
    tight = [[1.000, 1.020, 1.50, 1.60], [1.001, 1.021, 1.50, 1.60], [0.999, 1.019, 1.50, 1.60]]
    assert _pick(_cv_results(tight, few)) == 0
    # a tie in k is broken by the larger ridge
    one = [[1.00, 1.01, 1.50, 1.01], [1.10, 1.11, 1.60, 1.11], [0.90, 0.91, 1.40, 0.91]]
    assert _pick(_cv_results(one, few)) == 3
