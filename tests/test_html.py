import os

import pandas as pd
import pytest

from skdelay._atomic import atomic_path, write_text
from skdelay._html import render_html, write_html


def test_atomic_write_leaves_old_file_on_failure(tmp_path):
    target = tmp_path / "out.txt"
    write_text(target, "old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("boom")
    assert target.read_text() == "old"
    assert os.listdir(tmp_path) == ["out.txt"]


def test_report_inlines_tables_and_figures(tmp_path):
    plt = pytest.importorskip("matplotlib.pyplot")
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    table = pd.DataFrame({"delay": [151.0]})
    path = write_html(tmp_path / "r.html", "Report <1>", [("Delay", [table, fig])])
    text = path.read_text()
    assert "Report &lt;1&gt;" in text
    assert "151" in text
    assert "data:image/png;base64," in text
    assert "<h2>Delay</h2>" in render_html("x", [("Delay", "<p>a</p>")])
