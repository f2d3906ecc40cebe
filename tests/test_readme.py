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
    assert '-c constraints.txt -e ".[all,test]"' in ci and "python -m pytest" in ci
    assert "torch==2.13.0" in (ROOT / "constraints.txt").read_text()


def test_readme_material_example_runs(capsys):
    code = re.search(r"```python\n(.*?)```", README, re.S).group(1)
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
