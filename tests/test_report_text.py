"""Report sentences follow the numbers they describe."""

from types import SimpleNamespace

import pandas as pd
import pytest

from skdelay._report import delay_sentence, faithful_sentence, revival_sentence


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
