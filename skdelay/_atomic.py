"""Atomic file and directory writes that survive ``kill -9``.

A reader sees the old file or the complete new one, never half.  Outputs are
built in a hidden temporary ``.NAME.skd<pid>x<start>_<random>.tmp`` next to
the target and renamed into place at the end.  The owning process id and its
start time are part of the name, so a later run into the same directory can
tell leftovers of a killed run (owner gone) from work in progress of a
running one (owner alive) and removes only the former
(:func:`clean_stale_temporaries`).
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_path", "check_writable", "clean_stale_temporaries", "make_temporary",
           "owner_tag", "remove_own_temporaries", "write_bytes", "write_text"]

#: ``.NAME.skd<pid>x<start>_<random>.<kind>``; NAME may itself contain dots, so the
#: pattern is anchored at the end.  ``tmp`` = output being built, ``old`` = the
#: previous output moved aside during a ``--force`` swap.
_TEMP_NAME = re.compile(r"^\.(?P<name>.+)\.skd(?P<pid>\d+)x(?P<start>\d+)_[a-z0-9_]+\."
                        r"(?P<kind>tmp|old)$")


def _start_time(pid):
    """Start time of process ``pid`` in clock ticks since boot (0 when unknown).

    Guards against pid reuse: a leftover whose pid now belongs to a *different*
    process (other start time) is stale too.  Only Linux exposes it cheaply
    (``/proc/PID/stat`` field 22); elsewhere 0 means "trust the pid alone".
    """
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as fh:
            stat = fh.read()
    except OSError:
        return 0
    # the command name (field 2) may contain spaces and parentheses: split after the last ')'
    fields = stat.rsplit(")", 1)[-1].split()
    try:
        return int(fields[19])
    except (IndexError, ValueError):
        return 0


def owner_tag(pid=None):
    """The ``skd<pid>x<start>_`` tag of temporaries owned by process ``pid`` (default: this one)."""
    pid = os.getpid() if pid is None else int(pid)
    return f"skd{pid}x{_start_time(pid)}_"


def _owner_alive(pid, start):
    if pid == os.getpid():
        return _start_time(pid) == start or start == 0
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by another user
        pass
    except OSError:  # pragma: no cover - exotic platforms: assume alive (never delete work)
        return True
    now = _start_time(pid)
    return start == 0 or now == 0 or now == start


#: parent directories in which this process created temporaries (see remove_own_temporaries)
_DIRECTORIES = set()


def clean_stale_temporaries(directory):
    """Remove the leftovers of killed skdelay runs in ``directory``; return their names.

    Only entries named like skdelay's temporaries whose owning process is
    gone are touched; temporaries of running processes and every other file
    are left alone.  A stale ``.old`` directory (the previous output moved
    aside by a ``--force`` swap that was killed) is moved back when its
    target is missing, so an interrupted swap never loses the old output.

    Parameters
    ----------
    directory : str or path-like
        The parent directory of an output.

    Returns
    -------
    list of str
        Names of the removed (or restored) entries.
    """
    return _clean(directory, lambda pid, start: not _owner_alive(pid, start))


def remove_own_temporaries():
    """Remove the temporaries this process created and still holds; return their names.

    The safety net of a run that is terminated (SIGTERM, Ctrl-C): a signal can
    land after a temporary is created and before the code that would remove it
    on failure has it in hand (inside ``tempfile.mkstemp``, or between it and
    the ``try`` of :func:`atomic_path`).  A ``.old`` output moved aside by an
    interrupted ``--force`` swap is moved back when its target is missing.
    """
    pid, start = os.getpid(), _start_time(os.getpid())
    removed = []
    for directory in sorted(_DIRECTORIES):
        removed += _clean(directory, lambda p, s: p == pid and (s == start or s == 0))
    return removed


def _clean(directory, remove):
    """Remove (or restore) the skdelay temporaries in ``directory`` whose owner
    ``(pid, start)`` satisfies ``remove``; return their names."""
    directory = Path(directory)
    removed = []
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return removed
    for entry in entries:
        match = _TEMP_NAME.match(entry.name)
        if match is None or not remove(int(match["pid"]), int(match["start"])):
            continue
        path = Path(entry.path)
        target = directory / match["name"]
        if match["kind"] == "old" and (path / "d").exists() and not os.path.lexists(target):
            try:
                os.replace(path / "d", target)
            except OSError:
                pass
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            try:
                path.unlink()
            except OSError:
                continue
        removed.append(entry.name)
    return removed


def make_temporary(path, *, kind="tmp", directory=False):
    """Create a hidden temporary file or directory next to ``path``, owned by this process.

    Stale temporaries of killed runs in the same parent are removed first.

    Parameters
    ----------
    path : path-like
        The final target.
    kind : {"tmp", "old"}
        Suffix: ``tmp`` for an output being built, ``old`` for a replaced one.
    directory : bool
        Create a directory (else an empty file).

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    clean_stale_temporaries(path.parent)
    _DIRECTORIES.add(str(path.parent.absolute()))  # before creating: see remove_own_temporaries
    prefix = f".{path.name}.{owner_tag()}"
    if directory:
        return Path(tempfile.mkdtemp(prefix=prefix, suffix=f".{kind}", dir=path.parent))
    fd, tmp = tempfile.mkstemp(prefix=prefix, suffix=f".{kind}", dir=path.parent)
    os.close(fd)
    return Path(tmp)


def check_writable(path, *, what="--out"):
    """Raise ``ValueError`` unless ``path`` could be created (or replaced) by this process.

    Walks up to the nearest existing ancestor, which must be a directory, and
    probes it by creating and removing a temporary file (``os.access`` is
    not enough: it says yes to root on read-only mounts and knows nothing
    of ``/proc``).  Nothing is left behind.

    Parameters
    ----------
    path : path-like
        The output file or directory.
    what : str
        Name of the option, for the message.

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    if path.exists() and path.is_dir() and not os.access(path, os.W_OK | os.X_OK):
        raise ValueError(f"{what} {path}: the directory is not writable; choose another {what}.")
    parent = path.absolute().parent
    while not parent.exists():
        if parent.parent == parent:  # pragma: no cover - the root always exists
            break
        parent = parent.parent
    if not parent.is_dir():
        raise ValueError(f"{what} {path}: {parent} is a file, not a directory; "
                         f"choose another {what}.")
    try:
        # named like a temporary, so a kill right here leaves nothing a later run keeps
        fd, probe = tempfile.mkstemp(prefix=f".probe.{owner_tag()}", suffix=".tmp", dir=parent)
    except OSError as exc:
        reason = os.strerror(exc.errno) if exc.errno else type(exc).__name__
        if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
            reason = "permission denied" if exc.errno != errno.EROFS else "read-only file system"
        raise ValueError(f"{what} {path}: cannot write in {parent} ({reason}); "
                         f"choose another {what}.") from None
    os.close(fd)
    os.unlink(probe)
    return path


@contextmanager
def atomic_path(path):
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success.

    On any exception the temporary file is removed and ``path`` is untouched;
    after ``kill -9`` the next write into the same directory removes it.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = make_temporary(path)
    try:
        yield tmp
        # mkstemp creates 0600 files; give the result the usual umask-based mode.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_text(path, text, encoding="utf-8"):
    """Write ``text`` to ``path`` atomically and return the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding=encoding)
    return Path(path)


def write_bytes(path, data):
    """Write ``data`` to ``path`` atomically and return the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)
