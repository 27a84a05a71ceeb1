"""Progress of ``analyze``: tqdm bars for free runs and spectra only when asked, stage times."""

import numpy as np
import pytest

from skdelay import analyze_series
from skdelay.cli import main


def _delay_map(n=6000, delay=12, seed=0):
    rng = np.random.default_rng(seed)
    s = np.full(n, 0.5)
    for t in range(delay - 1, n - 1):
        d = s[t - delay + 1]
        s[t + 1] = 0.5 * s[t] + 2 * d * (1 - d) + 1e-3 * rng.normal()
    return s[500:]


@pytest.fixture(scope="module")
def series():
    return _delay_map()


def test_analyze_shows_bars_and_times_the_model_stage(series, capsys):
    messages = []
    res = analyze_series(series, m=(2, 3), tau_min=6, tau_max=18, quick=True,
                         progress=messages.append, verbose=1)
    err = capsys.readouterr().err
    assert "free run" in err and "Jacobians" in err
    assert any("free runs" in m for m in messages)
    t = res.timings
    assert t["free_runs"] > 0 and t["spectra"] > 0 and t["fits_and_validation"] >= 0
    assert t["free_runs"] + t["spectra"] + t["fits_and_validation"] == pytest.approx(
        t["models"])
    assert t["models"] <= t["total"]


def test_analyze_is_silent_without_progress(series, capsys):
    res = analyze_series(series, m=(2, 3), tau_min=6, tau_max=18, quick=True)
    assert capsys.readouterr().err == ""
    assert res.timings["spectra"] > 0  # timed all the same


def test_cli_progress_lines_carry_elapsed_time(series, tmp_path, capsys):
    path = tmp_path / "s.npy"
    np.save(path, series)
    args = ["analyze", str(path), "--m", "2..3", "--tau-min", "6", "--tau-max", "18",
            "--quick", "--out", str(tmp_path / "o")]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "[skdelay " in err and " s] delay scan" in err
    assert "Jacobians" in err  # the spectra's bars (--quiet: none, tests/test_cli.py)
