"""The ``cfm`` command: one parser, subcommands from the command modules.

Built-in command groups: material.py (``materials``, ``backends``, ``point``), scene.py
(``drop-test``, ``run``), compare.py (``compare``), studies.py (``sweep``, ``calibrate``). More
commands come from the ``cfm.commands`` entry-point group (the verification suite registers
``verify`` there): a command module has ``add_parser(subparsers)`` and ``COMMANDS`` (name ->
handler). User mistakes (InputError, and a mistyped command or option, with "did you mean ...?")
print one paragraph and exit 2; numerical failures
(NumericalError, including a run whose physics broke) print where and when and exit 3. No
traceback for either, and no partial output file.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import warnings

from .. import plugins
from ..errors import InputError, NumericalError
from . import calculix, compare, export, fields, fit, material, scene, studies
from .suggest import Parser, VersionAction, refuse_unknown

BUILTIN = (material, scene, compare, studies, fit, export, fields, calculix)

plugins.declare_kind(
    "commands", "cfm.commands", lambda obj: callable(getattr(obj, "add_parser", None)) and
    isinstance(getattr(obj, "COMMANDS", None), dict), "a module with add_parser(subparsers) and COMMANDS",
    "register one with the 'cfm.commands' entry-point group")


def command_modules() -> list:
    """The built-in command modules, then the registered ones (broken ones warn and are skipped)."""
    extra = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for name, (module, err) in plugins.entries("commands").items():
            if err:
                print(f"cfm: command plugin '{name}' is skipped: {err}", file=sys.stderr)
            else:
                extra.append(module)
    return [*BUILTIN, *extra]


def build_parser(modules=None) -> argparse.ArgumentParser:
    """The ``cfm`` argument parser with every command module's subcommands."""
    parser = Parser(prog="cfm", description="Circular fiber model framework (SI units: m, s, kg, Pa).")
    parser.add_argument("--version", action=VersionAction, help="print the package version and the backends available, then exit")
    sub = parser.add_subparsers(dest="command", required=True)
    for module in modules or command_modules():
        module.add_parser(sub)
    return parser


class Terminated(KeyboardInterrupt):
    """SIGTERM received (the ``cfm`` console script turns the signal into this): unwinds like Ctrl-C,
    so that a staged output is removed, and ends the command with exit 143 (128 + SIGTERM)."""


def _after_signal(exc: BaseException) -> str:
    """What a signal left: nothing, or an output published whole just before it arrived (the
    signal is held back while files are moved: ``cfm_core.post.staging.deferred_signals``)."""
    published = getattr(exc, "published", None)
    if published is not None:
        return f"the signal came while the output was being moved into place, which was finished first: {published} is complete."
    return "no result written."


#: Options naming a file or folder a command writes (argparse dest, flag): an empty one is refused.
OUTPUT_OPTIONS = (("out", "--out"), ("plot", "--plot"), ("json", "--json"), ("png", "--png"))


def refuse_empty_outputs(args) -> None:
    """Refuse an output option given as empty text (``--out ''``, an unset shell variable): it names no
    path, and was taken as the current folder (replacing an earlier cfm output there) or skipped.

    Raises
    ------
    InputError
        Naming the option.
    """
    for dest, flag in OUTPUT_OPTIONS:
        value = getattr(args, dest, None)
        if isinstance(value, str) and not value:
            kind = "folder" if dest == "out" and args.command != "point" else "file"
            raise InputError(f"{flag} is empty; give a {kind} (an empty {flag}, e.g. from an unset shell "
                             f"variable, names no path).")


def main(argv=None) -> int:
    """Run the ``cfm`` command line; returns the exit status (0 ok, 1 a check failed, 2 input
    error, 3 numerical failure, 130 interrupted, 141 its output's reader stopped, 143 terminated)."""
    modules = command_modules()
    parser = build_parser(modules)
    args, extra = parser.parse_known_args(argv)
    if extra:  # a mistyped option: one paragraph with the closest options of the command, exit 2
        refuse_unknown(parser, args.command, extra)
    handlers = {name: fn for module in modules for name, fn in module.COMMANDS.items()}
    try:
        refuse_empty_outputs(args)
        return handlers[args.command](args)
    except InputError as exc:
        print(f"cfm {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except NumericalError as exc:
        print(f"cfm {args.command}: numerical failure: {exc}", file=sys.stderr)
        return 3
    except Terminated as exc:
        print(f"cfm {args.command}: terminated (SIGTERM); {_after_signal(exc)}", file=sys.stderr)
        return 143
    except KeyboardInterrupt as exc:
        print(f"cfm {args.command}: interrupted; {_after_signal(exc)}", file=sys.stderr)
        return 130
    except BrokenPipeError:  # `cfm materials | head`: the reader stopped reading; no traceback
        with contextlib.suppress(OSError, ValueError):  # Python's flush of stdout at exit would raise again
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, as for a command the signal ended


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
