"""Render the HTML reports in headless Chromium: figures load, table values show.

Uses selenium + chromedriver when both are available, otherwise
``chromium --headless --dump-dom`` on a copy of the page with a small script
that writes what the browser saw into the DOM.  Skipped (with the reason)
only when no Chromium binary can be found.
"""

import json
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt

from skdelay._html import write_html

FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-dev-shm-usage",
]


def _find(*names):
    for name in names:
        found = shutil.which(name)
        if found:
            return found
        for prefix in ("/usr/bin", "/usr/lib/chromium", "/snap/bin"):
            cand = Path(prefix) / name
            if cand.exists():
                return str(cand)
    return None


CHROMIUM = _find("chromium", "chromium-browser", "google-chrome", "chrome")
CHROMEDRIVER = _find("chromedriver")
pytestmark = pytest.mark.skipif(
    CHROMIUM is None,
    reason="no Chromium found (install it: apt-get install -y chromium chromium-driver)",
)

_PROBE = """
<script>
window.addEventListener('load', function () {
  var imgs = Array.prototype.map.call(document.images, function (i) {
    return {w: i.naturalWidth, h: i.naturalHeight, complete: i.complete};
  });
  var out = document.createElement('pre');
  out.id = 'skdelay-probe';
  out.textContent = JSON.stringify({images: imgs, text: document.body.innerText});
  document.body.appendChild(out);
});
</script>
"""


_DRIVER = {}


def _driver():
    """One headless Chromium (selenium) per test module, fresh profile."""
    if "driver" not in _DRIVER:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service

        opts = webdriver.ChromeOptions()
        opts.binary_location = CHROMIUM
        for flag in FLAGS:
            opts.add_argument(flag)
        profile = tempfile.mkdtemp(prefix="skdelay-chromium-")
        opts.add_argument(f"--user-data-dir={profile}")
        _DRIVER["profile"] = profile
        _DRIVER["driver"] = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
        _DRIVER["driver"].set_page_load_timeout(60)
    return _DRIVER["driver"]


def close_browser():
    """Quit the Chromium that :func:`_driver` started, if any, and remove its profile (every
    module that renders pages calls it when done: a driver left open outlives pytest)."""
    driver = _DRIVER.pop("driver", None)
    if driver is not None:
        driver.quit()
    shutil.rmtree(_DRIVER.pop("profile", ""), ignore_errors=True)


@pytest.fixture(scope="module", autouse=True)
def _close_browser():
    yield
    close_browser()


def _with_selenium(path):
    driver = _driver()
    driver.get(Path(path).resolve().as_uri())
    images = driver.execute_script(
        "return Array.prototype.map.call(document.images, function (i) {"
        "return {w: i.naturalWidth, h: i.naturalHeight, complete: i.complete};});"
    )
    text = driver.execute_script("return document.body.innerText;")
    return {"images": images, "text": text}


def _with_dump_dom(path):
    html = Path(path).read_text(encoding="utf-8").replace("</body>", _PROBE + "</body>")
    with tempfile.TemporaryDirectory() as work:
        probe = Path(work) / "probe.html"
        probe.write_text(html, encoding="utf-8")
        profile = Path(work) / "profile"
        cmd = [CHROMIUM, *FLAGS, f"--user-data-dir={profile}", "--virtual-time-budget=10000",
               "--dump-dom", probe.as_uri()]
        dom = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=True).stdout
    match = re.search(r'<pre id="skdelay-probe">(.*?)</pre>', dom, re.DOTALL)
    assert match, "Chromium did not run the page's load handler"
    import html as _html

    return json.loads(_html.unescape(match.group(1)))


def render(path):
    """What headless Chromium sees: image sizes and the page text."""
    try:
        import selenium  # noqa: F401

        use_selenium = CHROMEDRIVER is not None
    except ImportError:
        use_selenium = False
    return _with_selenium(path) if use_selenium else _with_dump_dom(path)


def _check_page(path, expected_texts, min_images):
    seen = render(path)
    images = seen["images"]
    assert len(images) >= min_images, f"{len(images)} images in {path}"
    assert all(img["complete"] and img["w"] > 0 and img["h"] > 0 for img in images), images
    text = re.sub(r"\s+", " ", seen["text"])
    for expected in expected_texts:
        assert expected in text, f"{expected!r} not shown in {path}"


def test_tiny_report_renders(tmp_path):
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot(np.sin(np.arange(100) / 5))
    table = pd.DataFrame({"lambda_max": [2.5, 1.4], "D_KY": [3.4, 10.2]},
                         index=pd.Index([50, 150], name="tau0"))
    path = write_html(tmp_path / "tiny.html", "tiny report",
                      [("figure", fig), ("table", table)])
    plt.close(fig)
    _check_page(path, ["tiny report", "lambda_max", "10.2", "3.4"], min_images=1)


def test_dump_dom_fallback_sees_the_same(tmp_path):
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot([0, 1], [1, 0])
    path = write_html(tmp_path / "t.html", "fallback",
                      [("f", fig), ("t", pd.DataFrame({"x": [7.25]}))])
    plt.close(fig)
    seen = _with_dump_dom(path)
    assert [img["w"] > 0 for img in seen["images"]] == [True]
    assert "7.25" in seen["text"]


def test_broken_image_is_detected(tmp_path):
    path = tmp_path / "broken.html"
    path.write_text('<html><body><img src="data:image/png;base64,AAAA"></body></html>')
    with pytest.raises(AssertionError):
        _check_page(path, [], min_images=1)


def test_analysis_report_renders(tmp_path):
    from _cli_data import small_delay_series

    from skdelay._analysis import analyze_series

    x, tau0 = small_delay_series()
    result = analyze_series(x, m=(2, 3), tau_min=tau0 - 4, tau_max=tau0 + 4,
                            quick=True, random_state=0)
    result.save(tmp_path / "out")
    page = tmp_path / "out" / "report.html"
    row = result.summary_row()
    expected = [f"{row['delay']} +- {row['delay_error']:.1f}", f"{row['D_KY']:.2f}",
                "Kaplan-Yorke", "forecast error", "Validation of the iterated models"]
    _check_page(page, expected, min_images=4)
    assert os.path.getsize(page) < 5_000_000
