"""Reading series from files, writing them back, and atomic output directories."""

import numpy as np
import pandas as pd
import pytest

from skdelay._io import (
    atomic_directory,
    check_output_directory,
    read_series,
    read_table,
    write_series,
)

X = np.sin(0.3 * np.arange(50)) + 0.01 * np.arange(50)


def _write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("sep", [" ", "\t", ",", ";", "   "])
def test_text_separators_and_header(tmp_path, sep):
    rows = "\n".join(f"{i}{sep}{float(v)!r}" for i, v in enumerate(X))
    path = _write(tmp_path / "d.csv", f"# comment line\ntime{sep}intensity\n{rows}\n")
    s = read_series(path, "intensity")
    assert s.name == "intensity"
    np.testing.assert_allclose(s.to_numpy(), X)
    np.testing.assert_allclose(read_series(path, 1).to_numpy(), X)
    np.testing.assert_allclose(read_series(path, "0").to_numpy(), np.arange(50))


def test_tisean_style_single_column_with_comments(tmp_path):
    body = "\n".join(repr(float(v)) for v in X)
    path = _write(tmp_path / "laser.dat", f"# TISEAN file\n\n{body}  # trailing\n")
    np.testing.assert_allclose(read_series(path).to_numpy(), X)


def test_npy_1d_and_2d(tmp_path):
    np.save(tmp_path / "a.npy", X)
    np.testing.assert_array_equal(read_series(tmp_path / "a.npy").to_numpy(), X)
    np.save(tmp_path / "b.npy", np.column_stack([X, 2 * X]))
    np.testing.assert_array_equal(read_series(tmp_path / "b.npy", 1).to_numpy(), 2 * X)
    with pytest.raises(ValueError, match="--column"):
        read_series(tmp_path / "b.npy")


def test_parquet(tmp_path):
    pytest.importorskip("pyarrow")
    pd.DataFrame({"t": np.arange(50.0), "x": X}).to_parquet(tmp_path / "d.parquet")
    np.testing.assert_array_equal(read_series(tmp_path / "d.parquet", "x").to_numpy(), X)
    assert read_table(tmp_path / "d.parquet").columns.tolist() == ["t", "x"]


@pytest.mark.parametrize(
    "name, content, column, match",
    [
        ("empty.csv", "", None, "is empty"),
        ("comments.txt", "# only\n# comments\n", None, "holds no data"),
        ("prose.txt", "alpha beta\ngamma delta\n", 0, "non-numeric"),
        ("word.txt", "hello\n", None, "no data rows"),
        ("nan.txt", "1\n2\nnan\n4\n", None, "NaN"),
        ("short.txt", "1.0\n", None, "at least 2"),
        ("const.txt", "3\n3\n3\n", None, "constant"),
        ("two.txt", "1 2\n3 4\n5 7\n", None, "2 columns"),
        ("two.txt", "1 2\n3 4\n5 7\n", "speed", "no column 'speed'"),
        ("two.txt", "1 2\n3 4\n5 7\n", 7, "out of range"),
        ("ragged.txt", "1\n2 3\n", None, "same number of columns"),
        ("header.csv", "x\n", None, "no data rows"),
        ("x.xlsx", "1\n2\n", None, "unsupported file type"),
    ],
)
def test_bad_files_say_what_to_fix(tmp_path, name, content, column, match):
    path = _write(tmp_path / name, content)
    with pytest.raises(ValueError, match=match) as info:
        read_series(path, column)
    assert "\n" not in str(info.value)


def test_missing_file_and_bad_npy(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        read_series(tmp_path / "nope.npy")
    _write(tmp_path / "bad.npy", "not numpy")
    with pytest.raises(ValueError, match="not a valid .npy"):
        read_series(tmp_path / "bad.npy")
    with pytest.raises(ValueError, match="directory"):
        read_series(tmp_path)


@pytest.mark.parametrize("suffix", [".npy", ".csv", ".txt"])
def test_write_read_round_trip(tmp_path, suffix):
    path = write_series(tmp_path / f"x{suffix}", X, name="mg", comment="made by a test")
    np.testing.assert_allclose(read_series(path).to_numpy(), X, rtol=1e-9)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    with pytest.raises(ValueError, match="npy"):
        write_series(tmp_path / "x.xlsx", X)


def test_atomic_directory_creates_and_refuses(tmp_path):
    out = tmp_path / "report"
    with atomic_directory(out) as tmp:
        (tmp / "a.txt").write_text("one")
    assert (out / "a.txt").read_text() == "one"
    with pytest.raises(ValueError, match="--force"):
        check_output_directory(out)
    with pytest.raises(ValueError, match="--force"), atomic_directory(out):
        pass  # never reached
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]


def test_atomic_directory_replace_and_failure_leave_no_half_state(tmp_path):
    out = tmp_path / "report"
    with atomic_directory(out) as tmp:  # --force only replaces what skdelay wrote
        (tmp / "old.txt").write_text("old")
    with pytest.raises(RuntimeError), atomic_directory(out, force=True) as tmp:
        (tmp / "new.txt").write_text("half")
        raise RuntimeError("boom")
    assert sorted(p.name for p in out.iterdir()) == [".skdelay-output", "old.txt"]
    with atomic_directory(out, force=True) as tmp:
        (tmp / "new.txt").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == [".skdelay-output", "new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report"]
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="not a directory"):
        check_output_directory(tmp_path / "file", force=True)
