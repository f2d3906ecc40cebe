"""cfm_backends.threads.num_threads: the count set for the block, the caller's restored after it."""

import sys
import types

import pytest

from cfm_backends import threads as T
from cfm_backends.threads import num_threads


class Lib:
    """Stands in for numba / torch: records the counts set."""

    def __init__(self, n):
        self.n, self.calls = n, []

    def get_num_threads(self):
        return self.n

    def set_num_threads(self, n):
        self.calls.append(n)
        self.n = n


@pytest.fixture
def machine(monkeypatch):
    """A fake machine: set ``cpus`` (allowed) and ``idle`` (idle cores measured, None: unreadable)."""
    state = types.SimpleNamespace(cpus=list(range(8)), idle=8.0, load=0.0)
    monkeypatch.setattr(T, "_last", None)
    monkeypatch.setattr(T, "allowed_cpus", lambda: state.cpus)
    monkeypatch.setattr(T, "idle_cores", lambda cpus, sample=T.SAMPLE_S, with_resolution=False: (
        state.idle if not with_resolution or state.idle is None else (state.idle, 0.0)))
    monkeypatch.setattr(T.os, "getloadavg", lambda: (state.load, state.load, state.load))
    return state


@pytest.mark.parametrize("threads, serial, inside", [(3, False, 3), (3, True, 3), (None, True, 1), (None, False, 8)])
def test_count_inside_and_restored_after(threads, serial, inside, machine):
    lib = Lib(8)
    with num_threads(lib, threads, serial=serial):
        assert lib.n == inside
    assert lib.n == 8


def test_restored_when_the_run_raises():
    lib = Lib(4)
    with pytest.raises(ZeroDivisionError):
        with num_threads(lib, 1):
            assert lib.n == 1
            1 / 0
    assert lib.n == 4


def test_numba_count_restored():
    numba = pytest.importorskip("numba")
    before = numba.get_num_threads()
    with num_threads(numba, 1):
        assert numba.get_num_threads() == 1
    assert numba.get_num_threads() == before


@pytest.mark.parametrize("cpus, idle, expect", [
    (8, 8.0, 8),      # idle machine: every allowed core
    (8, 6.95, 7),     # one core busy elsewhere
    (2, 1.02, 1),     # the 2-core case of issue 23: the other core is held by another process
    (2, 1.5, 1),      # a half-busy core is not free: a barrier would wait for it
    (2, 0.1, 1),      # everything busy: still one thread
    (4, None, 3),     # /proc/stat unreadable: the load average (1.0) instead
])
def test_default_count_is_the_free_cores(machine, cpus, idle, expect):
    machine.cpus, machine.idle, machine.load = list(range(cpus)), idle, 1.0
    assert T.free_cores() == expect
    lib = Lib(cpus)
    with num_threads(lib, None):
        assert lib.n == expect
    assert lib.n == cpus


def test_default_never_exceeds_the_librarys_threads(machine):
    lib = Lib(2)
    with num_threads(lib, None):
        assert lib.n == 2


def test_a_dask_workers_tasks_share_its_cores(machine, monkeypatch):
    """Inside a Dask worker running 4 tasks at once on 8 free cores, each run takes 2 threads."""
    worker = types.SimpleNamespace(state=types.SimpleNamespace(nthreads=4))
    fake = types.SimpleNamespace(get_worker=lambda: worker)
    monkeypatch.setitem(sys.modules, "distributed", fake)
    assert T.free_cores() == 2
    worker.state.nthreads = 16
    assert T.free_cores() == 1


def test_outside_a_dask_worker(machine, monkeypatch):
    def not_in_worker():
        raise ValueError("No worker found")
    monkeypatch.setitem(sys.modules, "distributed", types.SimpleNamespace(get_worker=not_in_worker))
    assert T.free_cores() == 8


def test_idle_cores_on_this_machine():
    cpus = T.allowed_cpus()
    idle = T.idle_cores(cpus, 0.02)
    assert idle is None or 0.0 <= idle <= len(cpus) + 1e-9


def test_numba_refuses_too_many_threads_before_loading_any_kernel(monkeypatch):
    """The count is chosen just before the time loop, but a count above the cores is refused before
    the kernels are loaded (a cold compile takes minutes)."""
    pytest.importorskip("numba")
    from dataclasses import replace

    from cfm_backends.numba_explicit import codegen, solver
    from cfm_core.errors import InputError
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene

    model = replace(build_model(builtin_scene("drop-test").with_overrides(element_size=0.004)), end_time=1e-5)

    def no_load(*args, **kwargs):
        raise AssertionError("kernels loaded before the thread count was checked")

    monkeypatch.setattr(codegen, "load", no_load)
    with pytest.raises(InputError, match="option threads = 4096 is more than the"):
        solver.run_model(model, threads=4096)


@pytest.mark.parametrize("idle_ticks, total_ticks, expect", [
    (6, 6, 2),      # idle
    (5, 6, 2),      # one tick of 6 busy: the resolution of the sample, not a busy core
    (4, 6, 1),      # two ticks: a core busy a third of the time or more is not free
    (3, 6, 1),      # the other core held by another process for the whole sample
    (17, 20, 1),    # a longer sample: 3 of 20 ticks (0.3 cores) is more than one tick and 15 %
    (19, 20, 2),
])
def test_one_tick_of_proc_stat_is_not_a_busy_core(monkeypatch, idle_ticks, total_ticks, expect):
    """On 2 cores, a 30 ms sample counts about 6 ticks of /proc/stat: one busy tick is within its
    resolution (3 % of the measurements on an idle machine), more is load."""
    monkeypatch.setattr(T, "_last", None)
    monkeypatch.setattr(T, "allowed_cpus", lambda: [0, 1])
    monkeypatch.setattr(T.time, "sleep", lambda s: None)
    monkeypatch.setattr(T, "_helper_ticks", lambda: 0.0)
    stat = iter([(100.0, 200.0), (100.0 + idle_ticks, 200.0 + total_ticks)])
    monkeypatch.setattr(T, "_cpu_times", lambda cpus: next(stat))
    assert T.free_cores() == expect


def test_idle_cores_with_its_resolution(monkeypatch):
    monkeypatch.setattr(T.time, "sleep", lambda s: None)
    monkeypatch.setattr(T, "_helper_ticks", lambda: 0.0)
    stat = iter([(0.0, 0.0), (5.0, 8.0)])
    monkeypatch.setattr(T, "_cpu_times", lambda cpus: next(stat))
    assert T.idle_cores([0, 1], with_resolution=True) == (1.25, 0.25)
