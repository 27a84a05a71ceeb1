"""GapReport read at a glance: three conditioned sentences and the one figure that shows it."""

import dataclasses
import re

import matplotlib
import numpy as np
import pandas as pd
import pytest

from skdelay.gap import diagnose_gap
from skdelay.systems import MackeyGlass

matplotlib.use("Agg")
MG = MackeyGlass()
N = 8000
F0 = 0.0831


@pytest.fixture(scope="module")
def hum_report():
    x = MG.simulate(N, random_state=8101)
    real = 5.0 + 2.0 * (x + 0.06 * x.std() * np.sin(2 * np.pi * F0 * np.arange(N)))
    return diagnose_gap(real, MG, random_state=0, n_jobs=2,
                        effects=["periodic_interference", "measurement_noise"])


def sentences(text):
    head = text.split("\n\n")[0]
    return re.split(r"(?<=\.) (?=[A-Z])", head)


def test_three_sentences_fully_explained(hum_report):
    rep = hum_report
    assert rep.explained == "fully", rep.reasons
    where, which, far = sentences(rep.summary())
    assert where.startswith("Real and simulated data differ most in a spectral line at 0.083")
    assert which.startswith("The effect periodic_interference explains it: line at 0.083")
    pct = f"{100 * rep.shrink:.0f} %"
    assert far.startswith(f"With it the gap falls from {rep.gap_before:.3g} to "
                          f"{rep.gap_after:.3g} ({pct} removed cross-validated)")
    assert far.endswith(f"within the no-gap threshold {rep.significance['threshold']:.3g}.")


def test_partly_wording_never_says_explains(hum_report):
    part = dataclasses.replace(hum_report, explained="partly", shrink=0.45,
                               gap_after=0.55 * hum_report.gap_before,
                               reasons=["histogram still off (gap 12, largest |z| 9.0)"])
    text = part.summary()
    _, which, far = sentences(text)
    assert which == ("The effect periodic_interference accounts for part of it (45 %); the rest "
                     "lies outside the effect library.")
    assert "explains" not in text and "Best explanation" not in text
    assert "Partly explained (45 %)" in text and "What remains: histogram still off" in text
    assert "still above the no-gap threshold" in far


def test_a_rest_within_the_threshold_is_not_said_to_lie_outside_the_library(hum_report):
    """Only broadband indicators off and the rest under the no-gap threshold: no second cause
    was sought, and the text says so instead of "outside the effect library"."""
    thr = hum_report.significance["threshold"]
    info = dict(hum_report.info, small_rest=True)
    small = dataclasses.replace(hum_report, explained="partly", info=info,
                                gap_after=0.5 * thr,
                                shrink=1.0 - 0.5 * thr / hum_report.gap_before,
                                reasons=["band_spectrum still off (gap 1.65, largest |z| 2.8)"])
    text = small.summary()
    _, which, far = sentences(text)
    pct = f"{100 * small.shrink:.0f} %"
    assert which == (f"The effect periodic_interference accounts for {pct} of it; the rest "
                     "would not be called a gap, too little to name a second cause, though 1 "
                     "indicator still differs (details below).")
    assert "within the no-gap threshold" in far
    assert "outside the effect library" not in text and "explains" not in text
    assert "What remains: band_spectrum still off" in text
    # the flag alone does not speak for a rest above the threshold
    above = dataclasses.replace(small, gap_after=2.0 * thr,
                                shrink=1.0 - 2.0 * thr / hum_report.gap_before)
    assert "the rest lies outside the effect library" in above.summary()


def test_no_gap_wording(hum_report):
    sig = dict(hum_report.significance, significant=False)
    quiet = dataclasses.replace(hum_report, significance=sig, best_effect=None)
    where, which, _ = sentences(quiet.summary())
    assert where.startswith("Real and simulated data are indistinguishable")
    assert which == "No effect is needed." and "explains" not in quiet.summary()


def _labels(fig):
    out = []
    for ax in fig.axes:
        if ax.get_visible():
            out += [ax.get_xlabel(), ax.get_ylabel(), ax.get_title()]
    return out


def test_key_figure_spectrum_on_log_axis_with_the_line(hum_report):
    fig = hum_report.plot()
    key = fig.axes[0]
    assert hum_report.key_panel() == "spectrum"
    assert key.get_xscale() == "log" and "frequency (cycles per time unit" in key.get_xlabel()
    marked = [line.get_xdata()[0] for line in key.get_lines()
              if len(line.get_xdata()) == 2 and line.get_xdata()[0] == line.get_xdata()[1]]
    assert any(abs(m - F0) < 1.0 / N for m in marked)
    for ax in fig.axes:
        if ax.get_visible():
            assert ax.get_xlabel() and (ax.get_ylabel() or ax.get_title() == "candidate effects")
    assert not any("index" in s or "segment statistic" in s for s in _labels(fig))
    matplotlib.pyplot.close(fig)


def test_key_figure_follows_the_effect(hum_report):
    import matplotlib.pyplot as plt

    i = hum_report.info
    clip = dataclasses.replace(hum_report, best_effect="clipping", effects=pd.DataFrame(
        [{"effect": "clipping", "params": {"low": -np.inf, "high": 1.2}, "shrink": 0.9,
          "status": "ok", "description": "", "gap_before": 1.0, "gap_after": 0.1}]),
        combined=None)
    fig = clip.plot()
    assert clip.key_panel() == "histogram"
    key = fig.axes[0]
    assert key.get_xlabel() == "value (units of the real data)"
    level = i["real_mean"] + 1.2 * i["real_std"]
    assert any(t.get_text() == f"clipped above {level:.4g}" for t in key.texts)
    plt.close(fig)
    drift = dataclasses.replace(clip, best_effect="parameter_drift")
    fig = drift.plot()
    assert fig.axes[0].get_xlabel() == "time (time units)"
    assert fig.axes[0].get_title().startswith("statistics per segment against time")
    plt.close(fig)
    delay = dataclasses.replace(clip, best_effect="delay_mismatch")
    fig = delay.plot()
    assert fig.axes[0].get_yscale() == "log"
    assert fig.axes[0].get_xlabel() == "delay tau (time units)"
    plt.close(fig)


def test_html_opens_with_the_headline(hum_report, tmp_path):
    page = hum_report.to_html(tmp_path / "r.html").read_text()
    head = hum_report.headline()
    assert page.index(head.split(":")[0]) < page.index("data:image/png;base64,")
    assert page.index("data:image/png;base64,") < page.index("Candidate effects")


def test_a_masked_line_is_said_to_have_been_found_against_the_fitted_runs(hum_report):
    """A line found only against the runs of the best effect (gap._diagnose.masked_lines):
    the details say so, with the line's frequency and the effect, and only then."""
    assert hum_report.info["masked_lines"] == [] and "stood out only" not in hum_report.summary()
    info = dict(hum_report.info, masked_lines=[0.3125], masked_by="measurement_noise")
    text = dataclasses.replace(hum_report, info=info).summary()
    assert ("The spectral line at 0.3125 cycles per time unit stood out only against runs "
            "with measurement_noise fitted") in text
    info = dict(info, masked_lines=[0.3125, 0.25])
    text = dataclasses.replace(hum_report, info=info).summary()
    assert "spectral lines at 0.3125 cycles per time unit, 0.25 cycles per time unit" in text
