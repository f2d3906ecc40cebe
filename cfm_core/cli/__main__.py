"""``python -m cfm_core.cli ...`` and the ``cfm`` console script: the ``cfm`` command."""

import gc
import signal
import sys

from .app import Terminated, main


def console() -> int:
    """Run :func:`main` on ``sys.argv``; its exit status, for ``sys.exit`` (the ``cfm`` console script).

    SIGTERM is handled as Ctrl-C (:func:`_terminated`). Every object left is frozen out of the garbage collector (``gc.freeze``) before the interpreter
    shuts down: its collections at exit would walk the hundreds of thousands of objects numba and
    matplotlib create (~0.25 s of a 2 s ``cfm drop-test``) to free memory the ending process gives
    back anyway. Objects still go away by reference counting; files are closed by the writers.
    """
    signal.signal(signal.SIGTERM, _terminated)
    code = main()
    gc.freeze()
    return code


def _terminated(signum, frame):
    """SIGTERM (``kill``, a batch system's time limit, ``timeout``) ends a command as Ctrl-C does: the
    output being written is removed and --out stays as it was (:class:`Terminated`, exit 143)."""
    raise Terminated()


if __name__ == "__main__":
    sys.exit(console())
