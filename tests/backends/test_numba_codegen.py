"""Generated, cached kernel modules of the numba backend (one file per material source)."""

import os
import time

import pytest

pytest.importorskip("numba")
from cfm_backends.numba_explicit import codegen
from fixtures.hand_derived import NeoHookeanStandIn
from cfm_core.errors import InputError


def test_module_source_layout():
    text = codegen.module_source(NeoHookeanStandIn())
    assert ">>> standalone" not in text and "<<< standalone" not in text
    for name in ("psi_grad", "psi_hess_diag", "psi_energy", "psi_grad_hess_diag"):
        assert f"\n{name} = njit(cache=True, fastmath=False" in text
    for kernel in ("def eig3(", "def stress_block(", "def element_pass(", "def sphere_contact(",
                   "def advance(", "def point_history("):
        assert text.count(kernel) == 1
    compile(text, "generated", "exec")


def test_load_is_cached_and_keyed_by_content():
    a = codegen.load(NeoHookeanStandIn(1e3, 1e4))
    b = codegen.load(NeoHookeanStandIn(5e3, 2e4))      # same source, other parameters
    assert a is b and os.path.dirname(a.__file__) == str(codegen.cache_dir())


def test_missing_functions_are_an_input_error():
    class Broken(NeoHookeanStandIn):
        def numba_source(self):
            return "import math\n\ndef psi_grad(m1, m2, m3, p):\n    return (0.0,) * 6\n"

    with pytest.raises(InputError, match="psi_hess_diag"):
        codegen.module_source(Broken())


def test_prune_keeps_the_newest(tmp_path):
    (tmp_path / "__pycache__").mkdir()
    files = []
    for i in range(10):
        f = tmp_path / f"cfm_numba_x_{i:02d}.py"
        f.write_text("")
        (tmp_path / "__pycache__" / f"cfm_numba_x_{i:02d}.advance-1.py311.nbi").write_text("")
        os.utime(f, (time.time() + i, time.time() + i))
        files.append(f)
    (tmp_path / "cfm_numba_other_00.py").write_text("")
    codegen._prune(tmp_path, "cfm_numba_x_", keep=files[0], n_keep=3)
    left = sorted(p.name for p in tmp_path.glob("*.py"))
    assert left == ["cfm_numba_other_00.py", "cfm_numba_x_00.py", "cfm_numba_x_08.py", "cfm_numba_x_09.py"]
    assert len(list((tmp_path / "__pycache__").iterdir())) == 3


def test_cold_first_run_says_what_it_compiles(tmp_path, monkeypatch):
    """An empty kernel cache: one line before (material, once per machine, an estimate, the folder)
    and one after (seconds); once numba's cache index exists, nothing."""
    import io

    from cfm_core.material.registry import make_material

    monkeypatch.setenv("CFM_CACHE_DIR", str(tmp_path))
    material = make_material("cfm")
    out = io.StringIO()
    with codegen.announce(material, stream=out):
        pass
    text = out.getvalue()
    assert "compiling kernels for material 'cfm'" in text and "once per machine" in text
    assert str(tmp_path) in text and "compiled in" in text
    assert (tmp_path / "numba" / "compile_seconds.json").is_file()
    folder = tmp_path / "numba" / "__pycache__"
    folder.mkdir(parents=True)
    (folder / f"{codegen._module_name(material)}.advance-1.py311.nbi").write_text("")
    quiet = io.StringIO()
    with codegen.announce(material, stream=quiet):
        pass
    assert quiet.getvalue() == ""
