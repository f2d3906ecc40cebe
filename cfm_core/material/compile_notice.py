"""The one notice a cold first run prints while numba compiles a material's generated kernels.

Both backends that compile generated numba code (``numba``: the explicit solver; ``skfem``: its
compiled element kernels) import their module through :func:`cfm_core.material.cache.import_generated`
and compile it on first call (``njit(cache=True)``), which takes 10-30 s once per machine and
material. :func:`announce_compile` says so on stderr before, and how long it took after; it is
silent when numba's on-disk cache already holds the kernel. While it compiles it holds a lock file
beside the module in the cache: another process about to compile the same module (a second test
worker, a Dask worker of the same sweep) waits for it and then loads the cached kernels instead of
compiling them a second time. Imports no numba.
"""

from __future__ import annotations

import json
import sys
import time
from contextlib import contextmanager, suppress

from .cache import cache_dir, generated_name

TIMES = "compile_seconds.json"  # the last compile time of a backend's folder: the next estimate


def is_compiled(text: str, prefix: str, subdir: str, label: str, kernel: str) -> bool:
    """Whether numba's on-disk cache holds machine code of ``kernel`` of a generated module.

    Parameters
    ----------
    text, prefix, subdir, label : str
        As given to :func:`cfm_core.material.cache.import_generated` (module source, name prefix,
        cache subfolder, material name).
    kernel : str
        Name of a function of the module that every run calls (e.g. ``"advance"``).

    Returns
    -------
    bool
        True when ``<cache>/<subdir>/__pycache__/<module>.<kernel>-*.nbi`` exists.
    """
    name = generated_name(text, prefix, label)
    return any((cache_dir(subdir) / "__pycache__").glob(f"{name}.{kernel}-*.nbi"))


def _last_compile_time(subdir: str, kernel: str) -> float | None:
    try:
        return float(json.loads((cache_dir(subdir) / TIMES).read_text())[kernel])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _store_compile_time(subdir: str, kernel: str, seconds: float) -> None:
    path = cache_dir(subdir) / TIMES
    try:
        try:
            times = dict(json.loads(path.read_text()))
        except (OSError, ValueError, TypeError):
            times = {}
        times[kernel] = seconds
        path.write_text(json.dumps(times))
    except OSError:  # a read-only cache still runs
        pass


_READY: set = set()  # (cache folder, module name, kernel) found or compiled: not looked up again


@contextmanager
def announce_compile(text: str, prefix: str, subdir: str, label: str, kernel: str, stream=None,
                     estimate: str = "about 20 s on a free core"):
    """Say on stderr what a cold first run is doing while numba compiles a generated module.

    When :func:`is_compiled` is False, prints "numba: compiling kernels for material 'LABEL' (once
    per machine, ~N s; cached in DIR)..." before the block and "numba: kernels for material 'LABEL'
    compiled in N s." after it (the seconds are kept per kernel in ``DIR/compile_seconds.json`` as
    the next estimate). The block runs holding ``DIR/<module>.lock`` (:func:`_compiling`): a process
    compiling the same module meanwhile is waited for, and the block then loads its cached kernels.
    Silent when the cache has the kernel; once found or compiled, a kernel is not looked up again
    in this process.

    Parameters
    ----------
    text, prefix, subdir, label, kernel : str
        See :func:`is_compiled`.
    stream : file, optional
        Where to print (default ``sys.stderr``).
    estimate : str
        The duration said before the first compilation on this machine (later: the last one's).
    """
    folder = cache_dir(subdir)
    ready = (str(folder), generated_name(text, prefix, label), kernel)
    if ready in _READY or is_compiled(text, prefix, subdir, label, kernel):
        _READY.add(ready)
        yield
        return
    stream = stream or sys.stderr
    guess = _last_compile_time(subdir, kernel)
    estimate = f"~{guess:.0f} s" if guess else estimate
    lead = "\n" if getattr(stream, "isatty", lambda: False)() else ""   # below a progress bar
    print(f"{lead}numba: compiling kernels for material '{label}' (once per machine, {estimate}; cached in "
          f"{folder})...", file=stream, flush=True)
    start = time.perf_counter()
    with _compiling(folder / f"{ready[1]}.lock"):
        yield
    took = time.perf_counter() - start
    print(f"numba: kernels for material '{label}' compiled in {took:.1f} s.", file=stream, flush=True)
    _READY.add(ready)
    _store_compile_time(subdir, kernel, took)


#: Longest wait (s) for another process compiling the same module; then this one compiles too.
LOCK_WAIT = 900.0


@contextmanager
def _compiling(path):
    """Hold the lock file ``path`` (``filelock``) while compiling; without filelock, or where the
    lock cannot be taken (read-only cache, LOCK_WAIT s passed), compile unlocked."""
    try:
        from filelock import FileLock, Timeout
    except ImportError:
        yield
        return
    lock = FileLock(str(path))
    try:
        lock.acquire(timeout=LOCK_WAIT)
    except (Timeout, OSError):
        yield
        return
    try:
        yield
    finally:
        with suppress(OSError):
            lock.release()
