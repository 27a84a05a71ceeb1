"""Report sentences follow the numbers they describe."""

import warnings
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from scipy.signal import lfilter

from skdelay import NoDipWarning, analyze_series
from skdelay._report import (
    analysis_sections,
    delay_sentence,
    faithful_sentence,
    revival_sentence,
    spectrum_caveat,
)


def _result(delay=40.0, significant=True, minimal_m=None, reason=""):
    delays = pd.DataFrame({"delay": [delay], "delay_error": [0.7], "significant": [significant],
                           "reason": ["" if significant else "the dip is 1.2 standard errors deep"]},
                          index=pd.Index([5], name="m"))
    return SimpleNamespace(delays=delays, m=5, delay=round(delay), minimal_m=minimal_m, step=1,
                           minimal_m_reason=reason, runs={2: None, 5: None})


@pytest.mark.parametrize(("lag", "words"), [
    (41, "at the delay"), (46, "6 samples beyond the delay"),
    (284, "7.1 times the delay"), (25, "15 samples before the delay"),
])
def test_revival_sentence_matches_the_distance(lag, words):
    text = revival_sentence("autocorrelation", lag, _result())
    assert words in text
    assert ("slightly" not in text) and (("beyond" in text) == (lag > 42))


def test_no_dip_means_no_delay_claims():
    res = _result(significant=False)
    assert "cannot tell the delay" in delay_sentence(res)
    assert "beyond" not in revival_sentence("autocorrelation", 284, res)
    assert "gives the delay 40.0 +- 0.7" in delay_sentence(_result())


def test_faithful_sentence_follows_the_verdict():
    assert "m_d = 3" in faithful_sentence(_result(minimal_m=3))
    text = faithful_sentence(_result(reason="the model with m=5 is not faithful"))
    assert text.startswith("No model up to m = 5 is faithful") and "m=5" in text


def test_a_dip_of_another_window_length_is_named_not_denied():
    # the model's m (5) has no significant dip, m = 2 has one: "cannot tell" would be false
    res = _result(significant=False)
    res.delays = pd.concat([pd.DataFrame(
        {"delay": [39.6], "delay_error": [1.1], "significant": [True], "reason": [""]},
        index=pd.Index([2], name="m")), res.delays])
    text = delay_sentence(res)
    assert "cannot tell" not in text and "m = 2: 39.6 +- 1.1" in text
    assert text.startswith("The forecast error of m = 5 shows no significant dip")


def test_spectrum_caveat_only_for_a_model_without_an_attractor():
    res = _result()
    res.validation = pd.DataFrame({"status": [""]}, index=pd.Index([5], name="m"))
    assert spectrum_caveat(res) == ""
    res.validation.loc[5, "status"] = "not faithful: histogram 0.07 > 0.05"
    assert spectrum_caveat(res) == ""  # a wrong histogram still has an attractor
    res.validation.loc[5, "status"] = "not faithful: collapsed onto a fixed point at step 200"
    text = spectrum_caveat(res)
    assert "collapsed onto a fixed point at step 200" in text and "not of an attractor" in text


def _ar2(n, seed):
    """A linear stochastic AR(2) process, x[t] = 1.6 x[t-1] - 0.8 x[t-2] + e[t]: no delay,
    no chaos."""
    return lfilter([1.0], [1.0, -1.6, 0.8], np.random.default_rng(seed).standard_normal(n))


def test_an_analysis_without_a_dip_warns_and_says_what_its_spectrum_is():
    with pytest.warns(NoDipWarning, match="no window length shows a significant") as rec:
        res = analyze_series(_ar2(6000, 5), quick=True, random_state=0)
    assert "shortest delay" in str(rec[0].message)  # not "scan delays on both sides of 1"
    assert not res.delays["significant"].any()
    text = res.summary()
    assert "the data cannot tell the delay" in text
    assert "D_KY/tau" not in text  # a dimension per delay needs a delay
    # the AR(2) models' free runs decay onto the process's fixed point; the exponents of
    # their local maps along the noisy data must not read as an attractor's
    status = res.validation.loc[res.m, "status"]
    print(text, status, sep="\n")
    assert ("not of an attractor of the model" in text) == ("collapsed" in status)
    assert "collapsed" in status
    sections = analysis_sections(res)
    assert "not of an attractor of the model" in str(sections[2][1])
    table = sections[0][1][1]  # the summary table: no measured delay, no dimension density
    assert table["delay [samples]"] == f"{res.delay} (no significant dip: the grid minimum)"
    assert table["dimension density D_KY/tau [1/time unit]"] == "- (no delay)"


def test_an_analysis_with_a_dip_does_not_warn():
    from skdelay.systems import MackeyGlass, measure

    x = measure(MackeyGlass(tau=17.0).simulate(8000, random_state=0), noise=0.005,
                random_state=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error", NoDipWarning)
        res = analyze_series(x, m=(2, 3), tau_max=40, quick=True, random_state=0)
    assert res.delays["significant"].all()
    assert "cannot tell" not in res.summary() and "not of an attractor" not in res.summary()
    assert "D_KY/tau = " in res.summary()
