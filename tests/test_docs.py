"""The documentation site (docs/, Sphinx): every public name of ``cfm`` is in the API reference,
every page is reachable from the index, and the site builds with warnings as errors.

The first two checks read the sources and need no Sphinx; the build runs when Sphinx and the
``docs`` extra are installed (``pip install -e ".[docs]"``; CI installs it). The build here skips
the gallery's execution (``-D plot_gallery=0``): ``tests/test_examples.py`` runs the examples, and
``.ci/run`` builds the whole site, gallery included.
"""

from __future__ import annotations

import fnmatch
import importlib.util
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import cfm_core

DOCS = Path(__file__).resolve().parents[1] / "docs"
#: Folders of docs/ that hold generated or non-page files.
GENERATED = ("_build", "_templates", "_static", "auto_examples", "api/generated", "examples")
#: Pages sphinx-gallery writes into docs/ (an orphan page of execution times).
GENERATED_PAGES = ("sg_execution_times.rst",)


# ----------------------------------------------------------------------------- API reference
def autosummary_entries(text: str) -> set[str]:
    """Names listed in the ``.. autosummary::`` blocks of an rst text, qualified with the
    ``.. currentmodule::`` in force (``cfm_core.drop_test``)."""
    names, module, inside = set(), "", False
    for line in text.splitlines():
        stripped = line.strip()
        if m := re.match(r"\.\. currentmodule:: (\S+)", stripped):
            module, inside = m.group(1), False
        elif stripped.startswith(".. autosummary::"):
            inside = True
        elif inside and stripped and not line.startswith((" ", "\t")):
            inside = False
        elif inside and stripped and not stripped.startswith(":"):
            names.add(stripped if "." in stripped or not module else f"{module}.{stripped}")
    return names


def missing_from_api(public: list[str], entries: set[str], package: str = "cfm_core") -> list[str]:
    """The names of ``public`` that no autosummary entry documents as ``package.name``."""
    return [n for n in public if f"{package}.{n}" not in entries]


def test_every_public_name_of_cfm_is_in_the_api_reference():
    entries = set().union(*(autosummary_entries(p.read_text()) for p in (DOCS / "api").glob("*.rst")))
    missing = missing_from_api(cfm_core.__all__, entries)
    assert not missing, f"names of cfm_core.__all__ not listed in docs/api/*.rst (add them to docs/api/cfm.rst): {missing}"


def test_api_checker_reports_a_name_left_out():
    text = ".. currentmodule:: cfm_core\n\n.. autosummary::\n   :toctree: generated\n\n   drop_test\n\nText.\n"
    assert autosummary_entries(text) == {"cfm_core.drop_test"}
    assert missing_from_api(["drop_test", "sweep"], autosummary_entries(text)) == ["sweep"]


# ----------------------------------------------------------------------------- pages and toctrees
def _exclude_patterns() -> list[str]:
    source = (DOCS / "conf.py").read_text()
    block = re.search(r"exclude_patterns = \[(.*?)\]", source, re.S).group(1)
    return re.findall(r'"([^"]+)"', block)


def source_pages(root: Path = DOCS, exclude: list[str] | None = None) -> set[str]:
    """Document names (``user/model``) of the .md and .rst pages under ``root``, without the
    excluded patterns (Sphinx's ``exclude_patterns``) and the generated folders."""
    exclude = _exclude_patterns() if exclude is None else exclude
    pages = set()
    for path in root.rglob("*"):
        rel = path.relative_to(root).as_posix()
        if (path.suffix not in (".md", ".rst") or rel in GENERATED_PAGES
                or rel.startswith(tuple(g + "/" for g in GENERATED))):
            continue
        if any(fnmatch.fnmatch(rel, pat) or rel.startswith(pat.rstrip("/*") + "/") for pat in exclude):
            continue
        pages.add(rel.rsplit(".", 1)[0])
    return pages


def toctree_entries(text: str, suffix: str) -> list[str]:
    """Entries of the toctrees of one page (MyST ```` ```{toctree} ```` or rst ``.. toctree::``)."""
    if suffix == ".md":
        blocks = re.findall(r"```\{toctree\}\n(.*?)```", text, re.S)
    else:
        blocks = re.findall(r"\.\. toctree::\n((?:[ \t]+.*\n|\n)*)", text)
    entries = []
    for block in blocks:
        for line in block.splitlines():
            line = line.strip()
            if line and not line.startswith(":"):
                entries.append(re.sub(r"^.*<(.+)>$", r"\1", line))  # "Title <page>" -> page
    return entries


def reachable(root: Path = DOCS, start: str = "index") -> set[str]:
    """Document names reached from ``start`` through toctrees (entries relative to the page, or
    absolute from the source root with a leading /)."""
    seen, todo = set(), [start]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        path = next((root / f"{name}{s}" for s in (".md", ".rst") if (root / f"{name}{s}").is_file()), None)
        if path is None:
            continue
        for entry in toctree_entries(path.read_text(), path.suffix):
            if entry.startswith("/"):
                target = entry[1:]
            else:
                target = (Path(name).parent / entry).as_posix()
            parts = []
            for p in target.split("/"):
                if p == "..":
                    parts.pop()
                elif p not in ("", "."):
                    parts.append(p)
            todo.append("/".join(parts))
    return seen


def test_every_page_is_reachable_from_the_index():
    pages = source_pages()
    assert {"index", "user/index", "api/index", "dev/index", "conventions", "architecture"} <= pages
    lost = sorted(pages - reachable())
    assert not lost, f"pages in docs/ not reachable from the index toctree: {lost}"
    assert "auto_examples/index" in reachable(), "the gallery is not in the index toctree"


def test_every_example_is_in_the_gallery():
    header = DOCS / "examples" / "GALLERY_HEADER.rst"
    assert header.is_file(), "sphinx-gallery needs docs/examples/GALLERY_HEADER.rst"
    conf = (DOCS / "conf.py").read_text()
    pattern = re.search(r'"filename_pattern": r"([^"]+)"', conf).group(1)
    for example in (DOCS / "examples").glob("*.py"):  # run by the gallery, so its figures are real
        assert re.search(pattern, "/" + example.name), f"{example.name} is not run by the gallery"
        assert re.match(r'"""\n.+\n=+\n', example.read_text()), f"{example.name}: no gallery title"


def test_reachability_checker_finds_an_orphan(tmp_path):
    (tmp_path / "user").mkdir()
    (tmp_path / "index.md").write_text("# Home\n\n```{toctree}\nuser/index\n```\n")
    (tmp_path / "user" / "index.md").write_text("# Guide\n\n```{toctree}\n:maxdepth: 2\n\nmodel\n/other\n```\n")
    for name in ("user/model", "other", "orphan"):
        (tmp_path / f"{name}.md").write_text("# page\n")
    assert source_pages(tmp_path, exclude=[]) - reachable(tmp_path) == {"orphan"}


# ----------------------------------------------------------------------------- the build
DOC_MODULES = ("sphinx", "numpydoc", "furo", "sphinx_gallery", "myst_parser")


@pytest.mark.skipif(any(importlib.util.find_spec(m) is None for m in DOC_MODULES),
                    reason='the docs extra is not installed (pip install -e ".[docs]")')
def test_site_builds_with_warnings_as_errors(tmp_path):
    """``sphinx-build -W --keep-going -b html`` on a copy of docs/ (the checkout stays clean),
    offline, the gallery's examples not executed; about 30 s on 2 cores."""
    src = tmp_path / "docs"
    shutil.copytree(DOCS, src, ignore=shutil.ignore_patterns("_build", "auto_examples", "generated",
                                                             "sg_execution_times.rst"))
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", "-D", "plot_gallery=0",
           str(src), str(tmp_path / "html")]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"sphinx-build failed:\n{proc.stdout[-4000:]}\n{proc.stderr[-8000:]}"
    html = tmp_path / "html"
    for page in ("index.html", "user/drop-test.html", "api/cfm.html", "auto_examples/index.html",
                 "api/generated/cfm_core.drop_test.html"):
        assert (html / page).is_file(), page
