"""Sphinx configuration of the cfm-materials documentation site.

Build (offline, warnings as errors; ``pip install -e ".[docs]"`` first)::

    sphinx-build -W --keep-going -b html docs docs/_build/html

The gallery runs every script of ``docs/examples`` (each a few seconds; the first numba run of a
machine compiles the kernels, about 30 s). ``-D plot_gallery=0`` builds without running them.
No intersphinx: the build never fetches anything.
"""

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if (ROOT / "cfm_core").is_dir():  # a plain checkout; an installed project is found anyway
    sys.path.insert(0, str(ROOT))

import cfm_core  # noqa: E402

os.environ.setdefault("MPLBACKEND", "Agg")

project = "cfm-materials"
author = "cfm-materials contributors"
copyright = "cfm-materials contributors, BSD-3-Clause"
version = release = cfm_core.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
templates_path = ["_templates"]
# Files in docs/ that are not pages: generated tables included from pages, the examples' sources
# (the gallery renders them), build output.
exclude_patterns = [
    "_build", "examples/*", "auto_examples/*.ipynb", "auto_examples/*.py",
    "auto_examples/*.zip", "auto_examples/*.json", "auto_examples/*.md5",
    "paper/*.md", "scenes/*.md", "septa/*.md", "skfem/*.md", "skfem/*-*mm/*",
]

# MyST: $...$ math, ::: fences, headings get anchors for cross-page links (docs/user/*.md#...)
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

# API reference: stubs generated from the names listed in docs/api/*.rst (tests/test_docs.py checks
# that every name of cfm_core.__all__ is listed there).
autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_typehints = "none"  # the numpydoc sections state types, shapes and units
autodoc_mock_imports = []   # backends import numba/torch/skfem inside methods only
numpydoc_show_class_members = False  # members come from the class template (no stub per method)
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"\.py$",       # run every example (all take seconds on 2 mm meshes)
    "ignore_pattern": r"__init__\.py",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "reset_modules": ("matplotlib",),
    "abort_on_example_error": True,
    "min_reported_time": 1,
}

html_theme = "furo"
html_title = f"cfm-materials {release}"
html_static_path = ["_static"]
html_theme_options = {"navigation_with_keys": True}

nitpicky = False

