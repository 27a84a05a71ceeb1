"""The ``skdelay`` command: every subcommand, exit codes, one-line errors, atomic outputs."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("matplotlib")

from _cli_data import small_delay_series

from skdelay.cli import main, parse_m, parse_params

ANALYZE_FAST = ["--m", "2..3", "--tau-min", "6", "--tau-max", "18", "--quiet",
                "--n-queries", "800", "--quick"]


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_usage_error(code, err, match):
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert match.lower() in lines[0].lower(), lines[0]


def listing(path):
    return sorted(p.name for p in Path(path).iterdir())


@pytest.fixture(scope="module")
def series_file(tmp_path_factory):
    x, delay = small_delay_series()
    path = tmp_path_factory.mktemp("data") / "map.csv"
    pd.DataFrame({"time": np.arange(x.size), "signal": x}).to_csv(path, index=False)
    return path, delay


# ------------------------------------------------------------------------ parsing helpers
def test_parse_m_and_params():
    assert parse_m("2..5") == (2, 3, 4, 5)
    assert parse_m("3") == (3,)
    assert parse_m("5,2") == (2, 5)
    assert parse_params(["tau=30", "b=0.1:0.12"]) == {"tau": 30.0, "b": (0.1, 0.12)}


def test_help_version_and_missing_command(capsys):
    assert run(["--help"], capsys)[0] == 0
    code, out, _ = run(["--version"], capsys)
    assert code == 0 and "skdelay" in out
    assert run([], capsys)[0] == 2
    code, _, err = run(["frobnicate"], capsys)
    assert_usage_error(code, err, "invalid choice")
    code, _, err = run(["analyze", "x.csv", "--m", "0..9x"], capsys)
    assert_usage_error(code, err, "--m")


# -------------------------------------------------------------------------------- analyze
def test_analyze_finds_the_delay_and_writes_everything(series_file, tmp_path, capsys):
    path, delay = series_file
    out = tmp_path / "report"
    code, stdout, err = run(["analyze", path, "--column", "signal", "--out", out,
                             *ANALYZE_FAST], capsys)
    assert code == 0, err
    assert err == ""  # --quiet: no progress
    assert {"results.json", "forecast_error.csv", "delays.csv", "lyapunov.csv",
            "validation.csv", "report.html"} <= set(listing(out))
    res = json.loads((out / "results.json").read_text())
    assert abs(res["summary"]["delay"] - delay) <= 1
    assert res["summary"]["N"] >= 1 and res["summary"]["D_KY"] > 1
    fe = pd.read_csv(out / "forecast_error.csv", index_col="tau")
    assert list(fe.columns) == ["2", "3"] and fe.index.min() == 6 and fe.index.max() == 18
    assert abs(int(fe["3"].idxmin()) - delay) <= 1
    assert fe["3"].min() < 0.5 * fe["3"].median()  # a real dip, not noise
    spec = pd.read_csv(out / "lyapunov.csv")
    assert set(spec["m"]) == {2, 3}
    assert "delay" in stdout and "D_KY" in stdout
    assert listing(tmp_path) == ["report"]  # no temporary directories left behind

    # an existing directory is refused without --force and left untouched ...
    (out / "keep.txt").write_text("mine")
    code, _, err = run(["analyze", path, "-c", "1", "--out", out, *ANALYZE_FAST], capsys)
    assert_usage_error(code, err, "--force")
    assert "keep.txt" in listing(out)
    # ... and replaced as a whole with it
    code, _, err = run(["analyze", path, "-c", "1", "--out", out, "--force", *ANALYZE_FAST,
                        "--neighbors", "25", "--ridge", "0.05", "--flow"], capsys)
    assert code == 0, err
    assert "keep.txt" not in listing(out) and "report.html" in listing(out)
    opts = json.loads((out / "results.json").read_text())["options"]
    assert (opts["n_neighbors"], opts["ridge"], opts["flow"]) == (25, 0.05, True)
    assert listing(tmp_path) == ["report"]


def test_analyze_progress_goes_to_stderr(series_file, tmp_path, capsys):
    path, _ = series_file
    argv = ["analyze", path, "-c", "signal", "--out", tmp_path / "o"]
    argv += [a for a in ANALYZE_FAST if a != "--quiet"]
    code, _, err = run(argv, capsys)
    assert code == 0
    assert "delay scan" in err


BAD_FILES = [
    ("empty.csv", "", None, "empty"),
    ("prose.txt", "alpha beta\ngamma delta\n", "0", "non-numeric"),
    ("nan.txt", "\n".join(["0.5"] * 10 + ["nan"] + ["0.25"] * 3000), None, "NaN"),
    ("short.txt", "\n".join(str(v) for v in np.sin(np.arange(50.0))), None, "needs at least"),
    ("const.txt", "\n".join(["1.0"] * 3000), None, "constant"),
    ("two.csv", "a,b\n1,2\n3,4\n", None, "--column"),
    ("two.csv", "a,b\n1,2\n3,4\n", "speed", "no column 'speed'"),
    ("missing.csv", None, None, "does not exist"),
]


@pytest.mark.parametrize("name, content, column, match", BAD_FILES,
                         ids=[f"{b[0]}-{b[3]}" for b in BAD_FILES])
def test_analyze_bad_input_exits_2_and_writes_nothing(tmp_path, capsys, name, content,
                                                      column, match):
    path = tmp_path / name
    if content is not None:
        path.write_text(content)
    out = tmp_path / "out"
    argv = ["analyze", path, "--out", out, "--quiet"]
    if column is not None:
        argv += ["--column", column]
    code, stdout, err = run(argv, capsys)
    assert_usage_error(code, err, match)
    assert stdout == ""
    assert not out.exists()


def test_analyze_bad_options_exit_2(series_file, tmp_path, capsys):
    path, _ = series_file
    out = tmp_path / "out"
    for extra, match in ((["--tau-max", "3000"], "needs at least"),
                         (["--tau-min", "10", "--tau-max", "12"], "too short"),
                         (["--dt", "-1"], "positive"),
                         (["--ridge", "0"], "positive"),
                         (["--neighbors", "1"], "--neighbors"),
                         (["--m", "0"], "--m")):
        code, _, err = run(["analyze", path, "-c", "signal", "--out", out, *extra], capsys)
        assert_usage_error(code, err, match)
    assert not out.exists()


def test_failure_during_the_run_exits_1_and_writes_nothing(series_file, tmp_path, capsys,
                                                           monkeypatch):
    import skdelay._analysis as analysis

    def boom(*args, **kwargs):
        raise RuntimeError("the tangent dynamics diverged\nsecond line")

    monkeypatch.setattr(analysis, "analyze_series", boom)
    path, _ = series_file
    out = tmp_path / "out"
    code, _, err = run(["analyze", path, "-c", "signal", "--out", out, "--quiet"], capsys)
    assert code == 1
    assert err.strip().count("\n") == 0 and "diverged" in err
    assert listing(tmp_path) == []


# ------------------------------------------------------------------------------- simulate
def test_simulate_npy_csv_and_measurement(tmp_path, capsys):
    npy = tmp_path / "mg.npy"
    code, _, err = run(["simulate", "mackey_glass", "--n", 3000, "--param", "tau=17",
                        "-o", npy], capsys)
    assert code == 0, err
    x = np.load(npy)
    assert x.shape == (3000,) and 0.2 < x.min() < x.max() < 1.5
    assert oct(npy.stat().st_mode)[-3:] != "000"

    csv = tmp_path / "mg.csv"
    code, _, err = run(["simulate", "mackey-glass", "--n", 3000, "--noise", 0.01, "--bits", 6,
                        "-o", csv], capsys)
    assert code == 0, err
    from skdelay._io import read_series

    y = read_series(csv).to_numpy()
    assert y.size == 3000 and np.unique(y).size <= 64  # 6-bit ADC

    code, out, _ = run(["simulate", "--list"], capsys)
    assert code == 0 and "mackey_glass" in out and "co2_laser" in out


@pytest.mark.parametrize(
    "argv, match",
    [
        (["simulate", "nosuchsystem", "--n", 100], "unknown system"),
        (["simulate", "mackey_glass", "--n", 100, "--param", "gamma=2"], "no parameter"),
        (["simulate", "mackey_glass", "--n", 100, "--param", "tau"], "NAME=VALUE"),
        (["simulate", "mackey_glass", "--n", 100, "--param", "tau=abc"], "number"),
        (["simulate", "mackey_glass", "--n", 100, "--param", "tau=-3"], "positive"),
        (["simulate", "mackey_glass", "--n", 0], "--n"),
        (["simulate", "mackey_glass", "--n", 100, "--noise", -1], "--noise"),
        (["simulate", "mackey_glass"], "--n"),
    ],
)
def test_simulate_bad_usage(tmp_path, capsys, argv, match):
    out = tmp_path / "x.npy"
    code, _, err = run([*argv, "-o", out], capsys)
    assert_usage_error(code, err, match)
    assert listing(tmp_path) == []


def test_simulate_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "x.npy"
    out.write_bytes(b"precious")
    code, _, err = run(["simulate", "mackey_glass", "--n", 500, "-o", out], capsys)
    assert_usage_error(code, err, "--force")
    assert out.read_bytes() == b"precious"
    code, _, err = run(["simulate", "mackey_glass", "--n", 500, "-o", tmp_path / "x.xlsx"],
                       capsys)
    assert_usage_error(code, err, ".npy")


# ------------------------------------------------------------------------------------ gap
@pytest.fixture(scope="module")
def gap_files(tmp_path_factory):
    from skdelay.systems import MackeyGlass

    d = tmp_path_factory.mktemp("gap")
    t = np.arange(8000)
    real = MackeyGlass().simulate(8000, random_state=1) + 0.1 * np.sin(2 * np.pi * 0.2 * t)
    np.save(d / "real.npy", real)
    return d / "real.npy"


def test_gap_reports_the_effect(gap_files, tmp_path, capsys):
    out = tmp_path / "gap"
    code, stdout, err = run(["gap", gap_files, "--system", "mackey_glass", "--param", "tau=17",
                             "--effects", "periodic_interference,measurement_noise",
                             "--out", out, "--quiet"], capsys)
    assert code == 0, err
    assert {"report.html", "effects.csv", "where.csv", "summary.txt", "results.json"} <= set(
        listing(out))
    assert json.loads((out / "results.json").read_text())["best_effect"] == \
        "periodic_interference"
    assert "periodic_interference" in stdout


def test_gap_says_why_no_effect_is_named(gap_files, tmp_path, capsys):
    """A hum that no candidate can explain is a gap, not "indistinguishable"."""
    out = tmp_path / "gap"
    code, _, err = run(["gap", gap_files, "--system", "mackey_glass", "--param", "tau=17",
                        "--effects", "quantization", "--out", out, "--quiet"], capsys)
    assert code == 0, err
    res = json.loads((out / "results.json").read_text())
    assert res["best_effect"] is None
    assert res["best_effect_reason"].startswith("no candidate effect explains the gap")


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--system", "nosuch"], "unknown system"),
        (["--system", "mackey_glass", "--param", "q=1"], "no parameter"),
        (["--system", "mackey_glass", "--effects", "gremlins"], "unknown effect"),
        (["--system", "mackey_glass", "--param", "tau=17:20"], "drift"),
    ],
)
def test_gap_bad_usage(gap_files, tmp_path, capsys, extra, match):
    out = tmp_path / "gap"
    code, _, err = run(["gap", gap_files, *extra, "--out", out], capsys)
    assert_usage_error(code, err, match)
    assert not out.exists()


def test_gap_too_short_real_is_usage_error(tmp_path, capsys):
    real = tmp_path / "short.txt"
    real.write_text("\n".join(str(v) for v in np.sin(np.arange(300) / 7.0)))
    out = tmp_path / "gap"
    code, _, err = run(["gap", real, "--system", "mackey_glass", "--out", out, "--quiet",
                        "--effects", "measurement_noise"], capsys)
    assert_usage_error(code, err, "")
    assert not out.exists()


# ----------------------------------------------------------------------------------- demo
@pytest.fixture(scope="module")
def reduced_demo(tmp_path_factory):
    """The reduced demo (one delay, a short series) through the CLI, run once for the two
    tests below (its files and tables; what a browser shows of its report)."""
    import contextlib
    import io

    root = tmp_path_factory.mktemp("demo")
    stdout, stderr = io.StringIO(), io.StringIO()
    with pytest.MonkeyPatch.context() as mp, contextlib.redirect_stdout(stdout), \
            contextlib.redirect_stderr(stderr):
        mp.setenv("SKDELAY_DATA", str(root / "cache"))
        code = main(["demo", "--out", str(root / "demo"), "--n-samples", "8000",
                     "--delays", "50", "--quiet"])
    return code, stdout.getvalue(), stderr.getvalue(), root / "demo"


def test_demo_reduced(reduced_demo):
    code, stdout, err, out = reduced_demo
    assert code == 0, err
    assert {"report.html", "table.csv", "results.json", "delay_50"} <= set(listing(out))
    table = pd.read_csv(out / "table.csv", index_col="tau0")
    assert list(table.index) == [50]
    assert int(str(table.loc[50, "delay"]).split()[0]) in range(47, 54)
    assert float(str(table.loc[50, "D_KY"]).lstrip(">= ")) > 1 and table.loc[50, "N"] >= 1
    assert {"exact lambda_max", "exact D_KY"} <= set(table.columns)
    assert "D_KY" in stdout
    # the paper's three tables: values in three column groups, delays per m, chi per m
    comp = pd.read_csv(out / "paper_comparison.csv", header=[0, 1], index_col=0)
    assert set(comp.columns.get_level_values(0)) == {"paper", "exact (simulator)",
                                                     "this model"}
    assert comp.loc[50, ("paper", "lambda_max [1/ms]")] == 2.5  # Buenner et al., table 1
    assert comp.loc[50, ("paper", "D_KY")] == 3.4
    per_m = pd.read_csv(out / "delays_per_m.csv", index_col="tau0")
    assert {"m = 2", "m = 5", "autocorrelation revival"} <= set(per_m.columns)
    chi = pd.read_csv(out / "cross_prediction.csv", index_col=0)
    assert list(chi.index) == ["O (data)", "m = 2", "m = 3", "m = 4", "m = 5"]
    assert 0 < chi.loc["O (data)", "50"] < chi.loc["m = 2", "50"] * 3


def test_demo_report_shows_the_paper_and_the_exact_values(reduced_demo):
    """What a reader of the reduced demo's report.html sees in a browser: the paper's
    numbers, the simulator's exact values and the Takens cross-check (rendered in headless
    Chromium by tests/test_report_browser.py's helper; skipped without Chromium)."""
    browser = pytest.importorskip("test_report_browser")
    if browser.CHROMIUM is None:
        pytest.skip("no Chromium found (install it: apt-get install -y chromium "
                    "chromium-driver)")
    code, _, err, out = reduced_demo
    assert code == 0, err
    exact = pd.read_csv(out / "table.csv", index_col="tau0", dtype=str).loc["50"]  # as shown
    # the m_d models' settings come from the data (cross-validated forecasts on this
    # record), not from constants, and the report names them
    selection = pd.read_csv(out / "delay_50" / "model_selection.csv")
    chosen = selection.loc[selection["chosen"]].set_index("m")
    assert exact["m_d models"].startswith(
        "k " + "/".join(str(k) for k in chosen["n_neighbors"]) + f" (m {chosen.index[0]}-")
    takens = pd.read_csv(out / "takens_cross_check.csv", index_col=0)
    kantz_low = takens.loc["lambda_max", "standard embedding (Kantz)"].split(" .. ")[0]
    expected = [
        "The paper's table", exact["m_d models"], "paper", "exact (simulator)", "this model",
        "2.5", "3.4", "68",  # Buenner et al.: lambda_max, D_KY, D_KY/tau at 50 us
        str(exact["exact lambda_max"]), str(exact["exact D_KY"]).replace(">= ", ""),
        "Takens cross-check", "Kantz", kantz_low,
        "Delay estimates per m", "Cross-prediction errors", "Rescaled-spectrum collapse",
    ]
    try:
        browser._check_page(out / "report.html", expected, min_images=4)
    finally:
        browser.close_browser()


def test_demo_bad_usage(tmp_path, capsys):
    out = tmp_path / "demo"
    code, _, err = run(["demo", "--out", out, "--delays", "77"], capsys)
    assert_usage_error(code, err, "no embedded laser data")
    code, _, err = run(["demo", "--out", out, "--n-samples", 3000], capsys)
    assert_usage_error(code, err, "too short")
    assert not out.exists()


# ---------------------------------------------------------------------------- real process
def test_console_entry_point_exit_codes(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    bad = subprocess.run([sys.executable, "-m", "skdelay.cli", "analyze", str(tmp_path / "n.csv")],
                         capture_output=True, text=True, env=env, timeout=120, check=False)
    assert bad.returncode == 2
    assert bad.stderr.strip().count("\n") == 0 and "does not exist" in bad.stderr
