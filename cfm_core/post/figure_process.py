"""A second process that imports matplotlib while a run computes, then draws the run's figure.

Importing matplotlib takes 0.3-0.5 s, a fifth of a warm ``cfm drop-test`` end to end, and the
command needs it only after the solve. :func:`started` forks the process before the run: the child
imports matplotlib on the machine's other core while the parent loads its kernels and solves, and
draws the figure when :mod:`cfm_core.post.plots` sends it the arrays (pickled through a pipe). The
file is the one the same function draws in the parent: the child runs that function, writing the
PNG atomically into the same (staged) folder, and the parent waits for its answer before it goes
on. The child is only an accelerator: when it cannot start, fails, dies or does not answer within
:data:`ANSWER_S`, the parent draws the figure itself, as without it (and an error of the drawing
is then raised in the parent, as always).

The process is forked only where that is safe and can pay: Linux (``fork`` start method), a
process running one thread (forking a process with other threads can leave the child holding
their locks: a process whose numba threads have started or that imported torch, pytest-xdist
and Dask workers and notebooks draw inline), at least two cores in
the process's affinity, matplotlib not imported yet, not a daemonic process (a multiprocessing
pool's worker may have no children), and ``CFM_FIGURE_PROCESS`` not ``0``. Ctrl-C and SIGTERM
never make the child print: it ignores SIGINT (the parent ends it), dies quietly on SIGTERM,
both blocked around the fork until it has set that up, and it stops when the parent closes the
pipe. The child runs at a lower priority (nice 10), and the default thread count of a run does not count
its CPU time as load (:func:`cfm_backends.threads.free_cores`).
"""

from __future__ import annotations

import os
import sys
import threading

#: Seconds the parent waits for the child's answer to one figure before drawing it itself.
ANSWER_S = 60.0

#: Environment variable that turns the figure process off when set to ``0``.
ENV = "CFM_FIGURE_PROCESS"

_worker = None  # (process, parent end of the pipe) while a figure process runs


def _threads() -> str | None:
    """Which threads besides this one run in the process (a phrase), or None: Python threads,
    numba's worker threads once launched, torch's pools once torch is imported. (numpy's
    OpenBLAS pool is fork-safe: it stops itself around a fork.)"""
    if threading.active_count() != 1:
        return f"{threading.active_count()} Python threads run in this process"
    parallel = sys.modules.get("numba.np.ufunc.parallel")
    if parallel is not None and getattr(parallel, "_is_initialized", False):
        return "numba's threads run in this process"
    if "torch" in sys.modules:
        return "torch is imported (its thread pools)"
    return None


def usable() -> str | None:
    """Why a figure process would not start in this process now (a short phrase), or None when it
    would."""
    if os.environ.get(ENV, "").strip() == "0":
        return f"{ENV}=0"
    if not sys.platform.startswith("linux"):
        return f"not on Linux ({sys.platform})"
    threads = _threads()
    if threads is not None:
        return threads
    if "matplotlib" in sys.modules:
        return "matplotlib is imported already"
    mp = sys.modules.get("multiprocessing")
    if mp is not None and mp.current_process().daemon:
        return "a daemonic process (a multiprocessing pool's worker) may not start one"
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    if cores < 2:
        return "one core"
    return None


#: Signals blocked around the fork, so that none reaches the child before it has set its own
#: handlers (it would run the parent's: a traceback instead of the parent's one-line message).
_SIGNALS = ("SIGINT", "SIGTERM")


def _send(conn, message) -> bool:
    """Send to the parent; False when it is gone (it closed the pipe: Ctrl-C, an error)."""
    try:
        conn.send(message)
        return True
    except (OSError, ValueError):
        return False


def _serve(conn, other_end) -> None:
    """The child: ignore Ctrl-C (the parent ends it), end quietly on SIGTERM, import matplotlib,
    draw what comes, and stop when the parent is gone."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, [getattr(signal, n) for n in _SIGNALS])
    try:
        os.nice(10)  # the run's threads go first when both want a core
    except OSError:
        pass
    other_end.close()  # so that the parent's death reads as the end of the pipe here
    global _worker
    _worker = None  # the plot functions draw in this process
    try:
        import importlib

        for name in ("matplotlib.figure", "matplotlib.backends.backend_agg", "matplotlib.image"):
            importlib.import_module(name)  # the slow part, ahead of the figure
        from . import plots
    except BaseException as exc:  # noqa: BLE001 (any failure: the parent draws)
        _send(conn, ("failed", f"{type(exc).__name__}: {exc}"))
        return
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):
            return
        if job is None:
            return
        name, args = job
        try:
            getattr(plots, name)(*args)
            answer = ("drawn", None)
        except BaseException as exc:  # noqa: BLE001
            answer = ("failed", f"{type(exc).__name__}: {exc}")
        if not _send(conn, answer):
            return


def pid() -> int | None:
    """The process id of the figure process, None when none runs."""
    return _worker[0].pid if _worker is not None else None


def start() -> bool:
    """Fork the figure process when :func:`usable` allows it; True if one runs (now or already)."""
    global _worker
    if _worker is not None:
        return True
    if usable() is not None:
        return False
    import multiprocessing
    import signal

    blocked = [getattr(signal, n) for n in _SIGNALS]
    before = signal.pthread_sigmask(signal.SIG_BLOCK, blocked)
    try:
        context = multiprocessing.get_context("fork")
        parent_end, child_end = context.Pipe()
        process = context.Process(target=_serve, args=(child_end, parent_end), daemon=True,
                                  name="cfm-figures")
        process.start()
    except (OSError, ValueError, AssertionError):  # AssertionError: multiprocessing's own refusals
        return False
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)
    child_end.close()
    _worker = (process, parent_end)
    return True


def stop(wait: bool = True) -> None:
    """End the figure process (if one runs): ask it to stop and wait up to 5 s for it (``wait``),
    or kill it at once (an interrupted or failed command: nothing it draws will be used)."""
    global _worker
    if _worker is None:
        return
    process, conn = _worker
    _worker = None
    if wait:
        _send(conn, None)
    conn.close()
    if wait:
        process.join(timeout=5.0)
    if process.is_alive():
        process.kill()
    process.join()


def draw(name: str, *args) -> bool:
    """Have the figure process call ``plots.<name>(*args)`` (``args[0]``: the figure's path); True
    when it drew the figure, False when no process runs or it failed (then it is ended, a
    temporary file it left beside the figure removed, and the caller draws the figure)."""
    if _worker is None:
        return False
    process, conn = _worker
    try:
        conn.send((name, args))
        if conn.poll(ANSWER_S):
            answer, _ = conn.recv()
            if answer == "drawn":
                return True
    except (OSError, EOFError, ValueError):
        pass
    stop()
    if args:  # a child ended while writing leaves its temporary file (writers.atomic_write) beside the figure
        from pathlib import Path

        target = Path(args[0])
        for leftover in target.parent.glob(f".{target.name}.{process.pid}.*.tmp"):
            leftover.unlink(missing_ok=True)
    return False


class started:
    """``with started(wanted):`` a figure process runs inside the block when ``wanted`` and
    :func:`usable`; it is ended on leaving the block, killed at once when the block raised
    (Ctrl-C, a failed run: the figure it may be drawing is not wanted)."""

    def __init__(self, wanted: bool = True):
        self.wanted = wanted

    def __enter__(self):
        if self.wanted:
            start()
        return self

    def __exit__(self, kind, value, traceback) -> None:
        stop(wait=kind is None)
