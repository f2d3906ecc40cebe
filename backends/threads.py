"""The thread count of a run: set for the run, the caller's count restored after it (every backend).

numba and torch keep one process-wide count of worker threads (``get_num_threads`` /
``set_num_threads``); a backend sets the count its options ask for around its time loop and gives
the caller back the count it had, also when the run raises. Neither library is imported here:
the backend passes the module it uses.
"""

from __future__ import annotations

from contextlib import contextmanager


@contextmanager
def num_threads(lib, threads: int | None, serial: bool = False):
    """Run a block with ``threads`` threads of ``lib``; the previous count is restored after it.

    Parameters
    ----------
    lib : module
        numba or torch (anything with ``get_num_threads()`` and ``set_num_threads(n)``).
    threads : int or None
        Threads for the block (>= 1, the backend option ``threads``); None: 1 if ``serial``,
        else the library's current count is left as it is.
    serial : bool
        Whether the run is too small to gain from threads (start-up costs more than it saves),
        so that ``threads=None`` means one thread.

    Yields
    ------
    None
        The block runs with the count set.
    """
    old = lib.get_num_threads()
    if threads is None and serial:
        threads = 1
    if threads is not None:
        lib.set_num_threads(int(threads))
    try:
        yield
    finally:
        lib.set_num_threads(old)
