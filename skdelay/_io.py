"""Reading and writing scalar time series, and atomic output directories.

Formats: ``.npy`` (1-D, or 2-D with one column per channel), text
(``.csv``, ``.txt``, ``.dat``, ``.tsv`` or no suffix: TISEAN style, whitespace
or comma/semicolon/tab separated, ``#`` comments, optional header line) and
``.parquet`` (through pandas/pyarrow).  Every failure raises a
``ValueError``/``TypeError``/``FileNotFoundError`` whose one-line message says
what to fix, so the command line can report it and exit with status 2.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pandas as pd

from ._atomic import (
    atomic_path,
    check_writable,
    clean_stale_temporaries,
    make_temporary,
    write_text,
)
from ._checks import check_series

__all__ = ["OUTPUT_MARKER", "Unavailable", "atomic_directory", "check_output_directory",
           "dumps_strict", "is_skdelay_output", "read_series", "read_table", "write_json",
           "write_series"]

_TEXT_SUFFIXES = {".csv", ".txt", ".dat", ".tsv", ".asc", ""}
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*([eE][+-]?\d+)?|\.\d+([eE][+-]?\d+)?|nan|inf|infinity)$",
                     re.IGNORECASE)


def _first_data_lines(path, n=5):
    lines = []
    with open(path, encoding="utf-8", errors="replace") as fh:
        for raw in fh:
            line = raw.split("#", 1)[0].strip()
            if line:
                lines.append(line)
                if len(lines) >= n:
                    break
    return lines


def _delimiter(line):
    for sep in (",", ";", "\t"):
        if sep in line:
            return sep
    return r"\s+"


def _read_text(path):
    try:
        lines = _first_data_lines(path)
    except UnicodeDecodeError as exc:  # pragma: no cover - errors="replace" above
        raise ValueError(f"{path} is not a text file; save the series as .npy, .csv or "
                         ".txt.") from exc
    if not lines:
        raise ValueError(f"{path} holds no data (empty or only '#' comments); "
                         "write one sample per line (one column per channel).")
    sep = _delimiter(lines[0])
    splitter = re.compile(sep) if sep == r"\s+" else None
    first = splitter.split(lines[0]) if splitter else [t.strip() for t in lines[0].split(sep)]
    header = 0 if not all(_NUMBER.match(tok) for tok in first if tok != "") else None
    try:
        frame = pd.read_csv(path, sep=sep, comment="#", header=header, skip_blank_lines=True,
                            engine="c" if sep != ";" else "python", skipinitialspace=True)
    except (pd.errors.ParserError, ValueError) as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        raise ValueError(f"cannot parse {path} as a table ({msg}); every line needs the same "
                         "number of columns, separated by spaces, commas or tabs.") from exc
    if header is None:
        frame.columns = list(range(frame.shape[1]))
    else:
        frame.columns = [str(c).strip() for c in frame.columns]
    return frame


def read_table(path):
    """Read a file of one or more time-series columns into a DataFrame.

    Parameters
    ----------
    path : str or path-like
        ``.npy``, ``.parquet`` or a text file (``.csv``, ``.txt``, ``.dat``, ...).
        Text files may use spaces, commas, semicolons or tabs as separators,
        ``#`` starts a comment, and a first line that is not numeric is read
        as the column names.

    Returns
    -------
    pandas.DataFrame
        One column per channel; columns are named from the header (text,
        parquet) or numbered ``0, 1, ...`` (``.npy``, text without header).

    Examples
    --------
    >>> import tempfile, os
    >>> from skdelay._io import read_table
    >>> path = os.path.join(tempfile.mkdtemp(), "x.csv")
    >>> _ = open(path, "w").write("# laser\\nt,intensity\\n0,1.5\\n1,2.5\\n2,0.5\\n")
    >>> read_table(path).columns.tolist()
    ['t', 'intensity']
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist; check the file name.")
    if path.is_dir():
        raise ValueError(f"{path} is a directory; pass the data file inside it.")
    if path.stat().st_size == 0:
        raise ValueError(f"{path} is empty; pass a file with one sample per line.")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        try:
            arr = np.load(path, allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            raise ValueError(f"{path} is not a valid .npy file ({exc}); "
                             "save it with numpy.save.") from exc
        if arr.ndim == 1:
            arr = arr[:, None]
        if arr.ndim != 2:
            raise ValueError(f"{path} holds an array of shape {arr.shape}; save a 1-D series "
                             "or a 2-D array with one column per channel.")
        return pd.DataFrame(arr)
    if suffix == ".parquet":
        try:
            return pd.read_parquet(path)
        except ImportError as exc:
            raise ValueError("reading .parquet needs pyarrow; run `pip install pyarrow` "
                             "or convert the file to .csv/.npy.") from exc
        except Exception as exc:
            raise ValueError(f"{path} is not a readable parquet file ({type(exc).__name__}); "
                             "check the file or convert it to .csv/.npy.") from exc
    if suffix in _TEXT_SUFFIXES:
        return _read_text(path)
    raise ValueError(f"unsupported file type {suffix!r} for {path}; use .npy, .csv, .txt, "
                     ".dat or .parquet.")


def _pick_column(frame, column, path):
    names = list(frame.columns)
    if column is None:
        if len(names) == 1:
            return names[0]
        shown = ", ".join(repr(str(c)) for c in names[:8]) + (", ..." if len(names) > 8 else "")
        raise ValueError(f"{path} has {len(names)} columns ({shown}); choose one with "
                         "--column NAME or --column INDEX (0-based).")
    key = str(column).strip()
    for name in names:
        if str(name) == key:
            return name
    if re.fullmatch(r"-?\d+", key):
        idx = int(key)
        if -len(names) <= idx < len(names):
            return names[idx]
        raise ValueError(f"column index {idx} is out of range: {path} has {len(names)} "
                         f"column(s), indices 0..{len(names) - 1}.")
    shown = ", ".join(repr(str(c)) for c in names[:8])
    raise ValueError(f"no column {key!r} in {path}; available columns: {shown} "
                     "(or a 0-based index).")


def read_series(path, column=None, *, min_length=2):
    """Read one scalar time series from a file and check it.

    Parameters
    ----------
    path : str or path-like
        See :func:`read_table` for the formats.
    column : str or int, optional
        Column name or 0-based index; required when the file has several
        columns.
    min_length : int, default=2
        Minimum number of samples.

    Returns
    -------
    pandas.Series
        float64 values, named after the column; indexed by the file's
        ``DatetimeIndex`` / ``TimedeltaIndex`` when it has one (parquet
        written by pandas), else by ``0..n-1``.

    Raises
    ------
    ValueError
        Empty or unparsable file, non-numeric values, NaN/inf, a constant
        or too short series, an unknown column.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from skdelay._io import read_series
    >>> path = os.path.join(tempfile.mkdtemp(), "x.npy")
    >>> np.save(path, np.sin(np.arange(100.0)))
    >>> read_series(path).shape
    (100,)
    """
    frame = read_table(path)
    if frame.shape[0] == 0:
        raise ValueError(f"{path} has a header line but no data rows; "
                         "write one sample per line below it.")
    name = _pick_column(frame, column, path)
    col = frame[name]
    if col.dtype == object or pd.api.types.is_string_dtype(col.dtype):
        numeric = pd.to_numeric(col, errors="coerce")
        bad = np.flatnonzero(numeric.isna().to_numpy() & col.notna().to_numpy())
        if bad.size:
            raise ValueError(f"column {name!r} of {path} holds non-numeric values "
                             f"(first: {col.iloc[bad[0]]!r} in data row {bad[0]}); "
                             "pass a file of numbers only (a header line is fine).")
        col = numeric
    try:
        values = check_series(col.to_numpy(), name=f"column {name!r} of {Path(path).name}",
                              min_length=min_length)
    except (ValueError, TypeError) as exc:
        raise type(exc)(str(exc).replace("\n", " ")) from exc
    # a time index (parquet written from pandas) carries the sampling step: keep it
    # so that the caller can read it with skdelay._checks.sample_dt_from_index
    index = frame.index if isinstance(frame.index, (pd.DatetimeIndex, pd.TimedeltaIndex)) else None
    return pd.Series(values, index=index, name=str(name))


def write_series(path, values, *, name="x", comment=None):
    """Write a 1-D series atomically as ``.npy`` or text (``.csv`` with header, else plain).

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from skdelay._io import write_series, read_series
    >>> path = os.path.join(tempfile.mkdtemp(), "x.csv")
    >>> _ = write_series(path, np.arange(5.0))
    >>> read_series(path).tolist()
    [0.0, 1.0, 2.0, 3.0, 4.0]
    """
    path = Path(path)
    values = np.asarray(values, dtype=float).reshape(-1)
    suffix = path.suffix.lower()
    if suffix not in {".npy"} | (_TEXT_SUFFIXES - {""}):
        raise ValueError(f"cannot write {suffix or 'a file without suffix'!r}; name the output "
                         "*.npy, *.csv or *.txt.")
    with atomic_path(path) as tmp:
        if suffix == ".npy":
            with open(tmp, "wb") as fh:
                np.save(fh, values)
        else:
            lines = [f"# {line}" for line in (comment or "").splitlines() if line]
            if suffix == ".csv":
                lines.append(name)
            body = "\n".join(lines + [""]) if lines else ""
            with open(tmp, "w", encoding="utf-8") as fh:
                fh.write(body)
                np.savetxt(fh, values, fmt="%.10g")
    return path


#: file skdelay writes into every output directory it creates; ``--force`` only
#: replaces directories that hold it, so a mistyped ``--out ~/thesis`` never deletes
#: anything skdelay did not write.
OUTPUT_MARKER = ".skdelay-output"


def is_skdelay_output(path):
    """True when ``path`` is a directory that skdelay wrote (it holds :data:`OUTPUT_MARKER`)."""
    return (Path(path) / OUTPUT_MARKER).is_file()


def check_output_directory(path, *, force=False):
    """Check, before any work, that ``path`` can become an output directory.

    Parameters
    ----------
    path : str or path-like
        The ``--out`` directory.
    force : bool
        Allow replacing an existing non-empty directory -- only one that
        skdelay wrote (it holds :data:`OUTPUT_MARKER`).

    Returns
    -------
    pathlib.Path

    Notes
    -----
    Also removes the stale temporaries of killed runs in the parent
    directory (see :func:`skdelay._atomic.clean_stale_temporaries`).

    Raises
    ------
    ValueError
        ``path`` is a file, a non-empty directory without ``force``, a
        directory skdelay did not write, or neither it nor its parent can be
        written.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{path} exists and is not a directory; choose another --out.")
    if path.is_dir() and any(path.iterdir()):
        if not force:
            raise ValueError(f"output directory {path} already exists and is not empty; "
                             "choose another --out or pass --force to replace it.")
        if not is_skdelay_output(path):
            raise ValueError(f"--force refuses to replace {path}: it was not written by skdelay "
                             f"(no {OUTPUT_MARKER} file inside); choose another --out or "
                             "delete it yourself.")
    check_writable(path, what="--out")
    # leftovers of killed runs go now, not only when this run writes (it may fail first)
    clean_stale_temporaries(path.absolute().parent)
    return path


@contextmanager
def atomic_directory(path, *, force=False):
    """Fill a temporary directory next to ``path``, then swap it into place.

    A reader sees either the old directory or the complete new one; on any
    error the temporary directory is removed and ``path`` is left untouched.
    After ``kill -9`` the hidden ``.NAME.skd<pid>...tmp`` stays behind until
    the next write into the same parent, which removes it (only when its
    owner process is gone).  The result holds the marker
    :data:`OUTPUT_MARKER`; an existing non-empty ``path`` is only replaced
    when ``force`` is true and ``path`` holds the marker too.

    Examples
    --------
    >>> import tempfile, os
    >>> from skdelay._io import atomic_directory
    >>> out = os.path.join(tempfile.mkdtemp(), "report")
    >>> with atomic_directory(out) as tmp:
    ...     _ = (tmp / "a.txt").write_text("done")
    >>> sorted(os.listdir(out))
    ['.skdelay-output', 'a.txt']
    """
    path = Path(path)
    check_output_directory(path, force=force)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = make_temporary(path, directory=True)
    try:
        yield tmp
        (tmp / OUTPUT_MARKER).write_text(
            "written by skdelay; `--force` may replace this directory\n", encoding="utf-8")
        os.chmod(tmp, 0o755)
        if path.exists():
            old = make_temporary(path, kind="old", directory=True)
            os.replace(path, old / "d")
            try:
                os.replace(tmp, path)
            except BaseException:
                os.replace(old / "d", path)
                raise
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


# ------------------------------------------------------------------- strict JSON
class Unavailable:
    """A value that could not be computed, with the reason why.

    :func:`dumps_strict` writes it as ``null`` and puts the reason beside it
    under ``"<key>_reason"``.

    Parameters
    ----------
    reason : str
        One line: why there is no value (and what would give one).
    """

    __slots__ = ("reason",)

    def __init__(self, reason):
        self.reason = str(reason)

    def __repr__(self):
        return f"Unavailable({self.reason!r})"


def _plain(obj, reasons, key=None, default=None):
    """Recursively convert ``obj`` into JSON-safe Python objects (non-finite -> None)."""
    if isinstance(obj, Unavailable):
        return None
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        value = float(obj)
        return value if math.isfinite(value) else None
    if isinstance(obj, (complex, np.complexfloating)):
        raise TypeError(f"cannot write the complex number {obj!r} as JSON; store its real "
                        "part and imaginary part separately.")
    if isinstance(obj, dict):
        out = {}
        for k, v in obj.items():
            name = str(k)
            out[name] = _plain(v, reasons, name, default)
            reason_key = f"{name}_reason"
            if out[name] is None and reason_key not in obj:
                reason = (v.reason if isinstance(v, Unavailable)
                          else (reasons or {}).get(name))
                if reason is not None:
                    out[reason_key] = str(reason)
        return out
    if isinstance(obj, (pd.Series, pd.Index)):
        obj = obj.tolist()
    elif isinstance(obj, pd.DataFrame):
        return _plain(obj.to_dict(orient="list"), reasons, key, default)
    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    if isinstance(obj, (list, tuple, set, frozenset)):
        return [_plain(v, reasons, key, default) for v in obj]
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    if hasattr(obj, "to_dict"):
        return _plain(obj.to_dict(), reasons, key, default)
    if default is not None:
        return _plain(default(obj), reasons, key, None)
    raise TypeError(f"cannot write {type(obj).__name__} as JSON (at key {key!r}); convert it "
                    "to numbers, strings, lists or dicts first.")


def dumps_strict(obj, *, reasons=None, indent=2, default=None):
    """Serialise ``obj`` as strict JSON (RFC 8259): NaN and infinities become ``null``.

    ``json.dumps`` writes bare ``NaN`` / ``Infinity``, which JavaScript,
    ``jq`` and most JSON parsers reject; here every non-finite float becomes
    ``null``, and when the caller knows why (an :class:`Unavailable` value,
    or ``reasons[key]``) the reason is written beside it as
    ``"<key>_reason"`` (unless the dict already has that key).  numpy
    scalars/arrays, pandas objects and paths are converted.

    Parameters
    ----------
    obj : object
        dicts, lists, numbers, strings, numpy/pandas objects, :class:`Unavailable`.
    reasons : dict of str to str, optional
        Reason for a ``null`` under a key of that name (at any depth).
    indent : int or None, default=2
    default : callable, optional
        Called on objects of other types (like ``json.dumps``'s ``default``,
        e.g. ``str``); its result is converted in turn.  Without it such
        objects raise ``TypeError``.

    Returns
    -------
    str

    Examples
    --------
    >>> from skdelay._io import dumps_strict, Unavailable
    >>> print(dumps_strict({"delay": float("nan"), "m": Unavailable("no dip")}, indent=None))
    {"delay": null, "m": null, "m_reason": "no dip"}
    """
    return json.dumps(_plain(obj, reasons, None, default), indent=indent, allow_nan=False)


def write_json(path_or_file, obj, *, reasons=None, indent=2, default=None):
    """Write ``obj`` as strict JSON (see :func:`dumps_strict`) to a path (atomically) or file.

    Parameters
    ----------
    path_or_file : str, path-like or text file object
    obj : object
    reasons, indent, default
        As in :func:`dumps_strict`.

    Returns
    -------
    str
        The JSON text written (without the final newline).
    """
    text = dumps_strict(obj, reasons=reasons, indent=indent, default=default)
    if hasattr(path_or_file, "write"):
        path_or_file.write(text + "\n")
    else:
        write_text(path_or_file, text + "\n")
    return text
