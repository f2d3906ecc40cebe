"""Options shared by the command groups: material options, ``NAME=VALUE`` parameters, the output
directory. Imports no command module (the progress bar is the run pipeline's, ``progress=True``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import InputError
from ..simulation.registry import backend_for


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


def _option_value(text: str, kind: str):
    """A ``--option`` value in the type its declaration wants (number, integer, True/False, text, None)."""
    if text.strip().lower() == "none":
        return None
    if kind in ("bool", "any"):  # "any": True / False where the declaration lists them among its choices
        if text.strip().lower() in ("true", "false"):
            return text.strip().lower() == "true"
        return text
    if kind in ("float", "int"):
        try:
            value = float(text)
        except ValueError:
            return text  # the declaration's check names the option, the value and what is allowed
        return int(value) if kind == "int" and value.is_integer() else value
    return text


def backend_options(args, backend: str) -> tuple[dict, dict]:
    """The backend options of the command line: ``--option NAME=VALUE`` (repeatable), ``--vtu``,
    ``--device`` and ``--dtype``; InputError for a name the backend does not declare. Also how each
    was given (for the notes when one overrides the scene's [run] value)."""
    declared = getattr(backend_for(backend), "options_class", None)
    specs = declared.specs() if declared is not None else {}
    options, given_as = {}, {}
    for item in getattr(args, "option", None) or []:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise InputError(f"--option expects NAME=VALUE (SI units), got {item!r}; 'cfm backends --options' "
                             f"lists each backend's options.")
        if name not in specs:
            raise InputError(f"--option {name}: backend '{backend}' has no option of that name; its options are "
                             f"{', '.join(specs) or 'none'} ('cfm backends --options' gives units and ranges).")
        options[name] = _option_value(value, specs[name].kind)
        given_as[name] = f"--option {name}={value.strip()}"
    if getattr(args, "vtu", False):
        options["frame_interval"] = 2e-4
        given_as["frame_interval"] = "--vtu (frame_interval = 0.0002 s)"
    for flag in ("device", "dtype"):
        value = getattr(args, flag, None)
        if value is not None:
            if flag not in specs:
                raise InputError(f"--{flag} {value}: backend '{backend}' has no choice of {flag} (only torch has: "
                                 f"--backend torch --{flag} {value}).")
            options[flag] = value
            given_as[flag] = f"--{flag} {value}"
    return options, given_as
