"""Oversampled records: the sampling step is chosen from the data."""

import numpy as np
import pytest

from skdelay import analyze_series
from skdelay._sampling import noise_and_increments, sampling_step, white_noise_level
from skdelay.systems import MackeyGlass, measure


@pytest.fixture(scope="module")
def mg_oversampled():
    # Mackey-Glass tau = 17 sampled every 0.05 (20x the usual step): 340 samples per delay
    x = MackeyGlass(tau=17.0).simulate(80_000, sample_dt=0.05, random_state=0)
    return measure(x, noise=0.005, random_state=1)


def test_noise_level_from_the_structure_function(mg_oversampled):
    noise, _, inc = noise_and_increments(mg_oversampled, max_step=16)
    assert noise == pytest.approx(0.005, rel=0.1)  # measure() normalises to unit std
    assert inc[0] < 2 * noise < inc[-1]


@pytest.mark.parametrize("level", [0.01, 0.05])
def test_white_noise_level_from_high_order_differences(level):
    clean = MackeyGlass(tau=17.0).simulate(20_000, random_state=0)
    noise, resolved = white_noise_level(measure(clean, noise=level, random_state=1))
    assert resolved and noise == pytest.approx(level, rel=0.05)  # unit std after measure()
    noise, _ = white_noise_level(measure(clean, random_state=1))
    assert noise < 1e-3  # clean data: only the smooth signal's 8th differences


def test_white_noise_level_of_rough_data_is_only_a_bound():
    from skdelay.datasets import henon

    # a map is not smooth at its sampling step: the differences never level off
    x = measure(henon(20_000, random_state=0), noise=0.01, random_state=1)
    noise, resolved = white_noise_level(x)
    assert not resolved and noise > 0.1


def test_step_one_for_records_that_are_not_oversampled():
    x = measure(MackeyGlass(tau=17.0).simulate(20_000, random_state=0), noise=0.005,
                random_state=1)
    assert sampling_step(x) == 1
    assert sampling_step(MackeyGlass(tau=17.0).simulate(20_000, random_state=0)) == 1


def test_oversampled_record_gets_a_coarser_step_and_the_delay(mg_oversampled):
    step = sampling_step(mg_oversampled)
    # coarser (the raw step has 340 samples per delay), and the delay still spans at least
    # ten coarse samples
    assert 2 <= step <= 34
    res = analyze_series(mg_oversampled, m=(2, 3), tau_min=250, tau_max=430, sample_dt=0.05,
                         quick=True)
    assert res.step == step
    row = res.summary_row()
    assert row["sampling_step"] == step
    print(step, res.delays.to_string())  # the dips behind the verdict (coarse samples)
    # the delay estimate (dip centre) of every significant m within one coarse sample, in
    # record samples (the model's delay is the grid delay next to it with the lowest error)
    good = res.delays[res.delays["significant"]]
    assert len(good) and np.all(np.abs(good["delay"].to_numpy() * step - 340) <= step)
    assert abs(row["delay"] - 340) <= 2 * step
    # the same delay in time units (sample_dt 0.05 of the record)
    assert row["delay_time"] == pytest.approx(row["delay"] * 0.05)
    assert row["delay_time"] == pytest.approx(17.0, abs=2 * 0.05 * step + 1e-9)
    assert "oversampled" in res.summary()


def test_explicit_step_is_used():
    x = measure(MackeyGlass(tau=17.0).simulate(20_000, random_state=0), noise=0.005,
                random_state=1)
    res = analyze_series(x, m=(2, 3), tau_min=8, tau_max=30, quick=True, step=1)
    assert res.step == 1 and abs(res.summary_row()["delay"] - 17) <= 1
    with pytest.raises(ValueError, match="step"):
        analyze_series(x, m=(2,), tau_min=8, tau_max=30, quick=True, step=0)


def test_time_index_gives_the_sampling_interval():
    import pandas as pd

    x = measure(MackeyGlass(tau=17.0).simulate(12_000, random_state=0), noise=0.005,
                random_state=1)
    series = pd.Series(x, index=pd.timedelta_range(0, periods=x.size, freq="2ms"))
    res = analyze_series(series, m=(2, 3), tau_min=8, tau_max=30, quick=True)
    assert res.sample_dt == pytest.approx(0.002)
    assert res.summary_row()["delay_time"] == pytest.approx(17 * 0.002, abs=0.0021)  # 1 sample


def test_model_settings_by_cross_validation_are_used_and_reported():
    x = measure(MackeyGlass(tau=17.0).simulate(12_000, random_state=0), noise=0.01,
                random_state=1)
    res = analyze_series(x, m=(2, 3), tau_min=8, tau_max=30, quick=True, select_model=True)
    table = res.model_selection
    assert table is not None and sorted(set(table["m"])) == [2, 3]
    for m, grid in table.groupby("m"):  # one choice per window length
        assert int(grid["chosen"].sum()) == 1
        best = grid[grid["chosen"]].iloc[0]
        # the summed relative error, each error against its best on the grid (the mean
        # over folds of the per-fold ratios equals the ratio of the means)
        total = grid["one_step"] / grid["one_step"].min() + grid["iterated"] / grid[
            "iterated"].min()
        np.testing.assert_allclose(grid["total"], total, rtol=1e-12)
        # one-standard-error rule: the smoothest setting (most neighbours, then largest
        # ridge) within one standard error of the smallest total
        within = grid[grid["within_one_se"]]
        outside = grid[~grid["within_one_se"]]
        assert outside.empty or within["total"].max() < outside["total"].min()  # a threshold
        assert bool(best["within_one_se"]) and total.idxmin() in within.index
        assert (best["n_neighbors"], best["ridge"]) == max(zip(within["n_neighbors"],
                                                               within["ridge"]))
        # ... and is the one the model of that m was fitted with
        assert res.validation.loc[m, "n_neighbors"] == best["n_neighbors"]
        assert res.validation.loc[m, "ridge"] == best["ridge"]
    best = table[table["chosen"] & (table["m"] == 3)].iloc[0]  # the reported model's
    assert res.options["ridge"] == best["ridge"]
    assert res.options["per_parameter"] == pytest.approx(best["per_parameter"])


@pytest.mark.parametrize("m", [1.5, (2, 2.5), "3", (True,)])
def test_fractional_or_non_integer_m_is_refused(m):
    x = MackeyGlass(tau=17.0).simulate(3000, random_state=0)
    with pytest.raises(ValueError, match="whole window lengths"):
        analyze_series(x, m=m, tau_min=8, tau_max=30, quick=True)


@pytest.mark.parametrize("scale", [1e-300, 1e300])
def test_analysis_at_extreme_scale_equals_unit_scale(scale):
    x = measure(MackeyGlass(tau=17.0).simulate(12_000, random_state=0), noise=0.005,
                random_state=1)
    ref = analyze_series(x, m=(2, 3), tau_min=8, tau_max=30, quick=True).summary_row()
    row = analyze_series(x * scale, m=(2, 3), tau_min=8, tau_max=30, quick=True).summary_row()
    for key in ("delay", "N", "minimal_m"):
        assert row[key] == ref[key], key
    for key in ("delay_error", "lambda_max", "D_KY", "h_KS"):
        assert row[key] == pytest.approx(ref[key], rel=1e-6), key


@pytest.mark.parametrize("dt, smooth", [(0.01, True), (0.5, False)])
def test_smooth_at_step_tells_a_finely_sampled_flow_from_a_rough_record(dt, smooth):
    from skdelay._sampling import smooth_at_step
    from skdelay.systems import Ikeda

    x = measure(Ikeda().simulate(20_000, sample_dt=dt, random_state=0), noise=0.005,
                random_state=1)
    # the high-order differences level off in both ("resolved"); at step 0.5 the level is
    # Ikeda's own fast chaos, half the standard deviation, not noise
    noise, resolved = white_noise_level(x)
    assert resolved and (noise < 0.01) == smooth
    assert smooth_at_step(x) == smooth


def test_settings_are_cross_validated_by_default_unless_the_user_sets_them():
    from skdelay._analysis import AnalysisOptions, _options_from

    assert AnalysisOptions().select_model and not AnalysisOptions.quick().select_model
    assert _options_from(None, False, {}).select_model
    # neighbours or a ridge given by the user are kept (the choice is off) ...
    for given in ({"n_neighbors": 30}, {"ridge": 0.1}):
        opts = _options_from(None, False, dict(given))
        assert not opts.select_model
        assert getattr(opts.model, next(iter(given))) == next(iter(given.values()))
    # ... unless the choice is asked for as well; None (a CLI default) sets nothing
    assert _options_from(None, False, {"ridge": 0.1, "select_model": True}).select_model
    assert _options_from(None, False, {"n_neighbors": None, "ridge": None}).select_model
    assert not _options_from(None, True, {}).select_model
    with pytest.raises(TypeError, match="select_model must be True or False"):
        _options_from(None, False, {"select_model": "yes"})
