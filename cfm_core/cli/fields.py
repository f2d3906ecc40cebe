"""``--vtu``, ``--fields``, ``--full`` of the run commands and ``cfm fields RUN_DIR``: a cut view."""

from __future__ import annotations

from ..errors import InputError
from ..post.cutview import SCALARS, render_cut
from ..post.fields import FIELDS, parse_fields
from ..post.staging import adopt, check_file_target


def add_vtu_options(p) -> None:
    """Add ``--vtu``, ``--fields`` and ``--full`` to a run command's parser."""
    p.add_argument("--vtu", action="store_true",
                   help="also write the deformed specimen with stress/strain fields and the impactor over time "
                        "(ParaView specimen.pvd, units in each array's name and fields.json)")
    p.add_argument("--fields", metavar="A,B,...",
                   help=f"fields of --vtu, comma-separated or 'all' (default: all): {', '.join(FIELDS)}")
    p.add_argument("--full", action="store_true",
                   help="with --vtu: mirror a quarter (or half) model into the whole specimen (shear components "
                        "change sign across the mirror planes)")


def check_vtu_options(args, scene) -> tuple:
    """(fields, full) of the command line, checked before the run.

    Raises
    ------
    InputError
        --fields or --full without --vtu, an unknown field, --full for a specimen modelled whole
        (``symmetry = "none"``), or --vtu for a scene that is not a drop test.
    """
    vtu, fields, full = getattr(args, "vtu", False), getattr(args, "fields", None), getattr(args, "full", False)
    if not vtu:
        if fields is not None or full:
            raise InputError("--fields and --full choose what --vtu writes; add --vtu.")
        return None, False
    if scene.type != "drop-test":
        raise InputError(f"--vtu writes the specimen of a drop test; scene type {scene.type!r} has none "
                         f"(its reaction.csv holds the response).")
    if full and getattr(scene.specimen, "symmetry", None) == "none":
        raise InputError("--full mirrors a quarter or half model; this specimen's symmetry is 'none', already "
                         "the whole specimen.")
    return parse_fields(fields), full


def add_parser(sub) -> None:
    p = sub.add_parser("fields", help="draw a field of a --vtu run on a cut plane at a time (PNG)",
                       description="Draw one element field of a run written with --vtu on the plane y = 0 "
                                   "(through the impact point) at the stored frame nearest --at, deformed, with "
                                   "a colour bar in SI units (stresses in kPa) and the impactor's outline.")
    p.add_argument("run_dir", metavar="RUN_DIR", help="output folder of a run with --vtu")
    p.add_argument("--at", type=float, required=True, help="time, s, finite and 0 or more (the nearest stored "
                                                            "frame is drawn)")
    p.add_argument("--field", default="von_mises", help=f"the field (default von_mises): {', '.join(SCALARS)}")
    p.add_argument("--png", required=True, help="output image")
    p.add_argument("--y", type=float, default=0.0, help="cut plane y position, m (default 0), within the specimen; "
                                                         "a quarter or half run is mirrored about y = 0, so a "
                                                         "negative y draws its mirror image")


def cmd_fields(args) -> int:
    check_file_target(args.png, "--png", suffix=".png")
    info = render_cut(args.run_dir, args.at, args.field, args.png, y_cut=args.y)
    adopt(args.png, [args.run_dir])  # into the run's folder: it goes with the run when a later output replaces it
    print(f"{args.field} at t = {1e3 * info['t']:.3f} ms ({info['file']}): {info['min']:.4g} .. {info['max']:.4g} "
          f"{info['unit']}; wrote {args.png}")
    return 0


COMMANDS = {"fields": cmd_fields}
