"""The README's commands and examples are tests.

They run on every front page: ``README.md`` and, while it exists, the draft of the short front page
``docs/README-draft.md`` (the draft becomes README.md; the material example then lives on the
user-guide page docs/user/materials.md, which is checked too).
"""

import re
from pathlib import Path

import numpy as np
import pytest

from cfm_core import plugins

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
FRONT_PAGES = [p for p in (ROOT / "README.md", ROOT / "docs" / "README-draft.md") if p.is_file()]
pages = pytest.mark.parametrize("page", FRONT_PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())


@pages
def test_readme_opens_with_the_two_setup_commands_and_ci_runs_the_second(page):
    text = page.read_text()
    block = re.search(r"```bash\n(.*?)```", text, re.S).group(1).strip().splitlines()
    assert block[0].startswith('pip install -c constraints.txt -e ".[all]" && cfm drop-test --out')
    test_cmd = block[1].split("#")[0].strip()
    assert test_cmd == 'pip install -c constraints.txt -e ".[all,test]" && python -m pytest'
    ci = (ROOT / ".ci" / "run").read_text()
    extras = re.search(r'-c constraints\.txt -e "\.\[([a-z,]+)\]"', ci).group(1).split(",")
    assert {"all", "test"} <= set(extras) and "python -m pytest" in ci  # CI adds "docs" to build the site
    assert "torch==2.13.0" in (ROOT / "constraints.txt").read_text()


def _python_block(marker: str, text: str = README) -> str:
    """The python code block of ``text`` that contains ``marker``."""
    return next(b for b in re.findall(r"```python\n(.*?)```", text, re.S) if marker in b)


@pages
def test_readme_python_api_block_runs(page, tmp_path, monkeypatch, capsys):
    """The 'From Python' block: a 5 mm drop test, a parameter change, a comparison, a table, files."""
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(_python_block("cfm.drop_test(", page.read_text()), page.name, "exec"), namespace)
    base, stiffer, df = namespace["base"], namespace["stiffer"], namespace["df"]
    assert abs(base.peak_g - 117.2) < 0.1  # the README's paper table, 5 mm, long-term moduli
    assert stiffer.peak_g > base.peak_g and stiffer.compare(base)["peak_diff"] > 0
    assert list(df.columns) == ["t [s]", "a_raw [m/s^2]", "a_cfc600 [m/s^2]", "a_cfc600 [g]"]
    assert abs(df["a_cfc600 [g]"].max() - base.peak_g) < 1e-9
    assert (tmp_path / "out" / "drop-5mm" / "summary.json").is_file()


MATERIAL_PAGES = [p for p in (ROOT / "README.md", ROOT / "docs" / "user" / "materials.md")
                  if "register_material(" in p.read_text()]


@pytest.mark.parametrize("page", MATERIAL_PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_readme_material_example_runs(page, capsys):
    code = _python_block("register_material(", page.read_text())
    try:
        exec(compile(code, page.name, "exec"), {})
        printed = capsys.readouterr().out
        assert "[[[" in printed
        from cfm_core import make_material
        from cfm_core.material import reference as ref

        sigma = ref.cauchy(make_material("my-mr", {"c10": 250.0}), np.diag([0.8, 1.1, 1.1]))[0]
        assert sigma[0, 0] < 0 and np.isfinite(sigma).all()
    finally:
        plugins.unregister("materials", "my-mr")


def test_readme_study_api_block_runs(tmp_path, monkeypatch):
    """The studies block: cfm.sweep(...).to_dataframe() with units, the saved files, cfm.uniaxial."""
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(_python_block("cfm.sweep("), "README.md", "exec"), namespace)
    df, curve = namespace["df"], namespace["curve"]
    assert list(df.columns[:5]) == ["run_id", "thickness [m]", "k2 [-]", "status", "error"]
    assert list(df["status"]) == ["ok"] * 4 and list(df["k2 [-]"]) == [1.6, 1.8] * 2
    peaks = df.set_index(["thickness [m]", "k2 [-]"])["peak_g [g]"]
    assert peaks[(0.005, 1.8)] > peaks[(0.005, 1.6)] > peaks[(0.008, 1.6)]  # stiffer, thinner: harder
    saved = tmp_path / "out" / "k2-sweep"
    assert {"sweep.csv", "sweep.json", "peaks.png", "runs"} <= {p.name for p in saved.iterdir()}
    assert list(curve.columns) == ["t [s]", "stretch [-]", "nominal_stress [Pa]", "lateral_stretch [-]"]


def test_the_material_example_lives_on_the_user_guide_page():
    assert ROOT / "docs" / "user" / "materials.md" in MATERIAL_PAGES


# ----------------------------------------------------------------------------- the short front page
def _section(text: str, heading: str) -> str:
    m = re.search(rf"^## {re.escape(heading)}\n(.*?)(?=^## |\Z)", text, re.S | re.M)
    assert m, f"no section '## {heading}'"
    return m.group(1)


SHORT = [p for p in FRONT_PAGES if "## Commands" in p.read_text()]
short_pages = pytest.mark.parametrize("page", SHORT, ids=lambda p: p.relative_to(ROOT).as_posix())


def test_the_draft_front_page_is_short():
    draft = ROOT / "docs" / "README-draft.md"
    if draft.is_file():
        assert draft in SHORT and len(draft.read_text().splitlines()) <= 200


@short_pages
def test_front_page_lists_every_command_once(page):
    """The commands table names exactly the subcommands of ``cfm`` (a new command needs its line)."""
    from cfm_core.cli.app import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    listed = re.findall(r"^\| `cfm ([a-z-]+)` \|", _section(page.read_text(), "Commands"), re.M)
    assert sorted(listed) == sorted(sub.choices), f"listed {listed}, cfm has {sorted(sub.choices)}"


@short_pages
def test_front_page_numbers_come_from_the_paper_script(page):
    """Every peak (g) in 'The first result' is in the table python -m cfm_verification.paper wrote,
    at the thickness and convention the text gives, or is an experimental peak of the paper."""
    from cfm_verification.paper import EXPERIMENT_PEAKS_G

    rows = [r.strip("|").split("|") for r in (ROOT / "docs" / "paper" / "table.md").read_text().splitlines()[2:]]
    table = {(r[0].strip(), int(r[1])): r[2].strip() for r in rows}
    text = _section(page.read_text(), "The first result")
    experiment = {f"{v:g}" for v in EXPERIMENT_PEAKS_G.values()}
    quoted = re.findall(r"(\d+\.\d) g", text)
    assert len(quoted) >= 5
    for value in quoted:
        assert value in experiment or value in table.values(), f"{value} g is in neither the paper table nor the paper"
    # the ones tied to a thickness in the text
    assert table[("long-term", 8)] in text and table[("long-term", 5)] in text and table[("instantaneous", 8)] in text
    assert "python -m cfm_verification.paper --out docs/paper" in text
    for image in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", page.read_text()):
        assert (ROOT / image).is_file(), image


@short_pages
def test_front_page_docs_build_command_is_the_sites(page):
    text = _section(page.read_text(), "Documentation")
    build = "sphinx-build -W --keep-going -b html docs docs/_build/html"
    assert build in text and build in (ROOT / "docs" / "dev" / "docs.md").read_text()
    assert re.search(r'^docs = \[', (ROOT / "pyproject.toml").read_text(), re.M), "no docs extra"
    assert 'pip install -c constraints.txt -e ".[all,docs]"' in text
