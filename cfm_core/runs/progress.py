"""The progress bar of a run: a tqdm bar on stderr in simulated milliseconds (off when stderr is
not a terminal), or a caller's callback."""

from __future__ import annotations

import os
import sys

from tqdm import tqdm

from ..scene.scene import Scene


#: Size of the progress bar's terminal (columns, lines) where the terminal reports none (0).
FALLBACK_SIZE = (80, 24)


def bar_size(stream) -> dict:
    """tqdm's ``ncols`` / ``nrows`` for a progress bar on ``stream`` where the terminal reports a
    size of 0 (some CI consoles, serial and container terminals): there tqdm would draw nothing.

    A reported 0 (or 1) becomes ``$COLUMNS`` / ``$LINES`` if set, else :data:`FALLBACK_SIZE`
    (80 columns, 24 lines); a real size is left to tqdm (empty dict).

    Parameters
    ----------
    stream : file
        Where the bar is drawn (stderr).

    Returns
    -------
    dict
        Keyword arguments for tqdm: ``{}``, or ``ncols`` and/or ``nrows`` (characters, lines).
    """
    try:
        size = os.get_terminal_size(stream.fileno())
    except (AttributeError, ValueError, OSError):  # io.UnsupportedOperation is both of the last two
        return {}  # not a terminal: tqdm's own rules (off when stderr is not a terminal)
    out = {}
    for key, env, got, fallback in (("ncols", "COLUMNS", size.columns, FALLBACK_SIZE[0]),
                                    ("nrows", "LINES", size.lines, FALLBACK_SIZE[1])):
        if got <= 1:
            given = os.environ.get(env, "").strip()
            out[key] = int(given) if given.isdigit() and int(given) > 1 else fallback
    return out


def _progress(progress, scene: Scene, label: str):
    """A progress callback from the ``progress`` argument: None/False (none), True (a tqdm bar on
    stderr, off when stderr is not a terminal), or a callable taking the simulated time in s."""
    if progress is True:
        bar = tqdm(total=round(1e3 * scene.end_time, 3), desc=label, unit="ms", file=sys.stderr, disable=None,
                   mininterval=0.2, **bar_size(sys.stderr), bar_format="{desc}: {percentage:3.0f}%|{bar}| t = {n:.3f}/{total:.3f} ms [{elapsed}]")

        def update(t: float) -> None:
            n = round(1e3 * min(max(t, 0.0), scene.end_time), 3)
            if n > bar.n:
                bar.update(n - bar.n)

        def close(t_reached: float | None = None) -> None:
            """Finish the bar: a finished run (t_reached, s) ends at the time it reached (a drop test
            ends at separation, before the end time); a failed one keeps its end time, so the bar
            shows how far it got instead of 100 %."""
            if t_reached is not None:
                update(t_reached)
                bar.total = bar.n
                bar.refresh()
            bar.close()

        update.close = close
        return update
    return progress or None
