"""Run many independent tasks (drop tests): serially, on a local Dask cluster, or on a scheduler.

:func:`open_runner` is what ``cfm sweep`` and ``cfm calibrate`` use:

- ``scheduler=None``: a local Dask cluster of ``workers`` processes (default: this machine's
  cores), one thread each, started for the command and closed after it. The workers get
  ``NUMBA_NUM_THREADS=1`` (and OMP/BLAS threads 1) before numba starts, so that N workers on N
  cores do not each start N threads;
- ``scheduler="tcp://host:8786"`` (any Dask address): connect to a running scheduler, so the same
  command runs on a cluster. The workers there need cfm-materials installed; start them with
  one thread each (``dask worker tcp://host:8786 --nthreads 1``) and ``NUMBA_NUM_THREADS`` set to
  the cores per worker;
- ``scheduler="none"`` (or ``"serial"``): a plain loop in this process, no Dask needed.

``runner.map(fn, items)`` yields one :class:`Done` per item as soon as it finishes (in completion
order): its index, fn's return value, or the error text when fn raised (or its worker died). One
failure never stops the others. Dask is imported only when a Dask runner is opened.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import sys
import time
from dataclasses import dataclass
from typing import Callable, Iterable, Iterator

from ..errors import InputError
from ..tables import check_count

#: Values of --scheduler that mean "no Dask, a loop in this process".
SERIAL = ("none", "serial")
#: Environment of the local cluster's worker processes: one thread per worker process.
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
              "MKL_NUM_THREADS": "1"}
#: Seconds to wait for the scheduler's first worker before giving up.
WORKER_WAIT = 60.0
#: Seconds a running map waits without any worker before it gives up on the tasks left (the last
#: worker died or was stopped; a nanny restarts a killed worker within a few seconds).
WORKER_LOST = 30.0
#: Longest --worker-timeout (s), about 11.6 days.
WORKER_TIMEOUT_MAX = 1e6
#: Seconds between two looks at the scheduler's workers while no task finishes.
POLL = 0.25
#: Seconds without a finished task, workers present, after which (and again after each as many) a
#: running map says so on stderr: a suspended or deadlocked worker stays registered, and the study
#: waited without a word (the scheduler drops a silent worker only after its worker-ttl, 5 minutes
#: by default, and an external scheduler may never).
STALL_NOTE = 300.0


@dataclass(frozen=True)
class Done:
    """One finished task: ``index`` into the submitted items, ``value`` (fn's return value) or
    ``error`` ("ExceptionType: message") when it failed."""

    index: int
    value: object = None
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.error is None


def error_text(exc: BaseException) -> str:
    """One line naming the exception type and its message."""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _guarded(fn: Callable, item):
    """(True, fn(item)) or (False, error text): a task's failure travels as a value, so the
    worker does not log it as a crash and the text is the same as in a serial run."""
    try:
        return True, fn(item)
    except Exception as exc:
        return False, error_text(exc)


class SerialRunner:
    """Tasks one after another in this process (the reference the Dask runs are compared with)."""

    label = "serial (this process)"
    workers = 1
    in_process = True  # tasks run here: their arguments need not be picklable

    def map(self, fn: Callable, items: Iterable) -> Iterator[Done]:
        for i, item in enumerate(items):
            ok, value = _guarded(fn, item)  # KeyboardInterrupt still stops the loop
            yield Done(i, value) if ok else Done(i, error=value)


#: The part of a lost cluster's error text after its reason (:func:`lost_reason`).
NOT_DONE = ", so this run was not done"


def lost_reason(error: str) -> str | None:
    """The reason, without the advice to resume, when a run's error text says the Dask cluster was lost
    (no worker left, or the scheduler gone: the run was not done); None for any other error. A study
    that keeps no partial results (a calibration) gives its own advice."""
    if error.startswith(("WorkersLost:", "SchedulerLost:")) and NOT_DONE in error:
        return error.split(NOT_DONE, 1)[0]
    return None


class DaskRunner:
    """Tasks on a Dask client; ``cluster`` is the local cluster this runner owns (or None).

    worker_timeout (s): how long :meth:`map` waits while the scheduler has no worker (or cannot be
    reached) before it ends every task left with an error saying so (default :data:`WORKER_LOST`).
    """

    in_process = False  # tasks are pickled and sent to the workers

    def __init__(self, client, label: str, cluster=None, worker_timeout: float = WORKER_LOST):
        self.client, self.label, self.cluster = client, label, cluster
        self.worker_timeout = float(worker_timeout)

    @property
    def workers(self) -> int:
        """Number of task slots (worker threads) the scheduler has now."""
        return max(1, sum(self.client.nthreads().values()))

    def map(self, fn: Callable, items: Iterable) -> Iterator[Done]:
        from distributed import as_completed

        items = list(items)
        futures = self.client.map(functools.partial(_guarded, fn), items, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        pending = set(index)
        ac = as_completed(futures)
        lost_since = None
        progress = noted = time.monotonic()
        try:
            while not ac.is_empty():
                batch = ac.next_batch(block=False)
                if not batch:  # nothing finished: is any worker left to do the rest?
                    now = time.monotonic()
                    if self._has_workers():
                        lost_since = None
                        if now - noted >= STALL_NOTE:
                            noted = now
                            print(f"note: no run has finished for {now - progress:.0f} s on {self.label} "
                                  f"({len(pending)} left) although it has workers: a worker may be stuck "
                                  f"(suspended, swapping or deadlocked); check the cluster (its dashboard). Ctrl-C "
                                  f"stops the study; a sweep's rerun keeps the runs finished so far.",
                                  file=sys.stderr, flush=True)
                    elif lost_since is None:
                        lost_since = now
                    elif now - lost_since >= self.worker_timeout:
                        text = (f"WorkersLost: the Dask scheduler has had no worker for {self.worker_timeout:g} s "
                                f"(the last one died or was stopped){NOT_DONE}; runs finished "
                                f"so far are kept: start workers and rerun the same command to resume.")
                        for fut in futures:
                            if fut.key in pending:
                                pending.discard(fut.key)
                                yield Done(index[fut.key], error=text)
                        break
                    time.sleep(POLL)
                    continue
                lost_since = None
                progress = noted = time.monotonic()
                for fut in batch:
                    pending.discard(fut.key)
                    i = index[fut.key]
                    if fut.status == "finished":
                        ok, value = fut.result()
                        yield Done(i, value) if ok else Done(i, error=value)
                    else:  # the worker died, the task could not be sent, or the scheduler is gone
                        yield Done(i, error=self._failure_text(fut))
                    fut.release()
        finally:  # the consumer stopped early (error, Ctrl-C) or no worker is left: do not leave work queued
            left = [f for f in futures if f.key in pending or f.status not in ("finished", "error", "cancelled")]
            if left:
                with contextlib.suppress(Exception):
                    self.client.cancel(left)

    def _failure_text(self, fut) -> str:
        """The error of a task that did not finish: its exception (a worker that died, a task that
        could not be sent), or, for a task the client cancelled without one because the scheduler
        stopped answering (it was stopped, or the network failed), a text that says so."""
        exc = None
        if fut.status == "error":
            with contextlib.suppress(Exception):
                exc = fut.exception()
        if exc is not None:
            return error_text(exc)
        return (f"SchedulerLost: the connection to the {self.label} was lost before this run "
                f"finished (task {fut.status}){NOT_DONE}; runs finished so far are kept: restart the "
                f"scheduler and its workers and rerun the same command to resume.")

    def _has_workers(self) -> bool:
        """True when the scheduler reports at least one worker (False when it cannot be asked)."""
        try:
            return bool(self.client.nthreads())
        except Exception:  # scheduler gone or not answering: counts as no worker
            return False

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def _import_distributed():
    try:
        import distributed
    except ImportError:
        raise InputError("Dask is not installed, so --scheduler cannot be used: install it with "
                         "pip install 'cfm-materials[dask]' (dask[distributed]), or run serially with "
                         "--serial.") from None
    return distributed


def local_cluster(workers: int, worker_timeout: float = WORKER_LOST) -> DaskRunner:
    """A :class:`DaskRunner` on a new local cluster of ``workers`` one-thread processes."""
    distributed = _import_distributed()
    cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       env=dict(WORKER_ENV), dashboard_address=":0",
                                       silence_logs=logging.ERROR,
                                       preload=["cfm_core.studies.dask_preload"])  # Ctrl-C: no worker tracebacks
    try:
        client = distributed.Client(cluster)
    except BaseException:
        cluster.close()
        raise
    return DaskRunner(client, f"local Dask cluster, {workers} worker process(es) x 1 thread", cluster,
                      worker_timeout=worker_timeout)


#: Seconds a tcp:// address has to send the first bytes of a Dask handshake (a scheduler sends its
#: own as soon as it accepts a connection).
HANDSHAKE_WAIT = 10.0
#: Largest first message (bytes) a scheduler's handshake can announce: its 8-byte length prefix.
HANDSHAKE_BYTES = 2**26


#: The port a Dask scheduler listens on by default (its dashboard serves http on 8787).
SCHEDULER_PORT = 8786


def check_scheduler_address(address: str) -> None:
    """Refuse a web address (http:// or https://) as the scheduler's, saying which address to give.

    A scheduler's dashboard (``http://host:8787/status``) is what a browser shows, and the address
    users copy; Dask's client refused it with "unknown address scheme 'http'", and the advice then
    was ``dask worker http://...``, which no worker can connect to: workers and clients both take
    the scheduler's own address, ``tcp://host:8786`` by default.

    Parameters
    ----------
    address : str
        The ``--scheduler`` value.

    Raises
    ------
    InputError
        ``address`` is an http:// or https:// address; the message gives the tcp:// address on the
        same host at :data:`SCHEDULER_PORT` and the matching ``dask worker`` command.
    """
    from urllib.parse import urlsplit

    parts = urlsplit(address.strip())
    if parts.scheme.lower() not in ("http", "https"):
        return
    host = parts.hostname or "localhost"
    tcp = f"tcp://{f'[{host}]' if ':' in host else host}:{SCHEDULER_PORT}"
    raise InputError(f"--scheduler {address} is a web address, such as the scheduler's dashboard (port 8787 by "
                     f"default), not the scheduler's own: give its tcp:// address, {tcp} for the default port (the "
                     f"scheduler's log says 'Scheduler at: tcp://...'). Workers connect to that address too: "
                     f"'dask worker {tcp} --nthreads 1'.")


def check_speaks_dask(address: str, timeout: float = HANDSHAKE_WAIT) -> None:
    """Check that whatever listens at a tcp:// ``address`` answers as a Dask scheduler does.

    A Dask scheduler writes its handshake, a message whose first 8 bytes are its length, as soon
    as it accepts a connection. Another server at that port (the scheduler's dashboard, 8787 by
    default, or any HTTP server) sends nothing and waits for a request: Dask's client then waited
    for ever, and garbage read as a length asked numpy for 3 EiB. Other schemes (tls://, inproc://)
    and unreachable addresses are left to Dask's own connection, which names them.

    Raises
    ------
    InputError
        Something accepts connections at ``address`` but sends no handshake within ``timeout``
        seconds, or a first message no Dask handshake has.
    """
    import socket
    import struct
    from urllib.parse import urlsplit

    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    if parts.scheme != "tcp" or not parts.hostname or parts.port is None:
        return
    try:
        sock = socket.create_connection((parts.hostname, parts.port), timeout=timeout)
    except OSError:
        return  # refused or unreachable: Dask's connection says so
    hint = ("If it is the scheduler's dashboard (port 8787 by default), give the scheduler's own port, 8786 by "
            "default: its log says 'Scheduler at: tcp://...'.")
    with sock:
        sock.settimeout(timeout)
        head = b""
        try:
            while len(head) < 8:
                chunk = sock.recv(8 - len(head))
                if not chunk:
                    break
                head += chunk
        except OSError:
            pass
    if len(head) < 8:
        raise InputError(f"--scheduler {address}: a server accepts connections there but did not answer as a "
                         f"Dask scheduler within {timeout:g} s (a scheduler greets every new connection). {hint}")
    (length,) = struct.unpack("<Q", head)
    if not 0 < length <= HANDSHAKE_BYTES:
        raise InputError(f"--scheduler {address}: the server there answered, but not as a Dask scheduler (its "
                         f"first message announces {length} bytes). {hint}")


def connect(address: str, timeout: float = 30.0, worker_timeout: float = WORKER_LOST) -> DaskRunner:
    """A :class:`DaskRunner` on the Dask scheduler at ``address`` (e.g. tcp://host:8786); a server
    there that does not speak Dask's protocol is an InputError (:func:`check_speaks_dask`)."""
    distributed = _import_distributed()
    check_scheduler_address(address)
    check_speaks_dask(address)
    try:
        client = distributed.Client(address, timeout=f"{timeout}s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(f"--scheduler {address}: cannot connect to a Dask scheduler there "
                         f"({error_text(exc)}). Start one with 'dask scheduler' and workers with "
                         f"'dask worker {address} --nthreads 1', or leave --scheduler out to use a "
                         f"local cluster.") from None
    try:
        client.wait_for_workers(1, timeout=WORKER_WAIT)
    except (TimeoutError, OSError):
        client.close()
        raise InputError(f"--scheduler {address}: the scheduler has had no worker for "
                         f"{WORKER_WAIT:g} s; start some with 'dask worker {address} --nthreads 1'.") from None
    runner = DaskRunner(client, f"Dask scheduler {address}", worker_timeout=worker_timeout)
    runner.label += f" ({runner.workers} worker thread(s))"
    return runner


#: Most local Dask workers per core of this machine (:func:`max_local_workers`).
WORKERS_PER_CORE = 4


def max_local_workers() -> int:
    """The most worker processes a local cluster may have: :data:`WORKERS_PER_CORE` per core of
    this machine (each is a Python process with numba loaded; more than the cores only share them)."""
    return WORKERS_PER_CORE * (os.cpu_count() or 1)


def check_runner_options(scheduler: str | None = None, workers: int | None = None,
                         worker_timeout: float | None = None) -> float:
    """Check the options of :func:`open_runner` before any work (the commands call it first).

    Parameters
    ----------
    scheduler, workers, worker_timeout
        As for :func:`open_runner`.

    Returns
    -------
    float
        The worker timeout (s), :data:`WORKER_LOST` when None.

    Raises
    ------
    InputError
        ``workers`` not a whole number from 1 to :func:`max_local_workers`, or given with a serial
        run or a scheduler; ``worker_timeout`` not a number of seconds in (0, 1e6); a web address as
        the scheduler (:func:`check_scheduler_address`).
    """
    if worker_timeout is None:
        worker_timeout = WORKER_LOST
    elif isinstance(worker_timeout, bool) or not (0.0 < float(worker_timeout) < WORKER_TIMEOUT_MAX):
        raise InputError(f"--worker-timeout {worker_timeout!r} s is not allowed: give a number of seconds > 0 and "
                         f"below {WORKER_TIMEOUT_MAX:g} (how long a sweep waits with no Dask worker left before it "
                         f"stops).")
    if scheduler is not None:
        check_scheduler_address(scheduler)
    if workers is not None:
        cores = os.cpu_count() or 1
        check_count("--workers", workers, 1, max_local_workers(),
                    f"worker processes of the local Dask cluster: at most {WORKERS_PER_CORE} per core of this "
                    f"machine's {cores} core{'s' if cores != 1 else ''}")
    if scheduler is not None and scheduler.strip().lower() in SERIAL:
        if workers not in (None, 1):
            raise InputError(f"--workers {workers} has no effect with a serial run; leave it out "
                             f"or drop --serial / --scheduler none.")
    elif scheduler is not None and workers is not None:
        raise InputError(f"--workers {workers} sets the size of the local cluster and has no effect "
                         f"with --scheduler {scheduler}: the scheduler's workers are used. Leave one "
                         f"of them out.")
    return float(worker_timeout)


@contextlib.contextmanager
def open_runner(scheduler: str | None = None, workers: int | None = None, worker_timeout: float | None = None):
    """Context manager yielding a runner (see the module docstring); closes what it started.

    Parameters
    ----------
    scheduler : str, optional
        None (local cluster), "none"/"serial" (this process) or a Dask address.
    workers : int, optional
        Processes of the local cluster, 1 to :func:`max_local_workers` (default ``os.cpu_count()``);
        only with scheduler=None.
    worker_timeout : float, optional
        Seconds a Dask run waits with no worker left before the tasks left fail with a message
        (default :data:`WORKER_LOST`, 30 s).

    Yields
    ------
    SerialRunner or DaskRunner
        Its ``map(fn, items)`` yields :class:`Done` per item.

    Raises
    ------
    InputError
        Bad workers or worker_timeout (:func:`check_runner_options`), Dask missing, scheduler
        unreachable or without workers.
    """
    worker_timeout = check_runner_options(scheduler, workers, worker_timeout)
    if scheduler is not None and scheduler.strip().lower() in SERIAL:
        yield SerialRunner()
        return
    with quiet_distributed():
        runner = (local_cluster(workers or os.cpu_count() or 1, worker_timeout) if scheduler is None
                  else connect(scheduler, worker_timeout=worker_timeout))
        try:
            yield runner
        finally:
            runner.close()


#: Loggers of Dask's distributed that print to the terminal themselves (their own stderr handlers).
DISTRIBUTED_LOGGERS = ("distributed", "distributed.client")


@contextlib.contextmanager
def quiet_distributed():
    """Dask's own log records (with tracebacks: a client that fails to reconnect to a lost scheduler
    logs one at ERROR level) kept off the terminal while a runner is open; every failure they
    report reaches the user as the failed task's error instead (:meth:`DaskRunner.map`). The levels
    are restored afterwards. Imports distributed first: its import configures these loggers."""
    _import_distributed()
    loggers = [logging.getLogger(name) for name in DISTRIBUTED_LOGGERS]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)
