"""Oversampled delay equations: no significant dip at the raw step, the delay at the chosen one.

The delay equation here has a right-hand side that depends *only* on the delayed
value, ``dx/dt = x(t-1) (g exp(-x(t-1)^2) - 1)``: sampled 50 times per delay,
the one-step increment is far above the 0.5 % measurement noise, yet the first
window extrapolates almost all of it, so what the delayed window could add (the
second difference) is buried in the noise and sigma_m(tau) shows no significant
dip.  :func:`skdelay._sampling.sampling_step` finds the coarser step from the
data, and there the dip sits at the delay.
"""

import warnings

import numpy as np
import pytest
from numba import njit

from skdelay import DelaySelectorCV, NoDipWarning, analyze_series, lagged_windows
from skdelay._embedding import required_lags
from skdelay._sampling import sampling_step
from skdelay.systems import Ikeda, measure

PER_DELAY = 50


@njit(cache=True)
def _delayed_only(g, n, per_delay, substeps):
    """Heun steps of dx/dt = x(t-1) (g exp(-x(t-1)^2) - 1), every ``substeps``-th kept."""
    h = 1.0 / per_delay / substeps
    d = per_delay * substeps
    steps = (n + 4000) * substeps
    x = np.empty(steps + d + 1)
    for i in range(d + 1):
        x[i] = 1.0 + 0.1 * np.sin(i * 0.01)
    for i in range(d, d + steps):
        a, b = x[i - d], x[i - d + 1]
        x[i + 1] = x[i] + 0.5 * h * (a * (g * np.exp(-a * a) - 1.0)
                                     + b * (g * np.exp(-b * b) - 1.0))
    return x[d + 4000 * substeps::substeps][:n]


@pytest.fixture(scope="module")
def delayed_only():
    raw = _delayed_only(4.3, 20_000, PER_DELAY, 5)
    assert np.all(np.isfinite(raw)) and raw.std() > 0.5  # bounded, irregular oscillation
    return measure(raw, noise=0.005, random_state=0)


def test_raw_step_has_no_significant_dip_and_no_delay(delayed_only):
    X, y = lagged_windows(delayed_only, required_lags(3, 90))
    with pytest.warns(NoDipWarning, match="no window length shows a significant") as rec:
        sel = DelaySelectorCV(m=(2, 3), tau=range(20, 91), n_queries=2000,
                              random_state=0).fit(X, y)
    print(sel.delay_by_m_.to_string())  # the test behind the verdict
    assert np.isnan(sel.delay_) and np.isnan(sel.delay_error_)
    assert not sel.delay_by_m_["significant"].any()
    assert "a coarser sampling step" in str(rec[0].message)


def test_automatic_step_finds_the_delay_within_one_coarse_sample(delayed_only):
    step = sampling_step(delayed_only)
    # at least 2 (the raw step shows no dip), and the delay still spans several samples
    assert 2 <= step <= PER_DELAY // 5
    with warnings.catch_warnings():
        warnings.simplefilter("error", NoDipWarning)  # the coarse scan has a significant dip
        res = analyze_series(delayed_only, m=(2, 3), tau_min=20, tau_max=90, quick=True)
    row = res.summary_row()
    print(step, res.delays.to_string())  # the dips behind the verdict (coarse samples)
    assert res.step == step and row["sampling_step"] == step
    good = res.delays[res.delays["significant"]]
    assert len(good)  # at the raw step no m had a significant dip
    # the delay estimate (dip centre) of every significant m, in record samples, within one
    # coarse sample of the delay
    centres = good["delay"].to_numpy() * step
    assert np.all(np.abs(centres - PER_DELAY) <= step), centres
    assert "oversampled" in res.summary()


@pytest.fixture(scope="module")
def ikeda_fine():
    # 500 samples per delay, 100 per response time: smooth at the sampling step
    raw = Ikeda().simulate(40_000, sample_dt=0.01, random_state=4)
    return measure(raw, noise=0.005, random_state=4)


def test_coarser_steps_are_tried_where_the_chosen_step_shows_no_dip(ikeda_fine):
    # the second-difference rule keeps step 1 (its structure function is not quadratic
    # over the first lags), where no m has a significant dip
    assert sampling_step(ikeda_fine) == 1
    res = analyze_series(ikeda_fine, m=(2, 3), tau_min=400, tau_max=600, sample_dt=0.01,
                         quick=True)
    print(res.steps_tried, res.delays.to_string())  # the dips behind the verdict
    assert res.steps_tried[0] == 1 and res.step == res.steps_tried[-1] > 1
    good = res.delays[res.delays["significant"]]
    assert len(good)
    delay = 500 / res.step  # in coarse samples
    # every significant dip's error bar holds the delay, within 1.5 coarse samples (the
    # dip of a flow sits up to a sample early: 123.9-124.6 at step 4)
    assert np.all(np.abs(good["delay"] - delay) <= good["delay_error"])
    assert np.all(np.abs(good["delay"] - delay) <= 1.5)
    assert "no window length showed a significant forecast-error dip" in res.summary()
    assert "every 4th sample shows one" in res.summary() and res.step == 4
    assert "delay per m (in steps of 4 samples): " in res.summary()
    assert res.summary_row()["steps_tried"] == list(res.steps_tried)
    d = res.to_dict()
    assert d["n_record"] == ikeda_fine.size and d["n_samples"] == res.series.size


def test_coarser_steps_find_no_dip_where_there_is_no_delay():
    # smooth noise (white noise through a Gaussian filter of 20 samples) has no delay: no
    # rung of the ladder may report a dip
    rng = np.random.default_rng(0)
    kernel = np.exp(-0.5 * (np.arange(-80, 81) / 20.0) ** 2)
    x = measure(np.convolve(rng.standard_normal(40_000 + 160), kernel, mode="valid"),
                noise=0.005, random_state=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NoDipWarning)
        res = analyze_series(x, m=(2, 3), tau_min=40, tau_max=300, quick=True)
    print(res.steps_tried, res.delays.to_string())
    assert len(res.steps_tried) > 1 and res.step == res.steps_tried[0]
    assert not res.delays["significant"].any()
    assert "showed no significant forecast-error dip either" in res.summary()
    # the record's own length, not the analysed samples times the step (13334 x 3)
    assert res.summary().startswith(f"series: {x.size} samples") and x.size == 40_000
