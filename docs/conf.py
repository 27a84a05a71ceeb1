"""Sphinx configuration of the skdelay documentation.

Build: ``python -m sphinx -b html -W docs docs/_build/html``.  Figures of the
example pages come from ``docs/make_figures.py``; missing ones are generated
at build time (a few minutes on two cores), existing ones are reused.
"""

import os
import sys
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

os.environ.setdefault("MPLBACKEND", "Agg")

project = "skdelay"
author = "skdelay developers"
copyright = "skdelay developers"
try:
    release = _version("skdelay")
except PackageNotFoundError:  # pragma: no cover - docs built from a plain checkout
    release = "0.1.0"
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.intersphinx",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
]

autosummary_generate = True
autodoc_default_options = {}
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks = set()
numpydoc_xref_param_type = False

intersphinx_mapping = {}  # offline build: no network access needed

templates_path = []
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]
html_theme = "alabaster"
html_static_path = ["_static"]
html_theme_options = {"description": "systems with delayed feedback, scikit-learn style"}
suppress_warnings = ["config.cache"]


def _figures(app):
    import make_figures

    make_figures.main(only_missing=True)


def setup(app):
    app.connect("builder-inited", _figures)
