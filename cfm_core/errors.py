"""Exception types shared by the whole project.

Two families, so the CLI can tell a user's mistake from a numerical failure:

- :class:`InputError` (a ``ValueError``): bad names, parameters, files or geometry. The CLI prints
  its one-paragraph message and exits with status 2, without a traceback.
- :class:`NumericalError` (a ``RuntimeError``): overflow, element inversion or time-step collapse
  during a run. It names where (element, node) and when (time in s) it happened; the CLI prints it
  and exits with status 3. Nothing is written as if the run had succeeded.
"""

from __future__ import annotations

import difflib


class InputError(ValueError):
    """A user-facing input problem: the message names the field, the value and what is allowed.

    A ``ValueError``; the ``cfm`` command prints its one-paragraph message without a traceback and
    exits with status 2. Constructed like any exception, from the message alone.
    """


class NumericalError(RuntimeError):
    """A numerical failure during a computation.

    A ``RuntimeError``; the ``cfm`` command prints it and exits with status 3. The keyword
    arguments are optional context for reports, stored as attributes of the same names.

    Parameters
    ----------
    message : str
        What failed, where (element, node, row) and when (time in s).
    time : float, optional
        Simulated time of the failure (s).
    element : int, optional
        Index of the element (or material point, row) where it happened.
    quantity : str, optional
        What went wrong: ``"J"``, ``"exp argument"``, ``"time step"``, ...
    """

    def __init__(self, message: str, *, time: float | None = None, element: int | None = None,
                 quantity: str | None = None):
        super().__init__(message)
        self.time = time
        self.element = element
        self.quantity = quantity


def did_you_mean(word: str, choices) -> str:
    """The closest names to a mistyped one, as a sentence for an error message.

    Parameters
    ----------
    word : str
        What was given (a command, an option, a key).
    choices : iterable of str
        The valid names.

    Returns
    -------
    str
        ``"Did you mean 'thickness'?"`` (up to three names, closest first, by
        :func:`difflib.get_close_matches` with cutoff 0.6), or ``""`` when none is close.
    """
    close = difflib.get_close_matches(str(word), [str(c) for c in choices], n=3, cutoff=0.6)
    return f"Did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
