"""Options shared by the command groups: material options, ``NAME=VALUE`` parameters, the output
directory, the backend and options a scene runs with. Imports no command module (the progress bar
is the run pipeline's, ``progress=True``)."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from ..errors import InputError
from ..runs.settings import RunPlan, plan_run
from ..scene.scene import builtin_scene, builtin_scenes, load_scene
from ..simulation.registry import backend_for
from ..tables import overflowed_to_inf, shown

#: Most optimiser evaluations ``--max-evaluations`` allows (``cfm fit`` per start, ``cfm calibrate``).
EVALUATIONS_MAX = 100_000


def scene_named(name: str):
    """The scene of a ``--scene`` value: a scene file, else a built-in scene's name (``cfm run``,
    ``cfm drop-test``, ``cfm sweep`` and ``cfm calibrate`` alike; a file of that name wins).

    Raises
    ------
    InputError
        Neither a file nor a built-in name (the built-in names listed), or a malformed file.
    """
    if not Path(name).exists() and name in builtin_scenes():
        return builtin_scene(name)
    if not Path(name).exists():
        raise InputError(f"--scene {name!r}: no such file, and not a built-in scene "
                         f"(built-in: {', '.join(builtin_scenes())}).")
    return load_scene(name)


def parse_params(items) -> dict:
    """``NAME=VALUE`` strings -> {name: float}; InputError naming the bad item."""
    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise InputError(f"--param expects NAME=VALUE (SI units), got {item!r}.")
        try:
            number = float(value)
        except ValueError:
            raise InputError(f"--param {name.strip()}: value {value!r} is not a number.") from None
        if name.strip() in out and out[name.strip()] != number:
            raise InputError(f"--param {name.strip()} is given twice, as {shown(out[name.strip()])} and {shown(number)}; "
                             f"give each parameter once.")
        out[name.strip()] = number
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


#: Frame interval (s) of ``--vtu`` when ``--option frame_interval=...`` does not give one.
VTU_FRAME_INTERVAL = 2e-4


def _option_value(text: str, spec):
    """A ``--option`` value in the type its declaration (``spec``, an OptionSpec) wants (number,
    integer, True/False, text, None). "none" is the text choice where the declaration lists it
    (``renumber=none``), else None."""
    kind = spec.kind
    if text.strip().lower() == "none":
        return "none" if "none" in spec.choices else None
    if kind in ("bool", "any"):  # "any": True / False where the declaration lists them among its choices
        if text.strip().lower() in ("true", "false"):
            return text.strip().lower() == "true"
        return text
    if kind in ("float", "int"):
        if kind == "int":
            try:
                return int(text.strip())   # exact: 10**26 through a float became 100000000000000004764729344
            except ValueError:
                pass
        try:
            value = float(text)
        except ValueError:
            return text  # the declaration's check names the option, the value and what is allowed
        return int(value) if kind == "int" and value.is_integer() else value
    return text


def typed(text: str) -> str:
    """What the user typed, for a message: an integer of more than 20 digits shortened as
    :func:`cfm_core.tables.shown` shortens it, other text of more than 40 characters cut in the middle."""
    t = text.strip()
    if re.fullmatch(r"[+-]?\d+", t):
        try:
            return shown(int(t))
        except ValueError:  # beyond Python's 4300 digits of int(): shortened as text
            pass
    return t if len(t) <= 40 else f"{t[:24]}...{t[-8:]} ({len(t)} characters)"


def _overflowed(name: str, text: str, value, spec, backend: str) -> None:
    """InputError naming what was typed when a finite number beyond the float range (``1e400``,
    ``1`` followed by 400 zeros) read as inf and the option does not take inf; the declaration's
    own message would show only "inf"."""
    if not overflowed_to_inf(text, value):
        return
    try:
        spec.check(name, value, backend)  # inf allowed where the range is open to it (dt_max)
    except InputError:
        raise InputError(f"--option {name}={typed(text)} is beyond the float range (largest about 1.8e308), so it "
                         f"reads as {'-' if value < 0 else ''}inf, which {name} does not take: expected "
                         f"{spec.allowed()} ({spec.doc}); 'cfm backends --options' lists the options.") from None


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
        if name in options and options[name] != _option_value(value, specs[name]):
            raise InputError(f"--option {name} is given twice ({given_as[name]} and --option {name}={value.strip()}); "
                             f"give each option once.")
        options[name] = _option_value(value, specs[name])
        _overflowed(name, value, options[name], specs[name], backend)
        given_as[name] = f"--option {name}={value.strip()}"
    if getattr(args, "vtu", False) and "frame_interval" not in options:  # --option frame_interval=... wins
        options["frame_interval"] = VTU_FRAME_INTERVAL
        given_as["frame_interval"] = f"--vtu (frame_interval = {VTU_FRAME_INTERVAL:g} s)"
    for flag in ("device", "dtype"):
        value = getattr(args, flag, None)
        if value is not None:
            if flag not in specs:
                raise InputError(f"--{flag} {value}: backend '{backend}' has no choice of {flag} (only torch has: "
                                 f"--backend torch --{flag} {value}).")
            if flag in options and options[flag] != value:
                raise InputError(f"--{flag} {value} and {given_as[flag]} disagree; give the {flag} once (--{flag}).")
            options[flag] = value
            given_as[flag] = f"--{flag} {value}"
    return options, given_as


def plan_from_args(args, scene, default: str | None = None) -> RunPlan:
    """The backend and options a scene runs with: its ``[run]`` section, overridden by the command
    line (``--backend``, ``--option``, ``--dtype``, ``--device``, ``--vtu``), for ``cfm drop-test``,
    ``cfm run``, ``cfm sweep`` and ``cfm calibrate`` alike.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (``backend`` None when not given; ``scene`` the file, if any).
    scene : Scene
        The scene (its ``run`` section, if any).
    default : str, optional
        Backend when neither names one (default :func:`cfm_core.runs.pipeline.default_backend`).

    Returns
    -------
    RunPlan
        Backend, options, and notes on what the command line changed against the file.

    Raises
    ------
    InputError
        An unknown or unavailable backend (naming ``[run] backend`` when it came from the file), an
        option the backend does not declare, a value out of range.
    """
    from ..runs import pipeline

    if args.backend is not None and not args.backend.strip():
        raise InputError(f"--backend {args.backend!r} is empty; give a backend name ('cfm backends' lists them) or "
                         f"leave --backend out for the scene's [run] backend, else numba.")
    default = default or pipeline.default_backend(scene)
    run = scene.run
    name = args.backend or (run.backend if run is not None else None) or default
    where = f"{Path(args.scene).name} [run]" if getattr(args, "scene", None) else "the scene's [run]"
    if not args.backend and run is not None and run.backend:
        try:
            backend_for(name)
        except InputError as exc:
            raise InputError(f"{where} backend = {name!r}: {exc}") from None
    options, given_as = backend_options(args, name)
    given_as["backend"] = f"--backend {args.backend}"
    return plan_run(scene, args.backend, options, default=default, given_as=given_as, where=where)
