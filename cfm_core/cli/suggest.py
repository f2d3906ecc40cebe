"""The ``cfm`` argument parser's own behaviour: one-paragraph errors with "did you mean ...?" for a
mistyped command, option or choice (exit status 2), and ``cfm --version``.

Unambiguous prefixes of an option stay accepted (argparse's abbreviations: ``--thick`` is
``--thickness``); a name that is not a prefix (``--thicknesss``, ``--thikness``) is refused with
the closest option names of the command (:func:`cfm_core.errors.did_you_mean`).
"""

from __future__ import annotations

import argparse
import platform
import re
import sys
import warnings
from importlib import metadata

from .. import plugins
from ..errors import did_you_mean

DISTRIBUTION = "cfm-materials"


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one paragraph with the closest valid names, exit 2."""

    def error(self, message: str):
        """Print ``PROG: error: MESSAGE. Did you mean ...? (PROG --help lists ...)`` on stderr; exit 2."""
        hint = self._choice_hint(message)
        text = " ".join(filter(None, (f"{self.prog}: error: {message.rstrip('.')}.", hint,
                                      f"'{self.prog} --help' lists what is allowed.")))
        self.exit(2, text + "\n")

    def _choice_hint(self, message: str) -> str:
        m = re.search(r"invalid choice: '([^']*)'", message)
        if m is None:
            return ""
        head = message.split(":", 1)[0]  # "argument command" or "argument --moduli"
        for action in self._actions:
            names = [*action.option_strings, action.dest, str(action.metavar)]
            if action.choices is not None and any(head == f"argument {n}" for n in names):
                return did_you_mean(m.group(1), list(action.choices))
        return ""


def _subcommand_parser(parser: argparse.ArgumentParser, command: str | None):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction) and command in action.choices:
            return action.choices[command]
    return parser


def refuse_unknown(parser: argparse.ArgumentParser, command: str | None, extra: list[str]):
    """Exit 2 for arguments the command does not know, naming the closest options of the command.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The ``cfm`` parser (built by :func:`cfm_core.cli.app.build_parser`).
    command : str or None
        The subcommand that was parsed.
    extra : list of str
        The arguments left over by ``parse_known_args``.

    Raises
    ------
    SystemExit
        Always, with status 2, after one paragraph on stderr.
    """
    sub = _subcommand_parser(parser, command)
    options = {s.lstrip("-"): s for a in sub._actions for s in a.option_strings if s.startswith("--")}
    hints = []
    for token in extra:
        if token.startswith("-"):
            name = token.split("=", 1)[0]
            close = did_you_mean(name.lstrip("-"), options)  # the names without "--", which all share
            for bare, full in options.items():
                close = close.replace(repr(bare), repr(full))
            hints.append(f"{name}: {close[0].lower()}{close[1:]}" if close else f"{name}: no such option")
    text = f"unrecognized arguments: {' '.join(extra)}"
    if hints:
        text += " (" + "; ".join(hints) + ")"
    sub.error(text)


def version_text() -> str:
    """``cfm-materials X.Y.Z (Python A.B.C)`` and one line per backend with its kind and availability."""
    try:
        version = metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        version = "unknown (not installed)"
    lines = [f"{DISTRIBUTION} {version} (Python {platform.python_version()})", "backends:"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        entries = plugins.entries("backends")
    for name, (cls, err) in entries.items():
        if err:
            lines.append(f"  {name:<8} BROKEN: {err}")
            continue
        ok, why = cls().available()
        lines.append(f"  {name:<8} {cls.kind:<12} {'available' if ok else 'unavailable: ' + why}")
    return "\n".join(lines)


class VersionAction(argparse.Action):
    """``--version``: print :func:`version_text` (computed only when asked) and exit 0."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help=None):
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(version_text(), file=sys.stdout)
        parser.exit(0)
