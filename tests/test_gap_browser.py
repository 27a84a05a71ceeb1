"""The gap report's first screen as a reader sees it, in headless Chromium.

A 50 Hz mains hum in Mackey-Glass data sampled at 1 us (time unit: the
microsecond; 3 cycles in a 60 ms record): the line's frequency in Hz must be
in the report's first paragraph, and the figure must load with its axes
labelled in units.  Reuses the Chromium setup of ``test_report_browser``
(skipped with its message when no Chromium is installed).
"""

import re

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

from test_report_browser import CHROMIUM, close_browser, render

from skdelay.gap import diagnose_gap
from skdelay.systems import MackeyGlass

pytestmark = pytest.mark.skipif(
    CHROMIUM is None,
    reason="no Chromium found (install it: apt-get install -y chromium chromium-driver)",
)

N = 60_000  # 60 ms at 1 us: 3 cycles of 50 Hz, one frequency bin = 16.7 Hz
DT_S = 1e-6


@pytest.fixture(scope="module", autouse=True)
def _close_browser():
    yield
    close_browser()


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    mg = MackeyGlass()
    x = mg.simulate(N, random_state=561)
    t = np.arange(N) * DT_S
    real = 3.0 + 40.0 * (x + 0.05 * x.std() * np.sin(2 * np.pi * 50.0 * t + 0.7))
    # two candidates keep the test short; the browser check is about the page
    rep = diagnose_gap(real, mg, sample_dt="1 us", random_state=2, n_jobs=2,
                       effects=["periodic_interference", "measurement_noise"])
    path = rep.to_html(tmp_path_factory.mktemp("gap") / "gap.html")
    return rep, render(path)


def test_first_paragraph_names_the_line_in_hz(page):
    rep, seen = page
    assert rep.best_effect == "periodic_interference"
    text = re.sub(r"\s+", " ", seen["text"])
    first = text.split("Summary", 1)[1].split("What shows it", 1)[0]
    hz = [float(v) for v in re.findall(r"spectral line at ([0-9.]+) Hz", first)]
    assert hz, first
    assert abs(hz[0] - 50.0) < 1.0 / (N * DT_S)  # within one bin
    assert "cycles per time unit" not in first


def test_figure_loads_with_axes_in_units(page):
    _, seen = page
    images = seen["images"]
    assert images and all(i["complete"] and i["w"] > 300 and i["h"] > 300 for i in images)
    text = re.sub(r"\s+", " ", seen["text"])
    caption = text.split("What shows it", 1)[1].split("Details", 1)[0]
    assert "horizontal axis: frequency (Hz, log scale)" in caption
    assert "vertical axis: log10 power density (signal std squared per Hz)" in caption
