"""A Dask run whose last worker is gone stops within a bounded, configurable time (shared case
dask-last-worker-lost): the tasks left end with an error saying so, runs done are kept, and the
sweep writes its table so that a rerun resumes. A fake client stands for the scheduler, so the
timing is exact and no processes are started."""

import time

import pytest

from cfm_core.errors import InputError
from cfm_core.studies import dask_runner
from cfm_core.studies.dask_runner import DaskRunner, open_runner

distributed = pytest.importorskip("distributed")


class FakeFuture:
    def __init__(self, key, value=None):
        self.key, self.status, self._value = key, "pending", value

    def result(self):
        return True, self._value

    def release(self):
        pass


class FakeClient:
    """workers: callable(elapsed s) -> number of workers; finish_at: elapsed s when the tasks finish."""

    def __init__(self, workers, finish_at=None, unreachable=False):
        self.workers, self.finish_at, self.unreachable = workers, finish_at, unreachable
        self.t0 = time.monotonic()
        self.cancelled = []

    def map(self, fn, items, pure=False):
        self.futures = [FakeFuture(i, ("done", x)) for i, x in enumerate(items)]
        return self.futures

    def nthreads(self):
        if self.unreachable:
            raise OSError("scheduler gone")
        return {f"w{i}": 1 for i in range(self.workers(time.monotonic() - self.t0))}

    def cancel(self, futures):
        self.cancelled += list(futures)


class FakeAsCompleted:
    """distributed.as_completed over the fake futures: they finish when the client says so."""

    def __init__(self, futures):
        self.futures, self.left = list(futures), list(futures)

    def is_empty(self):
        return not self.left

    def next_batch(self, block=True):
        client = CLIENT[0]
        if client.finish_at is not None and time.monotonic() - client.t0 >= client.finish_at:
            batch, self.left = self.left, []
            for f in batch:
                f.status = "finished"
            return batch
        return []


CLIENT = []


@pytest.fixture
def fake(monkeypatch):
    monkeypatch.setattr(distributed, "as_completed", FakeAsCompleted)
    monkeypatch.setattr(dask_runner, "POLL", 0.01)

    def make(**kw):
        CLIENT[:] = [FakeClient(**kw)]
        return CLIENT[0]

    return make


@pytest.mark.parametrize("kw", [{"workers": lambda t: 0}, {"workers": lambda t: 1, "unreachable": True}])
def test_no_worker_left_ends_the_remaining_tasks_within_the_timeout(fake, kw):
    client = fake(**kw)
    runner = DaskRunner(client, "fake", worker_timeout=0.3)
    start = time.monotonic()
    done = list(runner.map(lambda x: x, [1, 2, 3]))
    elapsed = time.monotonic() - start
    assert 0.3 <= elapsed < 2.0
    assert sorted(d.index for d in done) == [0, 1, 2]
    assert all(d.error.startswith("WorkersLost:") and "rerun the same command to resume" in d.error for d in done)
    assert {f.key for f in client.cancelled} == {0, 1, 2}


def test_slow_tasks_with_a_worker_are_waited_for(fake):
    client = fake(workers=lambda t: 1, finish_at=0.5)
    done = list(DaskRunner(client, "fake", worker_timeout=0.1).map(lambda x: x, [1, 2]))
    assert [d.ok for d in done] == [True, True] and [d.value for d in done] == [("done", 1), ("done", 2)]


def test_a_stuck_worker_is_said_while_the_map_waits(fake, monkeypatch, capsys):
    """A worker suspended with kill -STOP stays registered: the sweep waited 400 s without a word."""
    monkeypatch.setattr(dask_runner, "STALL_NOTE", 0.2)
    client = fake(workers=lambda t: 1, finish_at=0.5)
    done = list(DaskRunner(client, "fake scheduler", worker_timeout=0.1).map(lambda x: x, [1, 2]))
    assert [d.ok for d in done] == [True, True]
    err = capsys.readouterr().err
    assert err.count("note: no run has finished for") == 2 and "on fake scheduler (2 left)" in err
    client = fake(workers=lambda t: 1, finish_at=0.1)
    list(DaskRunner(client, "fake", worker_timeout=0.1).map(lambda x: x, [1]))
    assert "no run has finished" not in capsys.readouterr().err


def test_a_worker_restarted_within_the_timeout_does_not_stop_the_run(fake):
    client = fake(workers=lambda t: 0 if 0.1 < t < 0.3 else 1, finish_at=0.6)  # a nanny restarts it
    done = list(DaskRunner(client, "fake", worker_timeout=0.5).map(lambda x: x, [1]))
    assert done[0].ok


def test_the_timeout_is_checked():
    with pytest.raises(InputError, match="--worker-timeout"):
        with open_runner(None, 1, worker_timeout=-1.0):
            pass


def test_sweep_keeps_finished_runs_and_resumes_after_the_workers_are_lost(tmp_path):
    pytest.importorskip("numba")
    from cfm_core.scene.scene import builtin_scene
    from cfm_core.studies import sweep
    from cfm_core.studies.dask_runner import Done, SerialRunner

    scene = builtin_scene("drop-test").with_overrides(element_size=0.0025, width=0.03)
    axes = sweep.parse_vary(["thickness=0.005,0.008"], scene)

    class LosesItsLastWorker:  # the first run finishes, then no worker is left
        label, workers = "fake", 1

        def map(self, fn, items):
            items = list(items)
            yield Done(0, fn(items[0]))
            yield Done(1, error="WorkersLost: the Dask scheduler has had no worker for 30 s")

    first = sweep.run_sweep(scene, axes, tmp_path, "numba", LosesItsLastWorker())
    assert first.failed == 1 and (tmp_path / "sweep.csv").is_file()
    rows = sweep.read_table(tmp_path / "sweep.csv")
    assert [r["status"] for r in rows] == ["ok", "failed"] and "WorkersLost" in rows[1]["error"]
    again = sweep.run_sweep(scene, axes, tmp_path, "numba", SerialRunner())
    assert again.skipped == 1 and again.executed == 1 and again.failed == 0


def test_a_lost_scheduler_names_itself_instead_of_nonetype(fake):
    """The scheduler killed mid-sweep: the client cancels every task left, without an exception. Before,
    each run's error read "NoneType: None"; now it says the scheduler was lost and how to resume."""
    client = fake(workers=lambda t: 1, finish_at=0.0)

    class Lost(FakeAsCompleted):
        def next_batch(self, block=True):
            batch, self.left = self.left, []
            for f in batch:
                f.status = "cancelled"
                f.exception = lambda: None
            return batch

    distributed.as_completed = Lost  # restored by the fixture's monkeypatch
    done = list(DaskRunner(client, "Dask scheduler tcp://h:1", worker_timeout=1.0).map(lambda x: x, [1, 2]))
    assert [d.ok for d in done] == [False, False]
    for d in done:
        assert d.error.startswith("SchedulerLost: the connection to the Dask scheduler tcp://h:1 was lost")
        assert "rerun the same command to resume" in d.error and "NoneType" not in d.error


def test_dask_log_records_stay_off_the_terminal_while_a_runner_is_open():
    """distributed's client logs a traceback (ERROR) when it cannot reconnect to a lost scheduler; the
    failed runs already say what happened, so its loggers are quiet while a runner is open, and their
    levels come back afterwards."""
    import logging

    before = {name: logging.getLogger(name).level for name in dask_runner.DISTRIBUTED_LOGGERS}
    assert logging.getLogger("distributed.client").isEnabledFor(logging.ERROR)   # distributed's own config
    with dask_runner.quiet_distributed():
        for name in ("distributed.client", "distributed", "distributed.comm"):
            assert not logging.getLogger(name).isEnabledFor(logging.CRITICAL)
    assert {name: logging.getLogger(name).level for name in dask_runner.DISTRIBUTED_LOGGERS} == before
    assert logging.getLogger("distributed.client").isEnabledFor(logging.ERROR)


def test_a_local_cluster_worker_ends_quietly_on_sigint():
    """Ctrl-C on a local-cluster sweep printed two tracebacks per worker process (CancelledError,
    KeyboardInterrupt) before "interrupted; no result written"; the workers' preload ends them quietly."""
    import subprocess
    import sys

    code = ("import os, signal, time; from cfm_core.studies.dask_preload import dask_setup; dask_setup(None); "
            "os.kill(os.getpid(), signal.SIGINT); time.sleep(30)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 130 and proc.stderr == ""
