"""numba's machine code is keyed by content: an edit of a kernel module that another imports
recompiles the importer, and the generated modules change name with any kernel file.

numba's own ``cache=True`` keys a function on its file and bytecode only: ``b.g`` calling ``a.f``
kept ``a.f``'s old machine code inlined after ``a.py`` changed (checked: 6.0 instead of 8.0 with
the in-tree ``__pycache__``), which is how the kernel files imported on their own were cached.
"""

import shutil
import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("numba")

from cfm_backends import numba_cache  # noqa: E402

A = textwrap.dedent("""
    from numba import njit
    from cfm_backends.numba_cache import key_on_folder

    key_on_folder(__file__)


    @njit(cache=True)
    def f(x):
        return x + 1.0
""")
B = textwrap.dedent("""
    from numba import njit
    from cfm_backends.numba_cache import key_on_folder

    from .a import f

    key_on_folder(__file__)


    @njit(cache=True)
    def g(x):
        return f(x) * 2.0
""")


def _g_of_one(root, cache) -> tuple[float, int, int]:
    """(g(1.0), cache hits, cache misses) in a fresh process."""
    code = ("import kernelpair.b as b\nv = b.g(1.0)\ns = b.g.stats\n"
            "print(v, sum(s.cache_hits.values()), sum(s.cache_misses.values()))")
    env = {"PYTHONPATH": str(root), "CFM_CACHE_DIR": str(cache), "PATH": "/usr/bin:/bin",
           "HOME": str(root), "NUMBA_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=root)
    assert out.returncode == 0, out.stderr
    value, hits, misses = out.stdout.split()
    return float(value), int(hits), int(misses)


def test_an_edit_of_an_imported_kernel_module_recompiles_its_importer(tmp_path):
    pkg = tmp_path / "kernelpair"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text(A)
    (pkg / "b.py").write_text(B)
    cache = tmp_path / "cache"
    assert _g_of_one(tmp_path, cache) == (4.0, 0, 1)          # compiled
    assert _g_of_one(tmp_path, cache) == (4.0, 1, 0)          # loaded from the cache
    (pkg / "a.py").write_text(A.replace("x + 1.0", "x + 3.0"))  # b.py unchanged
    assert _g_of_one(tmp_path, cache) == (8.0, 0, 1)          # recompiled, not the stale 4.0
    folders = list((cache / "numba-kernels").iterdir())
    assert len(folders) == 1 and len(list(folders[0].iterdir())) == 2  # one per content digest


def test_older_digest_folders_are_pruned(tmp_path):
    import os

    for i in range(6):
        (tmp_path / f"d{i}").mkdir()
        os.utime(tmp_path / f"d{i}", (1e9 + i, 1e9 + i))
    numba_cache._prune(tmp_path, keep=tmp_path / "d0")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d0", "d4", "d5"][:numba_cache.KEEP]


def test_the_folder_digest_covers_every_file_and_the_compiler_versions(tmp_path, monkeypatch):
    (tmp_path / "a.py").write_text(A)
    (tmp_path / "b.py").write_text(B)
    first = numba_cache.folder_digest(tmp_path)
    (tmp_path / "b.py").write_text(B + "\n")
    second = numba_cache.folder_digest(tmp_path)
    assert second != first
    import importlib.metadata as md

    real = md.version
    monkeypatch.setattr(md, "version", lambda d: "0.0" if d == "numba" else real(d))
    assert numba_cache.folder_digest(tmp_path) != second


def test_the_package_kernels_are_keyed_on_their_folder():
    from cfm_backends.numba_explicit.kernels import eigen

    folder = str(numba_cache.Path(eigen.__file__).resolve().parent)
    assert numba_cache._FOLDERS[folder] == numba_cache.folder_digest(folder)
    assert eigen.eig3.stats.cache_path == str(numba_cache.cache_path(folder, numba_cache._FOLDERS[folder]))


def _copy_kernels(src, dst):
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns("__pycache__"))
    return dst


def test_generated_module_names_change_with_any_kernel_file(tmp_path, monkeypatch):
    """eigen.py is imported by element.py: the generated numba module (which holds every kernel's
    text) gets another name, so numba compiles it anew; the same for the skfem module."""
    from cfm_backends.numba_explicit import codegen
    from cfm_backends.skfem_implicit import compiled
    from fixtures.hand_derived import NeoHookeanStandIn

    material = NeoHookeanStandIn()
    name = codegen._module_name(material)
    folder = _copy_kernels(codegen.KERNELS_DIR, tmp_path / "kernels")
    monkeypatch.setattr(codegen, "KERNELS_DIR", folder)
    monkeypatch.setattr(codegen, "_SOURCES", {})
    assert codegen._module_name(material) == name                # a copy: the same content
    (folder / "eigen.py").write_text((folder / "eigen.py").read_text().replace("def eig3(", "def eig3(  ", 1))
    monkeypatch.setattr(codegen, "_SOURCES", {})
    assert codegen._module_name(material) != name

    from cfm_core.material.registry import make_material

    neo = make_material("neo-hookean")
    skfem_name = codegen.generated_name(compiled.module_source(neo), "cfm_skfem", "m")
    kernels = tmp_path / "kernels.py"
    kernels.write_text(compiled.KERNELS_FILE.read_text() + "\n# an edit\n")
    monkeypatch.setattr(compiled, "KERNELS_FILE", kernels)
    assert codegen.generated_name(compiled.module_source(neo), "cfm_skfem", "m") != skfem_name


def test_the_generated_time_loop_is_in_the_disk_cache_after_a_run():
    """A kernel numba cannot cache (a ctypes pointer or another dynamic global anywhere in the
    time loop's call tree, e.g. numba's own Python-level set_parallel_chunksize) would only warn
    and recompile the whole loop in every process (30-60 s a run): after a run, the time loop
    and the element pass it calls must have machine code in the disk cache."""
    from cfm_backends.numba_explicit import NumbaExplicitBackend, codegen
    from fixtures.hand_derived import NeoHookeanStandIn, drop_test_model

    mat = NeoHookeanStandIn(mu=50.0e3, kappa=1.0e6)
    model = drop_test_model(mat, quarter=True, width=12e-3, thickness=4e-3, h=2e-3, mass=0.05,
                            velocity=1.0, end_time=0.2e-3)
    NumbaExplicitBackend().run(model)
    assert codegen.is_compiled(mat, "advance")
    assert codegen.is_compiled(mat, "element_pass")
