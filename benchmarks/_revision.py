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


def ab_parser(doc, *, repeats, baseline):
    """The options of a same-run A/B script: ``--repeats``, ``--baseline REV`` and the hidden
    ``--worker`` (the subprocess that measures one package and prints JSON)."""
    import argparse

    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=repeats)
    parser.add_argument("--baseline", default=baseline, metavar="REV")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    return parser
