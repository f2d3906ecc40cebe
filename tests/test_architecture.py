"""The layout's rules, checked: imports go one way (import-linter contracts in pyproject.toml)."""

from pathlib import Path

from importlinter.cli import lint_imports

ROOT = Path(__file__).resolve().parents[1]


def test_import_contracts_hold():
    """cli > studies > runs > post > simulation > scene > material > base inside the core;
    verification > backends, plugins > core; no heavy library in the core (pyproject.toml)."""
    assert lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True) == 0


def test_the_contract_check_can_fail(tmp_path):
    """An inverted layer order (material above cli) must be reported as broken."""
    config = tmp_path / "inverted.toml"
    config.write_text('[tool.importlinter]\nroot_packages = ["cfm_core"]\n\n[[tool.importlinter.contracts]]\n'
                      'name = "inverted"\ntype = "layers"\nlayers = ["cfm_core.material", "cfm_core.cli"]\n')
    assert lint_imports(config_filename=str(config), no_cache=True) == 1
