"""The README's commands and examples are tests."""

import re
from pathlib import Path

import numpy as np

from cfm_core import plugins

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def test_readme_opens_with_the_two_setup_commands_and_ci_runs_the_second():
    block = re.search(r"```bash\n(.*?)```", README, re.S).group(1).strip().splitlines()
    assert block[0].startswith('pip install -c constraints.txt -e ".[all]" && cfm drop-test --out')
    test_cmd = block[1].split("#")[0].strip()
    assert test_cmd == 'pip install -c constraints.txt -e ".[all,test]" && python -m pytest'
    ci = (ROOT / ".ci" / "run").read_text()
    extras = re.search(r'-c constraints\.txt -e "\.\[([a-z,]+)\]"', ci).group(1).split(",")
    assert {"all", "test"} <= set(extras) and "python -m pytest" in ci  # CI adds "docs" to build the site
    assert "torch==2.13.0" in (ROOT / "constraints.txt").read_text()


def _python_block(marker: str) -> str:
    """The README's python code block that contains ``marker``."""
    return next(b for b in re.findall(r"```python\n(.*?)```", README, re.S) if marker in b)


def test_readme_python_api_block_runs(tmp_path, monkeypatch, capsys):
    """The 'From Python' block: a 5 mm drop test, a parameter change, a comparison, a table, files."""
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(_python_block("cfm.drop_test("), "README.md", "exec"), namespace)
    base, stiffer, df = namespace["base"], namespace["stiffer"], namespace["df"]
    assert abs(base.peak_g - 117.2) < 0.1  # the README's paper table, 5 mm, long-term moduli
    assert stiffer.peak_g > base.peak_g and stiffer.compare(base)["peak_diff"] > 0
    assert list(df.columns) == ["t [s]", "a_raw [m/s^2]", "a_cfc600 [m/s^2]", "a_cfc600 [g]"]
    assert abs(df["a_cfc600 [g]"].max() - base.peak_g) < 1e-9
    assert (tmp_path / "out" / "drop-5mm" / "summary.json").is_file()


def test_readme_material_example_runs(capsys):
    code = _python_block("register_material(")
    try:
        exec(compile(code, "README.md", "exec"), {})
        printed = capsys.readouterr().out
        assert "[[[" in printed
        from cfm_core import make_material
        from cfm_core.material import reference as ref

        sigma = ref.cauchy(make_material("my-mr", {"c10": 250.0}), np.diag([0.8, 1.1, 1.1]))[0]
        assert sigma[0, 0] < 0 and np.isfinite(sigma).all()
    finally:
        plugins.unregister("materials", "my-mr")
