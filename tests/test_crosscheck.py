"""The Takens cross-check of the demo: settings from the data, sentences from the numbers."""

import math

import numpy as np
import pandas as pd
import pytest

from skdelay._crosscheck import TakensCheck, takens_cross_check


def _check(lams, d2):
    kantz = pd.DataFrame({"window": [50, 75], "exponent": lams, "fit_start": [10.0, 10.0],
                          "fit_stop": [60.0, 60.0]}, index=pd.Index([10, 15], name="dim"))
    return TakensCheck(lag=5, kantz=kantz, n_section=7000, d2_raw=5.0, d2_raw_spread=0.4,
                       d2_reduced=d2, d2_reduced_spread=0.1)


def test_sentence_follows_the_numbers():
    check = _check([0.003, 0.004], 2.0)
    inside = check.sentence({"lambda_max": 0.0035, "D_KY": 3.2}, scale=1000, unit="1/ms")
    assert "consistent with Kantz's estimates (3 to 4 1/ms" in inside
    assert "D2 + 1 = 3, close to the model's D_KY 3.2" in inside
    above = check.sentence({"lambda_max": 0.009, "D_KY": 9.4}, scale=1000, unit="1/ms")
    assert "lies above Kantz's estimates" in above
    assert "below the model's D_KY 9.4" in above and "about 8 dimensions" in above
    short = _check([0.003, 0.004], math.nan).sentence({"lambda_max": 0.001, "D_KY": 3.0})
    assert "lies below" in short and "too short for a correlation dimension" in short
    table = check.table({"lambda_max": 0.0035, "D_KY": 3.2}, {"lambda_max": 0.003,
                                                                "D_KY": 3.4}, scale=1000)
    assert table.loc["lambda_max", "standard embedding (Kantz)"] == "3 .. 4"
    assert table.loc["lambda_max", "exact (simulator)"] == "3"


def test_lag_and_windows_come_from_the_data():
    # a noisy sine with period 40: the mutual information first dips at a quarter period
    rng = np.random.default_rng(0)
    t = np.arange(12_000)
    x = np.sin(2 * np.pi * t / 40) + 0.3 * np.sin(2 * np.pi * t / 97) + 0.02 * rng.normal(
        size=t.size)
    check = takens_cross_check(x, 40, random_state=0)
    assert 7 <= check.lag <= 13
    # windows of one to two delays
    assert list(check.kantz["window"]) == sorted(check.kantz["window"])
    assert 40 <= check.kantz["window"].iloc[0] <= 40 + check.lag
    assert check.kantz["window"].iloc[-1] <= 80 + check.lag
    assert check.n_section > 250  # about one maximum per 40 samples


def test_bad_input():
    with pytest.raises(ValueError, match="at least 2 samples"):
        takens_cross_check(np.random.default_rng(0).normal(size=1000), 1)
    with pytest.raises(ValueError, match="too short"):
        takens_cross_check(np.sin(np.arange(400) / 3.0), 150)
