"""The skfem backend prints the numba backend's notice while its kernels compile on a cold first
run (one helper, cfm_core.material.compile_notice, shared by both), and nothing once they are cached."""

import io
import sys

import pytest

from cfm_core.material import compile_notice
from cfm_core.runs.pipeline import run_model
from cfm_core.scene.builder import build_model
from cfm_core.scene.scene import builtin_scene


def _run_skfem(stream, monkeypatch):
    monkeypatch.setattr(sys, "stderr", stream)
    model = build_model(builtin_scene("single-element").with_overrides(stretch=0.9, rate=100.0))
    return run_model(model, "skfem", dt=2.5e-4)


def test_skfem_says_what_it_compiles_on_a_cold_cache_and_nothing_after(tmp_path, monkeypatch):
    pytest.importorskip("skfem")
    pytest.importorskip("numba")
    _run_skfem(io.StringIO(), monkeypatch)  # compiled (or loaded) in the real cache
    real = compile_notice.cache_dir
    with monkeypatch.context() as m:  # the notice looks at an empty cache folder: a cold machine
        m.setattr(compile_notice, "cache_dir", lambda *parts: tmp_path.joinpath(*parts))
        (tmp_path / "skfem").mkdir()
        cold = io.StringIO()
        _run_skfem(cold, monkeypatch)
    text = cold.getvalue()
    assert "numba: compiling kernels for material 'cfm' (once per machine" in text
    assert str(tmp_path / "skfem") in text and "compiled in" in text
    assert (tmp_path / "skfem" / compile_notice.TIMES).is_file()  # the next estimate
    assert compile_notice.cache_dir is real
    warm = io.StringIO()
    _run_skfem(warm, monkeypatch)
    assert "compiling kernels" not in warm.getvalue()


def test_numba_and_skfem_share_one_notice():
    pytest.importorskip("skfem")
    from cfm_backends.numba_explicit import codegen
    from cfm_backends.skfem_implicit import solver

    assert solver.announce_compile is compile_notice.announce_compile
    assert codegen.compile_notice is compile_notice


def test_a_second_process_compiling_the_same_module_waits_for_the_first(tmp_path, monkeypatch):
    """The compile lock (a file beside the module): whoever comes second enters after the first
    has left, then finds the kernels cached; a lock that cannot be taken does not stop a run."""
    import threading

    from cfm_core.material import compile_notice

    path = tmp_path / "module.lock"
    order = []

    def second():
        with compile_notice._compiling(path):
            order.append("second compiles")

    with compile_notice._compiling(path):
        worker = threading.Thread(target=second)
        worker.start()
        worker.join(timeout=0.5)
        assert worker.is_alive()           # waiting for the first
        order.append("first done")
    worker.join(timeout=10.0)
    assert order == ["first done", "second compiles"]
    import filelock

    class Unwritable(filelock.FileLock):        # a read-only cache folder: the lock file cannot be made
        def acquire(self, *args, **kwargs):
            raise PermissionError(13, "read-only", str(self.lock_file))

    monkeypatch.setattr(filelock, "FileLock", Unwritable)
    with compile_notice._compiling(path):
        order.append("ran unlocked")
    assert order[-1] == "ran unlocked"
