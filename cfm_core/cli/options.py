"""Options shared by the command groups: material options, ``NAME=VALUE`` parameters, the output
directory. Imports no command module (the progress bar is the run pipeline's, ``progress=True``)."""

from __future__ import annotations

import argparse
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
    default = f"; default: {default_material}" if default_material else "; default: the scene's"
    p.add_argument("--material", default=default_material,
                   help=f"registered material name (see 'cfm materials'){default}")
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
