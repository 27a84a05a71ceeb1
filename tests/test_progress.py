"""Progress of ``analyze`` and ``gap``: tqdm bars for free runs, spectra and gap fits only
when asked, stage times."""

import numpy as np
import pytest

from skdelay import analyze_series
from skdelay.cli import main
from skdelay.gap import diagnose_gap
from skdelay.systems import MackeyGlass


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


def test_analyze_shows_bars_and_times_the_model_stage(series, capsys, monkeypatch):
    import skdelay._iterate

    monkeypatch.setattr(skdelay._iterate, "FREE_RUN_BAR_DELAY", 0.0)  # runs this short too
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


def test_a_free_run_shorter_than_the_bar_delay_draws_no_bar(series, capsys, monkeypatch):
    # the faithfulness search runs thousands of short runs: their bars were pure noise
    from sklearn.pipeline import make_pipeline

    import skdelay._iterate
    from skdelay import LocalLinearDelayMap, TwoWindowEmbedding, lagged_windows
    from skdelay.dynamics import iterate

    X, y = lagged_windows(series, 25)
    model = make_pipeline(TwoWindowEmbedding(m=2, tau=12),
                          LocalLinearDelayMap(n_neighbors=20)).fit(X, y)
    iterate(model, series[:200], 50, progress=True)
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(skdelay._iterate, "FREE_RUN_BAR_DELAY", 0.0)
    iterate(model, series[:200], 50, progress=True)
    assert "free run" in capsys.readouterr().err


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


# ------------------------------------------------------------------------------ gap fits
@pytest.fixture(scope="module")
def hum_record():
    t = np.arange(2000)
    return MackeyGlass().simulate(2000, random_state=1) + 0.1 * np.sin(2 * np.pi * 0.2 * t)


BARS = []


class _Bar:
    """Stands in for tqdm: records the total and the steps of each bar (in ``BARS``)."""

    def __init__(self, total=None, desc="", **kwargs):
        self.total, self.desc, self.n, self.postfix = total, desc, 0, []
        BARS.append(self)

    def update(self, n=1):
        self.n += n

    def set_postfix_str(self, s=""):
        self.postfix.append(s)

    def refresh(self):
        pass

    def close(self):
        pass


def test_gap_progress_steps_once_per_candidate_fit(hum_record, monkeypatch):
    monkeypatch.setattr("tqdm.auto.tqdm", _Bar)
    BARS.clear()
    effects = ["periodic_interference", "measurement_noise", "lowpass"]
    rep = diagnose_gap(hum_record, MackeyGlass(), effects=effects, random_state=0, n_jobs=1,
                       progress=True)
    assert rep.best_effect == "periodic_interference"
    (bar,) = BARS
    assert bar.desc == "gap diagnosis"
    # the simulator runs, every candidate of round 1, then the second round (if any)
    assert bar.n >= 1 + len(effects)
    assert bar.total == bar.n  # unused planned stages were taken off: the bar ends full
    assert bar.postfix[:2] == ["simulator runs", "candidate fits"]


def test_gap_is_silent_without_progress(hum_record, capsys):
    diagnose_gap(hum_record, MackeyGlass(), effects=["periodic_interference"], random_state=0)
    assert capsys.readouterr().err == ""


def test_cli_gap_shows_the_bar_unless_quiet(hum_record, tmp_path, capsys):
    path = tmp_path / "real.npy"
    np.save(path, hum_record)
    base = ["gap", str(path), "--system", "mackey_glass", "--effects", "periodic_interference"]
    assert main([*base, "--out", str(tmp_path / "a")]) == 0
    assert "gap diagnosis" in capsys.readouterr().err
    assert main([*base, "--out", str(tmp_path / "b"), "--quiet"]) == 0
    assert capsys.readouterr().err == ""



def test_gap_progress_must_be_a_flag():
    import numpy as np

    from skdelay.gap import diagnose_gap
    from skdelay.systems import MackeyGlass

    with pytest.raises(ValueError, match="progress must be True, False or None"):
        diagnose_gap(np.sin(np.arange(3000) * 0.1), MackeyGlass(), progress="yes")
