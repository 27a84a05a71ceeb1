"""The package as of an earlier git revision, for the benchmarks' same-run baselines.

``python benchmarks/<script>.py`` puts this folder first on ``sys.path``, so the
scripts import it as ``from _revision import export_package``.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def export_package(rev, dest):
    """Write ``skdelay/`` as of git revision ``rev`` into the folder ``dest`` (``git archive``,
    committed files only) and return ``dest``: put it on ``PYTHONPATH`` to run that version."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "skdelay"], check=True,
                             capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(dest)], input=archive, check=True)
    return dest
