"""Worker preload of the local Dask clusters of ``cfm sweep`` and ``cfm calibrate``.

On Ctrl-C the command closes its cluster, whose nanny stops each worker process with SIGINT; asyncio's
runner in the worker then raises KeyboardInterrupt and the process printed two tracebacks each
(CancelledError, KeyboardInterrupt) before the command's own "interrupted; no result written". A worker
of such a cluster holds no result the command still needs when it is stopped, so SIGINT ends it at once
and quietly. Dask calls :func:`dask_setup` in each worker process (``preload`` of
``distributed.LocalCluster``); workers of a user's own cluster (``--scheduler``) are left alone.
"""

from __future__ import annotations

import os
import signal


def _leave(signum, frame) -> None:  # pragma: no cover (runs in a worker process)
    os._exit(128 + signum)


def dask_setup(worker) -> None:
    """Make SIGINT end this worker process quietly (exit 130); a no-op where signals cannot be set."""
    try:
        signal.signal(signal.SIGINT, _leave)
    except ValueError:  # not the main thread of the process (a thread-based cluster): nothing to do
        pass
