"""Options shared by the command groups: material options, ``NAME=VALUE`` parameters, the output
directory and the progress bar. Imports no command module."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..errors import InputError


def parse_params(items) -> dict:
    """``NAME=VALUE`` strings -> {name: float}; InputError naming the bad item."""
    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise InputError(f"--param expects NAME=VALUE (SI units), got {item!r}.")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise InputError(f"--param {name.strip()}: value {value!r} is not a number.") from None
    return out


def add_material_options(p: argparse.ArgumentParser, default_material: str | None = "cfm"):
    p.add_argument("--material", default=default_material, help="registered material name (see 'cfm materials')")
    p.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="override a material parameter, SI units (Pa, s, -); repeatable")
    p.add_argument("--moduli", choices=["instantaneous", "long-term"], default=None,
                   help="whether c, k1 ... are instantaneous (g(0)) or long-term (g(inf)) moduli; default: the material's")
    p.add_argument("--elastic", action="store_true", help="switch the Prony series off (g(t) = 1)")




def out_dir(args) -> Path:
    """The ``--out`` directory (not created); InputError if it exists as a file."""
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a directory.")
    return out


class Progress:
    """Progress of a run in simulated time (a tqdm bar on stderr).

    Called with the simulated time t (s). Off when ``enabled`` is False (``--quiet``) or when
    stderr is not a terminal. A drop test ends at separation, before the scene's end time:
    :meth:`finish` then marks the bar complete at the time reached.
    """

    def __init__(self, end_time: float, label: str, enabled: bool = True):
        from tqdm import tqdm

        self.end = float(end_time)
        self.bar = None
        if enabled:
            self.bar = tqdm(total=round(1e3 * self.end, 3), desc=label, unit="ms", file=sys.stderr,
                            disable=None, mininterval=0.2, ncols=90, leave=True,
                            bar_format="{desc}: {percentage:3.0f}%|{bar}| t = {n:.3f}/{total:.3f} ms "
                                       "[{elapsed}<{remaining}]")

    def __call__(self, t: float) -> None:
        if self.bar is not None:
            n = round(1e3 * min(max(t, 0.0), self.end), 3)
            if n > self.bar.n:
                self.bar.update(n - self.bar.n)

    def finish(self) -> None:
        """The run ended normally: show the bar complete at the simulated time reached."""
        if self.bar is not None and not self.bar.disable:
            self.bar.total = self.bar.n
            self.bar.refresh()

    def close(self) -> None:
        """Close the bar (also after a failure: then it stays where the run stopped)."""
        if self.bar is not None:
            self.bar.close()
