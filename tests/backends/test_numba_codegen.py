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


def _corner_loops(fn):
    import ast

    return [n for n in ast.walk(fn) if isinstance(n, ast.For) and getattr(n.target, "id", "") == "a"]


def test_corner_loops_are_unrolled_in_the_generated_module():
    import ast

    from cfm_backends.numba_explicit.kernels.element import UNROLLED_CORNERS

    tree = ast.parse(codegen.module_source(NeoHookeanStandIn()))
    fns = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}
    for name in UNROLLED_CORNERS:
        text = ast.unparse(fns[name])
        assert not _corner_loops(fns[name]) and "6 * 7 + " in text and "6 * 8" not in text
        assert "fastmath=FASTMATH_SUMS" in text
    assert _corner_loops(fns["gather_corners"])          # other functions are left as written


def test_unrolled_names_are_read_from_the_kernel_text():
    from cfm_backends.numba_explicit.kernels.element import UNROLLED_CORNERS

    text = (codegen.KERNELS_DIR / "element.py").read_text()
    assert codegen.unrolled_names(text) == UNROLLED_CORNERS
    with pytest.raises(ValueError, match="no top-level UNROLLED_CORNERS"):
        codegen.unrolled_names(text.replace("UNROLLED_CORNERS = (", "OTHER = ("))


def test_module_text_comes_from_the_cache_keyed_by_its_inputs(tmp_path, monkeypatch):
    """A second process reads the module text stored under a digest of the kernel files, the
    generator and the material's code (no corner unrolling at start-up); any change of those
    inputs is another key."""
    import shutil

    mat = NeoHookeanStandIn()
    monkeypatch.delenv("CFM_NO_CODEGEN_CACHE", raising=False)
    monkeypatch.setenv("CFM_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(codegen, "_SOURCES", {})
    fresh = codegen.source_of(mat)
    assert fresh == codegen.module_source(mat)

    def no_generation(material):
        raise AssertionError("the module text was generated again")

    monkeypatch.setattr(codegen, "_SOURCES", {})
    monkeypatch.setattr(codegen, "module_source", no_generation)
    assert codegen.source_of(mat) == fresh                 # read back, not rebuilt

    key = [(mat.name, mat.numba_source())]
    before = codegen._source_key(key)
    kernels = tmp_path / "kernels"
    shutil.copytree(codegen.KERNELS_DIR, kernels, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(codegen, "KERNELS_DIR", kernels)
    assert codegen._source_key(key) == before              # same text, same key
    (kernels / "contact.py").write_text((kernels / "contact.py").read_text() + "\n# an edit\n")
    edited = codegen._source_key(key)
    assert edited != before
    assert codegen._source_key([(mat.name, mat.numba_source() + "\n")]) not in (before, edited)


def test_unroll_corners_refuses_what_it_cannot_unroll():
    text = "def f(n):\n    s = 0.0\n    for a in range(4):\n        s += a\n    return s\n"
    with pytest.raises(ValueError, match="has no 'for a in range\\(8\\)' loop"):
        codegen.unroll_corners(text, ("f",))
    with pytest.raises(ValueError, match="no top-level function \\['g'\\]"):
        codegen.unroll_corners(text.replace("range(4)", "range(8)"), ("g",))
    out = codegen.unroll_corners(text.replace("range(4)", "range(8)"), ("f",))
    ns = {}
    exec(out, ns)
    assert ns["f"](0) == 28.0 and "for a" not in out


def test_unrolled_kinematics_are_the_loops_to_the_bit():
    """The generated (unrolled, vectorised) F and hourglass modes equal the kernel file's own loops
    bit for bit, and numpy's sums to round-off (F = sum_a x_a (x) B_a; q_alpha = sum_a h_alpha,a
    v_a - sum_k (h_alpha . X_k) L_:k, L = sum_a v_a (x) B_a)."""
    import numpy as np

    from cfm_backends.numba_explicit.kernels import element as loops
    from cfm_backends.numba_explicit.kernels import layout as K

    mod = codegen.load(NeoHookeanStandIn())
    rng = np.random.default_rng(7)
    n, nn = 29, 60                                  # a block not full: a remainder after the vector loop
    x = rng.normal(size=(nn, 3))
    v = rng.normal(size=(nn, 3))
    conn = rng.integers(0, nn, size=(n + 5, 8)).astype(np.int32)
    ed = rng.normal(size=K.ED_N * K.BLOCK)
    out = []
    for kin in (mod.kinematics_block, loops.kinematics_block):
        wk = np.full(K.W_N * K.BLOCK, np.nan)
        kin(wk, ed, x, v, conn, 5, n)
        out.append(wk.reshape(K.W_N, K.BLOCK)[:K.W_Q + 12, :n])
    assert np.array_equal(out[0], out[1])
    B = ed.reshape(K.ED_N, K.BLOCK)[K.ED_B:K.ED_B + 24, :n].T.reshape(n, 8, 3)
    HX = ed.reshape(K.ED_N, K.BLOCK)[K.ED_HX:K.ED_HX + 12, :n].T.reshape(n, 4, 3)
    xa, va = x[conn[5:5 + n]], v[conn[5:5 + n]]
    F = np.einsum("eai,eak->eik", xa, B)
    L = np.einsum("eai,eak->eik", va, B)
    H = np.array([K.H0, K.H1, K.H2, K.H3])
    q = np.einsum("ga,eai->egi", H, va) - np.einsum("egk,eik->egi", HX, L)
    assert np.allclose(out[0][:9].T, F.reshape(n, 9), rtol=0, atol=1e-13)
    assert np.allclose(out[0][9:21].T, q.reshape(n, 12), rtol=0, atol=1e-12)
