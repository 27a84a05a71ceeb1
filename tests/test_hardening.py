"""Hardening (issue 16): usage errors exit 2, safe outputs under kill -9, strict JSON."""

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from skdelay._atomic import (
    atomic_path,
    check_writable,
    clean_stale_temporaries,
    make_temporary,
    owner_tag,
    remove_own_temporaries,
)
from skdelay._checks import sample_dt_from_index
from skdelay._io import (
    OUTPUT_MARKER,
    Unavailable,
    atomic_directory,
    check_output_directory,
    dumps_strict,
    read_series,
    write_json,
)
from skdelay.cli import main
from skdelay.systems import DivergenceError, Ikeda, MackeyGlass, get_system

SIM = ["simulate", "mackey_glass", "--n", "200"]


def run(argv, capsys):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def assert_usage_error(code, err, *needles):
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    for needle in needles:
        assert needle.lower() in lines[0].lower(), lines[0]


def listing(path):
    return sorted(p.name for p in Path(path).iterdir())


def dead_pid():
    """The pid of a process that has exited (and been reaped)."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


# ------------------------------------------------------------------ usage errors exit 2
@pytest.mark.parametrize("extra, needles", [
    (["--param", "tau=0.04"], ["does not resolve the delay", "tau=0.04"]),
    (["--param", "n=-3"], ["positive hill exponent", "n=-3"]),
    (["--param", "tau=-5"], ["delay tau must be positive"]),
    (["--param", "tau"], ["--param expects NAME=VALUE"]),
    (["--param", "tau=abc"], ["--param tau needs a number"]),
    (["--param", "gamma=1"], ["no parameter", "gamma", "valid parameters"]),
    (["--seed", "-1"], ["--seed", "between 0 and 2**32 - 1"]),
    (["--seed", str(2**32)], ["--seed", "between 0 and 2**32 - 1"]),
    (["--param", "tau=10:0.01"], ["does not resolve the delay"]),  # one end of a drift
])
def test_simulate_usage_errors_exit_2_and_write_nothing(tmp_path, capsys, extra, needles):
    code, _, err = run([*SIM, "-o", tmp_path / "x.npy", *extra], capsys)
    assert_usage_error(code, err, *needles)
    assert listing(tmp_path) == []


def test_unknown_system_exits_2(tmp_path, capsys):
    code, _, err = run(["simulate", "mackey", "--n", 10, "-o", tmp_path / "x.npy"], capsys)
    assert_usage_error(code, err, "unknown system 'mackey'", "mackey_glass")


@pytest.mark.parametrize("command", [
    ["analyze", "{data}", "--out", "{tmp}/o"],
    ["gap", "{data}", "--system", "mackey_glass", "--out", "{tmp}/o"],
    ["demo", "--out", "{tmp}/o"],
])
def test_n_jobs_zero_exits_2(tmp_path, capsys, command):
    data = tmp_path / "x.npy"
    np.save(data, np.sin(np.arange(300.0)))
    argv = [a.format(data=data, tmp=tmp_path) for a in command] + ["--n-jobs", "0"]
    code, _, err = run(argv, capsys)
    assert_usage_error(code, err, "--n-jobs", "use 1 (serial)")
    assert listing(tmp_path) == ["x.npy"]


def test_divergence_exits_2_and_names_the_parameter(tmp_path, capsys, monkeypatch):
    # no valid Mackey-Glass parameters diverge, so shrink the a-priori amplitude instead
    monkeypatch.setattr(MackeyGlass, "_amplitude", lambda self, params: 1e-6)
    out = tmp_path / "x.npy"
    code, _, err = run([*SIM, "-o", out, "--param", "tau=20"], capsys)
    assert_usage_error(code, err, "diverged", "beyond the bound", "change tau (default 17)")
    assert listing(tmp_path) == []


# ------------------------------------------------------------- unwritable outputs, early
def test_unwritable_out_is_found_before_any_work(tmp_path, capsys):
    afile = tmp_path / "a_file"
    afile.write_text("not a directory")
    missing_input = tmp_path / "missing.csv"  # would be exit 2 too, but later
    code, _, err = run(["analyze", missing_input, "--out", afile / "sub"], capsys)
    assert_usage_error(code, err, "--out", "is a file, not a directory")
    code, _, err = run([*SIM, "-o", afile / "x.npy"], capsys)
    assert_usage_error(code, err, "-o", "is a file, not a directory")
    assert listing(tmp_path) == ["a_file"]


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs Linux /proc")
def test_check_writable_probes_for_real():
    # os.access says yes to root on /proc; only an actual write attempt tells
    with pytest.raises(ValueError, match="cannot write in /proc"):
        check_writable("/proc/skdelay-out")


def test_check_writable_leaves_nothing(tmp_path):
    assert check_writable(tmp_path / "a" / "b" / "out") == tmp_path / "a" / "b" / "out"
    assert listing(tmp_path) == []


@pytest.mark.skipif(os.geteuid() == 0 if hasattr(os, "geteuid") else True,
                    reason="root may write into read-only directories")
def test_readonly_parent_is_usage_error(tmp_path, capsys):  # pragma: no cover - non-root
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        code, _, err = run([*SIM, "-o", ro / "x.npy"], capsys)
        assert_usage_error(code, err, "cannot write in")
    finally:
        ro.chmod(0o700)


# ------------------------------------------------------------------ --force and marker
def test_force_replaces_only_skdelay_outputs(tmp_path):
    foreign = tmp_path / "thesis"
    foreign.mkdir()
    (foreign / "chapter1.tex").write_text("precious")
    with pytest.raises(ValueError, match="not written by skdelay"):
        check_output_directory(foreign, force=True)
    with (pytest.raises(ValueError, match="not written by skdelay"),
          atomic_directory(foreign, force=True) as tmp):
        (tmp / "x").write_text("new")
    assert listing(foreign) == ["chapter1.tex"]

    ours = tmp_path / "ours"
    with atomic_directory(ours) as tmp:
        (tmp / "a.txt").write_text("first")
    assert listing(ours) == [OUTPUT_MARKER, "a.txt"]
    with pytest.raises(ValueError, match="pass --force"):
        check_output_directory(ours)
    with atomic_directory(ours, force=True) as tmp:
        (tmp / "b.txt").write_text("second")
    assert listing(ours) == [OUTPUT_MARKER, "b.txt"]
    assert listing(tmp_path) == ["ours", "thesis"]


def test_cli_force_refuses_foreign_directory_before_work(tmp_path, capsys):
    out = tmp_path / "results"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    data = tmp_path / "x.npy"
    np.save(data, np.sin(np.arange(300.0)))
    code, _, err = run(["analyze", data, "--out", out, "--force", "--quiet"], capsys)
    assert_usage_error(code, err, "not written by skdelay", OUTPUT_MARKER)
    assert listing(out) == ["keep.txt"]


# ------------------------------------------------------------------ stale temporaries
def test_stale_temporaries_are_removed_live_ones_kept(tmp_path):
    gone = dead_pid()
    stale_dir = tmp_path / f".report.skd{gone}x0_abc123.tmp"
    stale_dir.mkdir()
    (stale_dir / "half.json").write_text("{")
    stale_file = tmp_path / f".x.npy.skd{gone}x0_zz9.tmp"
    stale_file.write_text("half")
    live = tmp_path / f".other.{owner_tag()}q1.tmp"  # this process: in progress
    live.mkdir()
    unrelated = tmp_path / ".report.keepme.tmp"  # not skdelay's naming: never touched
    unrelated.mkdir()
    with atomic_directory(tmp_path / "report") as tmp:
        (tmp / "results.json").write_text("{}")
    assert listing(tmp_path) == sorted([live.name, ".report.keepme.tmp", "report"])


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="needs Linux /proc")
def test_reused_pid_counts_as_stale(tmp_path):
    # the pid is alive (this process) but the recorded start time is another process's
    mine = os.getpid()
    reused = tmp_path / f".out.skd{mine}x1_abc.tmp"
    reused.mkdir()
    assert clean_stale_temporaries(tmp_path) == [reused.name]
    assert listing(tmp_path) == []


def test_killed_force_swap_restores_the_old_output(tmp_path):
    # killed between "move old aside" and "move new in": the old output comes back
    gone = dead_pid()
    old = tmp_path / f".report.skd{gone}x0_abc.old"
    (old / "d").mkdir(parents=True)
    (old / "d" / "results.json").write_text('{"old": 1}')
    assert clean_stale_temporaries(tmp_path) == [old.name]
    assert listing(tmp_path) == ["report"]
    assert json.loads((tmp_path / "report" / "results.json").read_text()) == {"old": 1}


def test_atomic_path_temporary_is_owned_and_cleaned(tmp_path):
    target = tmp_path / "x.npy"
    with atomic_path(target) as tmp:
        assert tmp.name.startswith(f".x.npy.{owner_tag()}") and tmp.name.endswith(".tmp")
        tmp.write_text("data")
    assert listing(tmp_path) == ["x.npy"]
    tmp = make_temporary(target)
    assert tmp.exists()  # ours and alive: kept by the next clean-up
    assert clean_stale_temporaries(tmp_path) == []
    tmp.unlink()


#: kills at random moments after the start (the brief: >= 10, after 0.2-3 s)
N_RANDOM_KILLS = 10
#: extra kills while the hidden temporary is being written (on a loaded machine the
#: random ones mostly land in the imports, which would leave the clean-up untested)
N_WRITE_KILLS = 3


def _complete_series(path, n):
    values = read_series(path).to_numpy()
    assert values.shape == (n,)
    assert np.all(np.isfinite(values))


def _temporaries(directory):
    return [p.name for p in Path(directory).iterdir() if p.name.endswith(".tmp")]


@pytest.mark.slow
def test_kill_9_never_leaves_a_partial_output(tmp_path):
    """SIGKILL at random moments: the target is absent or complete; the next run cleans up."""
    n = 300_000  # a text file of this size takes ~1 s to write: a wide window for kills
    target = tmp_path / "mg.csv"
    argv = [sys.executable, "-m", "skdelay.cli", *SIM[:2], "--n", str(n), "--dt", "0.05",
            "-o", str(target), "--force"]
    rng = random.Random(16)

    def check_state():
        if target.exists():
            _complete_series(target, n)  # never a half-written file
        # nothing but the target and hidden temporaries of killed runs
        assert set(listing(tmp_path)) - {"mg.csv"} == set(_temporaries(tmp_path))

    killed = 0
    for _ in range(N_RANDOM_KILLS):
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            proc.wait(timeout=rng.uniform(0.2, 3.0))
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGKILL)
            proc.wait()
            killed += 1
        check_state()
    assert killed >= 3, "no run was killed: the test no longer tests anything"

    leftovers_seen = 0
    for _ in range(N_WRITE_KILLS):
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 60
        while not _temporaries(tmp_path) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.005)
        time.sleep(rng.uniform(0.0, 0.2))  # somewhere inside the write
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        leftovers_seen += bool(_temporaries(tmp_path))
        check_state()
    assert leftovers_seen >= 1, "no kill landed in the write: the clean-up was not exercised"

    final = subprocess.run(argv, check=False, capture_output=True, text=True, timeout=60)
    assert final.returncode == 0, final.stderr
    _complete_series(target, n)
    assert listing(tmp_path) == ["mg.csv"]  # leftovers of the killed runs are gone


@pytest.mark.slow
def test_kill_9_during_analyze_leaves_no_partial_directory(tmp_path):
    sys.path.insert(0, str(Path(__file__).parent))
    from _cli_data import small_delay_series

    x, _ = small_delay_series(n=3000)
    data = tmp_path / "in.npy"
    np.save(data, x)
    out = tmp_path / "res"
    argv = [sys.executable, "-m", "skdelay.cli", "analyze", str(data), "--out", str(out),
            "--force", "--quiet", "--quick", "--m", "2..3", "--tau-min", "6", "--tau-max", "16",
            "--n-queries", "500"]
    rng = random.Random(7)
    for _ in range(4):
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            proc.wait(timeout=rng.uniform(0.5, 3.0))
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGKILL)
            proc.wait()
        if out.exists():
            assert {"results.json", "report.html", OUTPUT_MARKER} <= set(listing(out))
            json.loads((out / "results.json").read_text())
    final = subprocess.run(argv, check=False, capture_output=True, text=True, timeout=120)
    assert final.returncode == 0, final.stderr
    assert listing(tmp_path) == ["in.npy", "res"]


# ----------------------------------------------------------------------- strict JSON
def _strict_loads(text):
    def refuse(token):
        raise AssertionError(f"non-strict JSON token {token}")

    return json.loads(text, parse_constant=refuse)


def test_dumps_strict_nan_inf_become_null_with_reasons():
    obj = {"summary": {"delay": float("nan"), "lambda_max": np.float32(np.inf),
                       "m": np.int64(3), "minimal_m": Unavailable("no m reached the floor"),
                       "D_KY": -np.inf, "D_KY_reason": "given by caller"},
           "curve": np.array([1.0, np.nan, 2.0]), "flag": np.bool_(True),
           "frame": pd.DataFrame({"a": [1.0, np.nan]}), "path": Path("x/y")}
    data = _strict_loads(dumps_strict(obj, reasons={"delay": "no significant dip"}))
    assert data["summary"] == {"delay": None, "delay_reason": "no significant dip",
                               "lambda_max": None, "m": 3, "minimal_m": None,
                               "minimal_m_reason": "no m reached the floor",
                               "D_KY": None, "D_KY_reason": "given by caller"}
    assert data["curve"] == [1.0, None, 2.0]
    assert data["flag"] is True and data["frame"] == {"a": [1.0, None]}
    assert data["path"] == os.fspath(Path("x/y"))


def test_dumps_strict_refuses_what_it_cannot_write():
    with pytest.raises(TypeError, match="complex"):
        dumps_strict({"z": 1j})
    with pytest.raises(TypeError, match="at key 'o'"):
        dumps_strict({"o": object()})


def test_write_json_path_and_file(tmp_path):
    path = tmp_path / "r.json"
    write_json(path, {"x": np.nan})
    assert _strict_loads(path.read_text()) == {"x": None}
    assert listing(tmp_path) == ["r.json"]
    with open(tmp_path / "s.json", "w") as fh:
        write_json(fh, [np.inf], indent=None)
    assert (tmp_path / "s.json").read_text() == "[null]\n"


# ------------------------------------------------------------------------- simulators
@pytest.mark.parametrize("cls, params, match", [
    (MackeyGlass, {"n": -3}, "positive Hill exponent"),
    (MackeyGlass, {"n": 0}, "positive Hill exponent"),
    (MackeyGlass, {"tau": -1.0}, "delay tau must be positive"),
    (MackeyGlass, {"a": float("nan")}, "give a finite number"),
    (MackeyGlass, {"b": "0.1"}, "must be a real number"),
    (Ikeda, {"tau": 0.0}, "delay tau must be positive"),
])
def test_invalid_parameters_at_construction(cls, params, match):
    error = TypeError if isinstance(next(iter(params.values())), str) else ValueError
    with pytest.raises(error, match=match):
        cls(**params)


def test_invalid_parameters_in_overrides():
    mg = MackeyGlass()
    with pytest.raises(ValueError, match="positive Hill exponent"):
        mg.simulate(10, n=-3)
    with pytest.raises(ValueError, match="positive Hill exponent"):
        mg.simulate(10, n=(10.0, -1.0))  # the end of a drift
    with pytest.raises(ValueError, match="delay tau must be positive"):
        mg.check_simulation(10, tau=-2.0)
    with pytest.raises(ValueError, match="does not resolve the delay"):
        mg.check_simulation(10, tau=0.04)
    assert mg.check_simulation(10, tau=30.0) is None


def test_divergence_beyond_the_bound_is_a_value_error(monkeypatch):
    monkeypatch.setattr(Ikeda, "_amplitude", lambda self, params: 1e-3)
    with pytest.raises(DivergenceError, match=r"change mu \(default 20\)") as info:
        Ikeda(mu=25.0).simulate(50, sample_dt=0.1, random_state=0)
    assert isinstance(info.value, ValueError)
    with pytest.raises(DivergenceError, match="lower dynamical_noise"):
        Ikeda().simulate(50, sample_dt=0.1, random_state=0)


def test_default_systems_stay_inside_their_bound():
    for name in ("mackey_glass", "ikeda", "electro_optic"):
        system = get_system(name)
        x = system.simulate(200, sample_dt=0.5, random_state=1)
        assert np.abs(x).max() < system._amplitude(system.params)


# ------------------------------------------------------------------- pandas sample_dt
def test_sample_dt_from_index():
    idx = pd.date_range("2024-01-01", periods=50, freq="250ms")
    assert sample_dt_from_index(pd.Series(np.arange(50.0), index=idx)) == 0.25
    tdi = pd.timedelta_range(0, periods=20, freq="2min")
    assert sample_dt_from_index(pd.Series(np.arange(20.0), index=tdi)) == 120.0
    assert sample_dt_from_index(pd.Series(np.arange(5.0))) is None
    irregular = idx.delete(10)
    with pytest.raises(ValueError, match="irregular"):
        sample_dt_from_index(pd.Series(np.arange(49.0), index=irregular))
    with pytest.raises(ValueError, match="not increasing"):
        sample_dt_from_index(pd.Series(np.arange(50.0), index=idx[::-1]))


def test_parquet_time_index_gives_the_step(tmp_path, capsys):
    pytest.importorskip("pyarrow")
    idx = pd.date_range("2024-01-01", periods=400, freq="5ms")
    frame = pd.DataFrame({"v": np.sin(np.arange(400.0))}, index=idx)
    frame.to_parquet(tmp_path / "regular.parquet")
    series = read_series(tmp_path / "regular.parquet")
    assert sample_dt_from_index(series) == 0.005
    frame.iloc[np.r_[0:100, 101:400]].to_parquet(tmp_path / "gappy.parquet")
    code, _, err = run(["analyze", tmp_path / "gappy.parquet", "--out", tmp_path / "o"], capsys)
    assert_usage_error(code, err, "irregular", "resample")
    assert not (tmp_path / "o").exists()


# ------------------------------------------------- invalid parameters fail at the call
from skdelay import _correlation as corr
from skdelay import (
    classic,
    required_lags,
    spacetime,
    validation,
)
from skdelay._testing_maps import henon

X = henon(800, random_state=0)
Y = henon(800, random_state=1)


@pytest.mark.parametrize("call, error, needles", [
    (lambda: validation.value_histogram(X, bins=0), ValueError, ["bins must be an integer in [1"]),
    (lambda: validation.value_histogram(X, bins=[0.0, np.nan]), ValueError, ["bin edges"]),
    (lambda: validation.value_histogram(X, range=(1, np.nan)), ValueError, ["range", "finite"]),
    (lambda: validation.histogram_distance(X, Y, bins=-3), ValueError, ["bins must be"]),
    (lambda: validation.histogram_distance(X, Y, bins="auto"), TypeError, ["bins"]),
    (lambda: validation.histogram_distance(X, Y, metric="l2"), ValueError,
     ["metric must be one of 'hellinger' or 'total_variation'"]),
    (lambda: validation.cross_prediction_by_region(X, Y, m=2, tau=2, n_regions=100_000),
     ValueError, ["n_regions must be an integer in [1, 50]"]),
    (lambda: validation.cross_prediction_error(X, m=2, tau=2, random_state="x"), TypeError,
     ["random_state must be None, an integer seed"]),
    (lambda: validation.cross_prediction_error(X, m=2, tau=2, random_state=-1), ValueError,
     ["random_state must be a seed in [0, 4294967295]"]),
    (lambda: validation.cross_prediction_error(X, m=2, tau=2, n_jobs=0), ValueError,
     ["n_jobs must be a non-zero integer", "use 1 (serial)"]),
    (lambda: validation.cross_prediction_error(X, m=2, tau=2, ridge=-1e-3), ValueError,
     ["ridge must be a finite number in [0, inf)"]),
    (lambda: validation.cross_prediction_error(X, m=2, tau=2, radius=np.nan), ValueError,
     ["radius must be a finite number in (0, inf) or None"]),
    (lambda: validation.power_spectrum(X, sample_dt=np.nan), ValueError, ["sample_dt must be"]),
    (lambda: validation.spectrum_distance(X, Y, max_frequency=-1.0), ValueError,
     ["max_frequency must be"]),
    (lambda: validation.autocorrelation_distance(X, Y, n_bands=0), ValueError,
     ["n_bands must be an integer in [1"]),
    (lambda: classic.correlation_sum(X, 2, radii=[np.nan, 0.1]), ValueError,
     ["radii must be finite, positive and strictly increasing"]),
    (lambda: classic.correlation_sum(X, 2, radii=[1e-300]), ValueError,
     ["beyond float64 resolution"]),
    (lambda: classic.correlation_sum(X, 2, workers=0), ValueError, ["workers must be a non-zero"]),
    (lambda: classic.false_nearest_neighbors(X, rtol=-1.0), ValueError,
     ["rtol must be a finite number in (0, inf)"]),
    (lambda: classic.false_nearest_neighbors(X, atol=np.nan), ValueError, ["atol must be"]),
    (lambda: classic.noise_reduction(X, end_weight=-1.0), ValueError, ["end_weight must be"]),
    (lambda: classic.poincare_section(X, sample_dt=-1.0), ValueError, ["sample_dt must be"]),
    (lambda: classic.poincare_section(X, prominence=np.nan), ValueError, ["prominence must be"]),
    (lambda: classic.poincare_section(X, kind="peaks"), ValueError, ["kind must be one of"]),
    (lambda: classic.maximal_lyapunov_exponent(X, dim=2, fit_range=(np.nan, 3)), ValueError,
     ["fit_range must be a finite (low, high) pair"]),
    (lambda: classic.correlation_dimension(X, dims=[1, 2], min_pairs=-1), ValueError,
     ["min_pairs must be an integer in [1"]),
    (lambda: corr.mutual_information(X, 3, n_bins=10**9), ValueError,
     ["n_bins must be an integer in [2, 4096]"]),
    (lambda: corr.revival_peak(corr.autocorrelation(X, 50), prominence=-1.0), ValueError,
     ["prominence must be"]),
    (lambda: spacetime.space_time(X, 20, n_columns=10**9), ValueError,
     ["n_columns must be an integer in [1, 320]"]),
    (lambda: spacetime.space_time(X, 20, start=np.nan), ValueError, ["start must be"]),
])
def test_invalid_parameters_fail_at_the_call(call, error, needles):
    with pytest.raises(error) as info:
        call()
    for needle in needles:
        assert needle in str(info.value), str(info.value)


def _fitted_henon_model():
    from sklearn.pipeline import make_pipeline

    from skdelay import LocalLinearDelayMap, TwoWindowEmbedding, lagged_windows

    return make_pipeline(TwoWindowEmbedding(m=2, tau=1), LocalLinearDelayMap()).fit(
        *lagged_windows(X, required_lags(2, 1)))


@pytest.mark.parametrize("entry", ["forecast_error_curve", "DelaySelectorCV", "analyze_series",
                                   "minimal_embedding", "lyapunov_spectrum",
                                   "select_model_options", "select_spectrum_model",
                                   "diagnose_gap"])
def test_every_parallel_entry_point_checks_n_jobs_itself(entry):
    # n_jobs=0 reached joblib's "n_jobs == 0 in Parallel has no meaning" (or was taken as
    # serial by the thread pools) after the work had started
    import skdelay
    from skdelay import dynamics, gap, model_selection
    from skdelay.systems import MackeyGlass

    calls = {
        "forecast_error_curve": lambda: skdelay.forecast_error_curve(X, m=2, tau=[1, 2],
                                                                     n_jobs=0),
        "DelaySelectorCV": lambda: skdelay.DelaySelectorCV(m=[2], tau=[1, 2], n_jobs=0).fit(
            *skdelay.lagged_windows(X, 4)),
        "analyze_series": lambda: skdelay.analyze_series(X, n_jobs=0),
        "minimal_embedding": lambda: dynamics.minimal_embedding(X, tau=1, m_max=2, n_jobs=0),
        "lyapunov_spectrum": lambda: dynamics.lyapunov_spectrum(_fitted_henon_model(), X,
                                                                n_jobs=0),
        "select_model_options": lambda: model_selection.select_model_options(X, 2, 1,
                                                                             n_jobs=0),
        "select_spectrum_model": lambda: model_selection.select_spectrum_model(X, 1, n_jobs=0),
        "diagnose_gap": lambda: gap.diagnose_gap(MackeyGlass().simulate(3000, random_state=0),
                                                 MackeyGlass(), n_jobs=0),
    }
    with pytest.raises(ValueError, match="n_jobs must be a non-zero integer, got 0; use 1"):
        calls[entry]()


@pytest.mark.parametrize("table, error, needle", [
    (np.ones(5), TypeError, "forecast_error must be a pandas DataFrame"),
    (pd.DataFrame(), ValueError, "has no columns"),
    (pd.DataFrame({2: [3.0, 2, 1, 2, 3]}, index=list("abcde")), ValueError,
     "index must hold the delays tau"),
    (pd.DataFrame({2: [3.0, 2, 1, 2, 3]}, index=[5, 1, 3, 2, 4]), ValueError,
     "strictly increasing"),
])
def test_locate_dips_refuses_what_is_not_a_forecast_error_table(table, error, needle):
    from skdelay import locate_dips

    with pytest.raises(error, match=needle):
        locate_dips(table)


def test_a_numpy_generator_is_a_random_state_as_the_docstrings_promise():
    # sklearn's check_random_state refuses generators: simulate, forecast_error_curve,
    # analyze_series and minimal_embedding raised "cannot be used to seed a RandomState"
    import skdelay
    from skdelay.systems import MackeyGlass

    def run(seed):
        x = MackeyGlass().simulate(3000, random_state=np.random.default_rng(seed))
        sigma = skdelay.forecast_error_curve(x, m=2, tau=[10, 17], n_queries=300,
                                             random_state=np.random.default_rng(seed))
        return x, sigma

    (x0, s0), (x1, s1), (x2, _) = run(0), run(0), run(1)
    np.testing.assert_array_equal(x0, x1)
    pd.testing.assert_frame_equal(s0, s1)
    assert not np.array_equal(x0, x2)
    # the delay-17 model forecasts better than the delay-10 one
    assert s0.loc[17, 2] < s0.loc[10, 2]
    with pytest.raises(TypeError, match="random_state must be None, an integer seed"):
        MackeyGlass().simulate(100, random_state="x")


def test_cross_prediction_by_region_counts_every_row_once():
    # the vectorised cell statistics (one bincount pass) cover every predicted row
    where = validation.cross_prediction_by_region(X, Y, m=2, tau=2, n_regions=3, random_state=0)
    # every predicted row (one per lag window with a next value) lies in exactly one cell
    assert where["count"].sum() == len(X) - required_lags(2, 2)
    assert len(where) == 9 and where["excess"].dropna().is_monotonic_decreasing


def test_power_spectrum_outside_float64_is_a_clear_error():
    with pytest.raises(ValueError, match="outside float64"):
        validation.power_spectrum(X * 1e200)
    _, p = validation.power_spectrum(X * 1e100, nperseg=64)
    _, p1 = validation.power_spectrum(X, nperseg=64)
    np.testing.assert_allclose(p, p1 * 1e200, rtol=1e-12)


def test_resolve_sample_dt():
    from skdelay._checks import resolve_sample_dt

    s = pd.Series(np.zeros(4), index=pd.date_range("2024", periods=4, freq="20ms"))
    assert resolve_sample_dt(s) == 0.02
    assert resolve_sample_dt(s, 3.0) == 3.0  # an explicit step (any unit) wins
    assert resolve_sample_dt(np.zeros(4)) == 1.0
    with pytest.raises(ValueError, match=r"sample_dt must be a finite number in \(0, inf\)"):
        resolve_sample_dt(s, -1.0)


def test_gap_with_an_unresolvable_delay_exits_2_before_work(tmp_path, capsys):
    real = tmp_path / "real.npy"
    np.save(real, np.sin(np.arange(500.0)))
    code, _, err = run(["gap", real, "--system", "mackey_glass", "--param", "tau=0.04",
                        "--out", tmp_path / "g"], capsys)
    assert_usage_error(code, err, "does not resolve the delay")
    assert listing(tmp_path) == ["real.npy"]


def test_stale_leftovers_go_even_when_the_next_run_fails(tmp_path, capsys):
    stale = tmp_path / f".res.skd{dead_pid()}x0_abc.tmp"
    stale.mkdir()
    code, _, err = run(["analyze", tmp_path / "missing.csv", "--out", tmp_path / "res"], capsys)
    assert_usage_error(code, err, "does not exist")
    assert listing(tmp_path) == []
    stale.mkdir()
    code, _, err = run([*SIM, "-o", tmp_path / "x.npy", "--param", "tau=-1"], capsys)
    assert code == 2 and stale.exists()  # refused while preparing: nothing touched yet
    code, _, err = run([*SIM, "-o", tmp_path / "x.npy"], capsys)
    assert code == 0, err
    assert listing(tmp_path) == ["x.npy"]


def test_runs_that_would_hang_are_refused_up_front(tmp_path, capsys):
    code, _, err = run(["simulate", "mackey_glass", "--n", 50_000_000, "--dt", 1000,
                        "-o", tmp_path / "x.npy"], capsys)
    assert_usage_error(code, err, "integration steps", "use fewer samples")
    assert listing(tmp_path) == []


def test_a_terminated_run_removes_the_temporaries_it_created(tmp_path):
    # a signal can land between the creation of a temporary and the try that would unwind
    # it (CI caught one at stop 23): the CLI then removes whatever this process created
    target = tmp_path / "out.csv"
    tmp = make_temporary(target)  # created, never handed to atomic_path
    other = tmp_path / f".out.csv.{owner_tag(1)}abc.tmp"  # a live process's work (pid 1)
    other.write_text("in progress")
    old = make_temporary(tmp_path / "report", kind="old", directory=True)
    (old / "d").mkdir()
    (old / "d" / "results.json").write_text("{}")  # an output moved aside by --force
    removed = remove_own_temporaries()
    assert tmp.name in removed and old.name in removed
    assert not tmp.exists() and not old.exists()
    assert other.exists()  # another process's temporary is never touched
    assert (tmp_path / "report" / "results.json").read_text() == "{}"  # moved back
    assert remove_own_temporaries() == []


@pytest.mark.slow
def test_sigterm_removes_the_temporary_at_once(tmp_path):
    # The signal must land while the output is being written.  On a loaded machine (tests
    # run in parallel) the test may see the temporary only as the write ends, and the
    # signal then lands after the run (default action, status -15, the output complete):
    # that try tests nothing, and the next one writes a record four times as long.
    for n in (300_000, 1_200_000, 4_800_000):
        target = tmp_path / f"mg{n}.csv"
        argv = [sys.executable, "-m", "skdelay.cli", *SIM[:2], "--n", str(n), "--dt", "0.05",
                "-o", str(target)]
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                text=True)
        deadline = time.monotonic() + 60
        # the output's temporary, not the writability probe of the argument checks (named
        # like a temporary and gone at once; a signal then lands before the run installs
        # its handler: default action, status -15, nothing written -- seen under load)
        while (not [t for t in _temporaries(tmp_path) if not t.startswith(".probe.")]
               and proc.poll() is None and time.monotonic() < deadline):
            time.sleep(0.005)
        assert proc.poll() is None, "the run ended before writing: nothing to test"
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
        if proc.returncode != 143 and target.exists() and not _temporaries(tmp_path):
            target.unlink()  # the write had ended: too late, try a longer one
            continue
        assert proc.returncode == 143, err
        assert "terminated; nothing was written" in err
        assert listing(tmp_path) == []  # no need to wait for the next run
        return
    pytest.fail("the signal never landed while the output was being written")
