"""The README's commands and examples are tests, and so are the blocks that moved from it into the
user guide (docs/user/*.md): the drop test from Python with its repeat, the studies API, the
material example.

README.md is the short front page: every command line in it parses as ``cfm`` reads it, the drop
test commands run (on a coarse mesh), its Python blocks run and their values are checked, its
commands table lists exactly the subcommands, its numbers come from the paper script's table.
"""

import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from cfm_core import plugins

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
USER = ROOT / "docs" / "user"


def _pages(*paths):
    return pytest.mark.parametrize("page", paths, ids=lambda p: p.relative_to(ROOT).as_posix())


def test_readme_opens_with_the_two_setup_commands_and_ci_runs_the_second():
    text = README
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


@_pages(ROOT / "README.md", USER / "drop-test.md")
def test_readme_python_api_block_runs(page, tmp_path, monkeypatch, capsys):
    """The 'From Python' block: a 5 mm drop test, a parameter change, a comparison, a table, files;
    on the user-guide page also the repeat from the saved scene.toml."""
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(_python_block("cfm.drop_test(", page.read_text()), page.name, "exec"), namespace)
    base, stiffer, df = namespace["base"], namespace["stiffer"], namespace["df"]
    assert abs(base.peak_g - 117.2) < 0.1  # the README's paper table, 5 mm, long-term moduli
    assert stiffer.peak_g > base.peak_g and stiffer.compare(base)["peak_diff"] > 0
    assert list(df.columns) == ["t [s]", "a_raw [m/s^2]", "a_cfc600 [m/s^2]", "a_cfc600 [g]"]
    assert abs(df["a_cfc600 [g]"].max() - base.peak_g) < 1e-9
    assert (tmp_path / "out" / "drop-5mm" / "summary.json").is_file()
    if page.name == "drop-test.md":  # the repeat: the same history, sample for sample
        assert namespace["again"].to_dataframe().equals(df)


MATERIAL_PAGES = [p for p in (ROOT / "README.md", USER / "materials.md") if "register_material(" in p.read_text()]


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


@_pages(ROOT / "README.md", USER / "sweeps.md")
def test_readme_study_api_block_runs(page, tmp_path, monkeypatch):
    """The studies block: cfm.sweep(...).to_dataframe() with units, the saved files, cfm.uniaxial."""
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(_python_block("cfm.sweep(", page.read_text()), page.name, "exec"), namespace)
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


def test_the_front_page_is_short():
    assert len(README.splitlines()) <= 200
    assert not (ROOT / "docs" / "README-draft.md").exists(), "the draft became README.md"


def _command_lines(text: str) -> list[str]:
    """The ``cfm ...`` command lines of the bash blocks of ``text`` (comments and set-up lines
    off, continued lines joined, an environment-variable prefix dropped)."""
    lines = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        for line in block.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            while words and re.fullmatch(r"[A-Z_]+=.*", words[0]):
                words = words[1:]
            if words[:1] == ["cfm"]:
                lines.append(shlex.join(words))
    return lines


@pytest.mark.parametrize("page", [ROOT / "README.md", *sorted(USER.glob("*.md"))],
                         ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_command_line_parses(page):
    """Every ``cfm`` line of the README's and the user guide's bash blocks names a real command
    with real options (``cfm`` refuses what argparse does not know)."""
    from cfm_core.cli.app import build_parser

    parser = build_parser()
    lines = _command_lines(page.read_text())
    for line in lines:
        args, extra = parser.parse_known_args(shlex.split(line)[1:])
        assert not extra, f"{page.name}: {line!r}: cfm does not know {extra}"
    if page.name == "README.md":
        assert len(lines) >= 5


def test_command_line_reader_sees_what_the_pages_write():
    text = "```bash\nFOO=a=b cfm drop-test --out x   # c\ncfm fit --test a.csv:uniaxial:1 \\\n    --fit k1\nls\n```\n"
    assert _command_lines(text) == ["cfm drop-test --out x", "cfm fit --test a.csv:uniaxial:1 --fit k1"]


def test_readme_drop_test_commands_run(tmp_path, monkeypatch):
    """The README's drop-test block, each line on a coarse quarter specimen (2 mm elements, 20 mm
    wide), in order (the torch line is left to tests/backends): the repeat from the scene.toml of
    the first run gives the same file, byte for byte."""
    from cfm_core.cli import main

    monkeypatch.chdir(tmp_path)
    section = _section(README, "The drop test")
    lines = _command_lines(section.split("```python")[0])
    assert lines[-1].startswith("cfm run --scene out/drop-5mm/scene.toml")
    (tmp_path / "my-scene.toml").write_text('[scene]\ntype = "drop-test"\n\n[specimen]\nthickness = 0.006\n')
    small = ["--element-size", "0.002", "--width", "0.02", "--quiet", "--no-plot"]
    for line in lines:
        argv = shlex.split(line)[1:]
        if "torch" in argv:  # the same run on torch: tests/backends (12 s here on a busy CPU)
            continue
        if argv[0] == "drop-test":
            argv += small
        else:
            argv += ["--quiet", "--no-plot"]
        assert main(argv) == 0, line
    first, again = (tmp_path / "out" / n / "acceleration.csv" for n in ("drop-5mm", "again"))
    assert again.read_bytes() == first.read_bytes()
    assert "repeats a run exactly" in section


@_pages(ROOT / "README.md")
def test_front_page_lists_every_command_once(page):
    """The commands table names exactly the subcommands of ``cfm`` (a new command needs its line)."""
    from cfm_core.cli.app import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    listed = re.findall(r"^\| `cfm ([a-z-]+)` \|", _section(page.read_text(), "Commands"), re.M)
    assert sorted(listed) == sorted(sub.choices), f"listed {listed}, cfm has {sorted(sub.choices)}"


@_pages(ROOT / "README.md")
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


@_pages(ROOT / "README.md")
def test_front_page_docs_build_command_is_the_sites(page):
    text = _section(page.read_text(), "Documentation")
    build = "sphinx-build -W --keep-going -b html docs docs/_build/html"
    assert build in text and build in (ROOT / "docs" / "dev" / "docs.md").read_text()
    assert re.search(r'^docs = \[', (ROOT / "pyproject.toml").read_text(), re.M), "no docs extra"
    assert 'pip install -c constraints.txt -e ".[all,docs]"' in text
