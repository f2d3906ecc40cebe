"""The thread count of a run: set for the run, the caller's count restored after it (every backend).

numba and torch keep one process-wide count of worker threads (``get_num_threads`` /
``set_num_threads``); a backend sets the count its options ask for around its time loop and gives
the caller back the count it had, also when the run raises. Neither library is imported here:
the backend passes the module it uses.

Without a count from the user, a run takes the cores actually free to this process
(:func:`free_cores`): the cores it may run on (affinity), less those other processes keep busy
(measured over a few milliseconds from /proc/stat; this process's own figure process does not
count), and inside a Dask worker its share of the worker's cores. A parallel step waits for its
slowest thread at every barrier: one thread on a core that another process holds makes every step
wait for the scheduler, so on a shared machine more threads than free cores made runs several
times slower than one thread.
"""

from __future__ import annotations

import math
import os
import sys
import time
from contextlib import contextmanager

from cfm_core.errors import InputError

SAMPLE_S = 0.03      # how long /proc/stat is watched for idle time (s)
REUSE_S = 2.0        # a measurement is reused this long (s): a sweep's runs do not each wait for one
IDLE_SLACK = 0.15    # a core counts as free when at least 85 % of it was idle ...
TICK_SLACK = 1.05    # ... or all of it but one tick of /proc/stat (its resolution; see free_cores)

_last: tuple[float, int] | None = None


def allowed_cpus() -> list[int]:
    """The CPUs this process may run on (its affinity; all CPUs where the OS cannot tell)."""
    try:
        return sorted(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return list(range(os.cpu_count() or 1))


def _cpu_times(cpus: list[int]) -> tuple[float, float] | None:
    """(idle, total) jiffies summed over ``cpus`` from /proc/stat, or None where unreadable."""
    try:
        with open("/proc/stat", encoding="ascii") as f:
            lines = f.read().splitlines()
    except OSError:
        return None
    want = {f"cpu{c}" for c in cpus}
    idle = total = 0.0
    for line in lines:
        parts = line.split()
        if parts and parts[0] in want:
            v = [float(x) for x in parts[1:]]
            idle += v[3] + (v[4] if len(v) > 4 else 0.0)       # idle + iowait
            total += sum(v[:8])                                # guest time is counted in user already
    return (idle, total) if total > 0 else None


def _helper_ticks() -> float:
    """CPU time so far (user + system, in /proc/stat's ticks) of this process's own helper that
    is about to go idle: the figure process of :mod:`cfm_core.post.figure_process`, which imports
    matplotlib while the run starts and then waits for the figure. 0 when none runs."""
    module = sys.modules.get("cfm_core.post.figure_process")
    pid = module.pid() if module is not None else None
    if pid is None:
        return 0.0
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as f:
            fields = f.read().rpartition(")")[2].split()
        return float(fields[11]) + float(fields[12])  # utime, stime (fields 14 and 15 of proc(5))
    except (OSError, IndexError, ValueError):
        return 0.0


def idle_cores(cpus: list[int], sample: float = SAMPLE_S, with_resolution: bool = False):
    """Cores of ``cpus`` left idle by every other process over ``sample`` seconds (None where
    /proc/stat cannot be read); this process sleeps meanwhile. The time of this process's own
    figure process (:func:`_helper_ticks`) counts as idle: it is done before the run needs the
    cores. With ``with_resolution``: (idle cores, the cores one tick of the sample stands for,
    ``len(cpus)`` / the ticks counted), or None."""
    a, ha = _cpu_times(cpus), _helper_ticks()
    if a is None:
        return None
    time.sleep(sample)
    b, hb = _cpu_times(cpus), _helper_ticks()
    if b is None or b[1] <= a[1]:
        return None
    idle = min(float(len(cpus)), len(cpus) * (b[0] - a[0] + max(0.0, hb - ha)) / (b[1] - a[1]))
    return (idle, len(cpus) / (b[1] - a[1])) if with_resolution else idle


def dask_worker_threads() -> int | None:
    """The thread count of the Dask worker this code runs in, or None outside a worker (only
    looked up where ``distributed`` is already imported: a worker has imported it)."""
    if "distributed" not in sys.modules:
        return None
    try:
        worker = sys.modules["distributed"].get_worker()
    except (ValueError, AttributeError):
        return None
    state = getattr(worker, "state", worker)
    n = getattr(state, "nthreads", None) or getattr(worker, "nthreads", None)
    return int(n) if n else None


def free_cores() -> int:
    """Threads a run should use by default: the cores actually free to this process, at least 1.

    The allowed cores (affinity) less those busy with other processes (idle time over
    ``SAMPLE_S`` from /proc/stat, a core free when at least 85 % idle or busy for no more than
    one tick of the sample; the 1-minute load average where /proc/stat is unreadable), divided
    among the task threads of a Dask worker (each of its concurrent tasks gets an equal share,
    never more than one core's worth less). A measurement is reused for ``REUSE_S`` seconds.

    Returns
    -------
    int
        1 <= threads <= the allowed cores.
    """
    global _last
    now = time.monotonic()
    cpus = allowed_cpus()
    if _last is not None and now - _last[0] < REUSE_S:
        n = _last[1]
    else:
        got = idle_cores(cpus, with_resolution=True) if len(cpus) > 1 else (float(len(cpus)), 0.0)
        if got is None:
            try:
                got = (len(cpus) - os.getloadavg()[0], 0.0)
            except OSError:
                got = (float(len(cpus)), 0.0)
        # /proc/stat counts whole ticks (100 a second): a 30 ms sample of 2 cores holds about 6,
        # and one of them busy (the kernel's own accounting, a daemon waking) is a third of a
        # core; at 85 % that made 3 % of the measurements on an idle machine, and a third of
        # the `cfm drop-test` runs (whose figure process starts meanwhile), take one thread. A
        # core another process holds is busy for every tick of the sample.
        idle, tick = got
        n = int(max(1, min(len(cpus), math.floor(idle + max(IDLE_SLACK, TICK_SLACK * tick)))))
        _last = (now, n)
    tasks = dask_worker_threads()
    if tasks:
        n = max(1, min(n, len(cpus) // tasks))
    return n


def check_count(threads: int | None) -> None:
    """Refuse a thread count above the cores this process may use (None: the default, allowed).

    Raises
    ------
    InputError
        ``threads`` is more than the allowed cores: more threads than cores never runs faster,
        and waits at every barrier.
    """
    cores = len(allowed_cpus())
    if threads is not None and threads > cores:
        raise InputError(f"option threads = {threads} is more than the {cores} core{'s' if cores > 1 else ''} this "
                         f"process may use; give at most {cores}, or leave threads out (default: the cores free "
                         f"now).")


@contextmanager
def num_threads(lib, threads: int | None, serial: bool = False):
    """Run a block with ``threads`` threads of ``lib``; the previous count is restored after it.

    Parameters
    ----------
    lib : module
        numba or torch (anything with ``get_num_threads()`` and ``set_num_threads(n)``).
    threads : int or None
        Threads for the block (>= 1, the backend option ``threads``); None: 1 if ``serial``,
        else :func:`free_cores` (never more than the library has).
    serial : bool
        Whether the run is too small to gain from threads (start-up costs more than it saves),
        so that ``threads=None`` means one thread.

    Yields
    ------
    None
        The block runs with the count set.
    """
    old = lib.get_num_threads()
    if threads is None:
        threads = 1 if serial else min(free_cores(), max(old, 1))
    check_count(threads)
    lib.set_num_threads(int(threads))
    try:
        yield
    finally:
        lib.set_num_threads(old)
