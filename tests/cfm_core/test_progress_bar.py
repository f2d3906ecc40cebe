"""The run's progress bar draws where the terminal reports a size of 0 (tqdm alone draws nothing
there): 80 columns (or $COLUMNS) and 24 lines are assumed."""

import io
import os
import sys

from cfm_core.runs import pipeline
from cfm_core.scene.scene import builtin_scene


class _Terminal(io.StringIO):
    def isatty(self):
        return True

    def fileno(self):
        return 2


def _draw(monkeypatch, size, reached=1.05e-2):
    monkeypatch.setattr(os, "get_terminal_size", lambda fd=None: os.terminal_size(size))
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    update = pipeline._progress(True, builtin_scene("drop-test"), "drop test 8.0 mm (numba)")
    for t in (1e-3, 5e-3, 1e-2):
        update(t)
    update.close(reached)
    return [s for s in term.getvalue().replace("\n", "\r").split("\r") if s]


def test_a_terminal_of_zero_columns_gets_an_80_column_bar(monkeypatch):
    monkeypatch.delenv("COLUMNS", raising=False)
    monkeypatch.delenv("LINES", raising=False)
    lines = _draw(monkeypatch, (0, 0))
    assert lines and "100%|" in lines[-1] and "#" in lines[-1] and "t = 10.500/10.500 ms" in lines[-1]
    assert max(len(s) for s in lines) <= 80
    monkeypatch.setenv("COLUMNS", "100")
    assert pipeline.bar_size(_Terminal()) == {"ncols": 100, "nrows": 24}


def test_a_real_size_or_no_terminal_is_left_to_tqdm(monkeypatch):
    monkeypatch.setattr(os, "get_terminal_size", lambda fd=None: os.terminal_size((120, 40)))
    assert pipeline.bar_size(_Terminal()) == {}
    assert pipeline.bar_size(io.StringIO()) == {}  # no file descriptor: not a terminal


def test_a_failed_run_does_not_end_its_bar_at_100_percent(monkeypatch):
    """A run that stops on an error (close without the time reached) keeps its end time: the bar
    shows how far it got; a finished one ends at the time it reached (after the last report)."""
    monkeypatch.delenv("COLUMNS", raising=False)
    last = _draw(monkeypatch, (0, 0), reached=None)[-1]
    end = 1e3 * builtin_scene("drop-test").end_time
    assert "100%" not in last and f"t = 10.000/{end:.3f} ms" in last
