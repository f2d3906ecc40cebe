"""``cfm calculix build``: CalculiX (ccx 2.20) from Debian's source package with the generated UMATs linked in."""

from __future__ import annotations

import time

from ..simulation.registry import get_backend


def add_parser(sub) -> None:
    """Add the ``calculix`` subcommand (``cfm calculix build``).

    Parameters
    ----------
    sub : argparse subparsers object
        Where the ``calculix`` parser is added.
    """
    p = sub.add_parser("calculix", help="build CalculiX with the generated UMATs (the 'calculix' backend)",
                       description="CalculiX for the 'calculix' backend.")
    actions = p.add_subparsers(dest="calculix_action", required=True)
    b = actions.add_parser(
        "build", help="fetch, build and cache ccx 2.20 with the generated Abaqus UMATs linked in",
        description="apt-get source calculix-ccx and its build dependencies (apt-get build-dep, as root; a "
                    "deb-src entry for the configured Debian archive is added when missing), compile CalculiX "
                    "once (about 10-25 minutes on 2 cores), then compile the generated UMAT of each material with "
                    "the project's adaptor and link ccx (seconds), into the cache (~/.cache/cfm/calculix/<key>, "
                    "key: the UMATs' code). Prints the time it took.")
    b.add_argument("--material", action="append", metavar="NAME",
                   help="registered material whose UMAT is linked in; repeatable (default: cfm and neo-hookean)")


def _cmd_calculix(args) -> int:
    t0 = time.perf_counter()
    say = lambda line: print(f"[{time.perf_counter() - t0:7.1f} s] {line}", flush=True)  # noqa: E731
    rec = get_backend("calculix").build(args.material, say=say)
    state = "already built" if rec["cached"] else "built"
    print(f"{state}: {rec['ccx']} (CalculiX {rec['version']}, UMATs: {', '.join(rec['materials'])}) in "
          f"{rec['seconds']:.1f} s (CalculiX library {rec.get('library_seconds', 0.0):.1f} s, UMATs and link "
          f"{rec.get('link_seconds', 0.0):.1f} s when built)")
    return 0


COMMANDS = {"calculix": _cmd_calculix}
