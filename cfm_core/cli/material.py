"""``cfm materials``, ``cfm backends`` and ``cfm point`` (the material-point driver)."""

from __future__ import annotations

import sys
import warnings

from .. import plugins
from ..errors import InputError
from ..material.plausible import check_material
from ..material.registry import make_material
from ..post.plots import plot_uniaxial
from ..post.writers import write_csv
from ..simulation import point
from ..simulation.registry import backend_for
from ..studies.outcomes import point_targets, stale_plot, uniaxial_title
from ..tables import check_count, unit_header
from .options import add_material_options, parse_params

#: Most steps of the --uniaxial loading ramp (about 2 ms each: 100 000 take a few minutes).
STEPS_MAX = 100_000
#: --steps and --hold of the --uniaxial ramp when not given (-, s).
STEPS_DEFAULT = 200
HOLD_DEFAULT = 0.0
#: The options of --uniaxial alone (argparse dest, flag): their defaults are None (False for --no-plot), so
#: that one the user typed with --history, where it would be ignored, is told from one not given.
UNIAXIAL_ONLY = (("rate", "--rate"), ("stretch", "--stretch"), ("steps", "--steps"), ("hold", "--hold"),
                 ("no_plot", "--no-plot"))


def _entries(kind: str) -> dict:
    """Registry entries without RuntimeWarnings: broken plugins are shown in the listing itself."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return plugins.entries(kind)


def _cmd_materials(args) -> int:
    for name, (spec, err) in _entries("materials").items():
        if err:
            print(f"{name}: BROKEN ({err})\n")
            continue
        print(f"{name}: {spec.description}")
        for p in spec.parameters:
            print(f"    {p.name:<8} = {p.default:<12g} {p.unit:<3} range {p.range_text():<22} {p.description}")
        print()
    return 0


def _cmd_backends(args) -> int:
    for name, (cls, err) in _entries("backends").items():
        if err:
            print(f"{name:<8} BROKEN       {err}")
            continue
        ok, why = cls().available()
        status = "available" if ok else f"unavailable: {why}"
        print(f"{name:<8} {cls.kind:<12} {status}  ({cls.description})")
        options = getattr(cls, "options_class", None)
        if getattr(args, "options", False):
            table = options.table() if options is not None else "(no options declared)"
            print("\n".join("    " + line for line in table.splitlines()) + "\n")
    return 0


def _step_bar(total: int):
    """A progress bar of the uniaxial driver's steps on stderr (off when stderr is no terminal); shown
    from :data:`BAR_STEPS` steps on, where a run takes more than a few seconds."""
    from tqdm import tqdm

    return tqdm(total=total, desc="uniaxial", unit="step", file=sys.stderr, leave=False,
                disable=None if total >= BAR_STEPS else True)


#: Steps of the uniaxial driver from which a progress bar is shown (100 000 steps took 3.5 minutes).
BAR_STEPS = 5_000


def _check_mode(args) -> None:
    """One of --uniaxial and --history, and no option of --uniaxial with --history (it would be ignored)."""
    if args.uniaxial and args.history:
        raise InputError("--uniaxial and --history exclude each other: give one of them.")
    if not args.history:
        return
    values = [(flag, getattr(args, dest)) for dest, flag in UNIAXIAL_ONLY]
    typed = [(flag, v) for flag, v in values if v is not None and v is not False]  # by identity: 0 == False
    if typed:
        flags = ", ".join(flag for flag, _ in typed)
        given = " ".join(flag if value is True else f"{flag} {value!r}" for flag, value in typed)
        shape, them = ("they shape", "them") if len(typed) > 1 else ("it shapes", "it")
        raise InputError(f"{flags}: only with --uniaxial, whose loading {shape} (given: {given}); --history "
                         f"{args.history} takes the deformation and its times from the file, and would ignore "
                         f"{them}. Drop {them}, or give --uniaxial instead of --history.")


def _cmd_point(args) -> int:
    _check_mode(args)
    steps = STEPS_DEFAULT if args.steps is None else args.steps
    hold = HOLD_DEFAULT if args.hold is None else args.hold
    if args.uniaxial:
        check_count("--steps", steps, 2, STEPS_MAX, "steps of the --uniaxial loading ramp")
    material = make_material(args.material, parse_params(args.param), args.moduli, args.elastic)
    for text in check_material(material):  # unit slips (k1 = 1.32 for 1.32 kPa), Poisson ratio far from 0.5
        print(f"warning: {text}", file=sys.stderr)
    plot = bool(args.uniaxial and not args.no_plot)
    # Every file, before the work and before any is written: a directory, a file as parent, unwritable, a file
    # that cannot be replaced, the input itself, a PNG of that name cfm did not write.
    _, png = point_targets(args.out, plot, "--out", suffix=".csv", inputs=[args.history] if args.history else [])
    if args.uniaxial:
        if args.rate is None or args.stretch is None:
            raise InputError("--uniaxial needs --rate (engineering strain rate, 1/s) and --stretch (final stretch, -).")
        with warnings.catch_warnings(record=True) as caught:  # printed as the run checks' warnings are
            warnings.simplefilter("always", RuntimeWarning)
            with _step_bar(steps * (2 if hold > 0 else 1) + 1) as bar:
                t, lam, P, lat = point.uniaxial(material, args.rate, args.stretch, steps, hold,
                                                progress=lambda done, total: bar.update(done - bar.n))
        for w in caught:
            print(f"warning: {w.message}", file=sys.stderr)
        source = "numpy reference"
        if args.backend not in (None, "numpy"):
            P, residual = point.uniaxial_on_backend(material, backend_for(args.backend), t, lam, lat)
            source = f"backend {args.backend} along the reference's path (lateral stress {residual:.1e} of the axial)"
        write_csv(args.out, unit_header(point.UNIAXIAL_UNITS), [t, lam, P, lat])
        written = [str(args.out)]
        stale = stale_plot(png, "--no-plot wrote no plot of this one (remove it, or run without --no-plot)")
        if args.no_plot and stale:
            print(f"warning: {stale}", file=sys.stderr)
        if not args.no_plot:
            plot_uniaxial(png, lam, P, uniaxial_title(material, args.rate, source))
            written.append(str(png))
        print(f"wrote {', '.join(written)}: {t.size} rows (t s, stretch -, nominal stress Pa, lateral stretch -), {source}")
        return 0
    if not args.history:
        raise InputError("give --history F.csv (header t,F11,...,F33) or --uniaxial --rate R --stretch L.")
    t, F = point.read_history(args.history)
    backend = backend_for(args.backend) if args.backend else None
    with warnings.catch_warnings(record=True) as caught:  # printed as the run checks' warnings are
        warnings.simplefilter("always", RuntimeWarning)
        sigma = point.run_history(material, t, F, backend)
    for w in caught:
        print(f"warning: {w.message}", file=sys.stderr)
    write_csv(args.out, unit_header(point.STRESS_UNITS), [t] + [sigma[:, k] for k in range(6)])
    stale = stale_plot(png, "a --history run writes no plot, and its stress-stretch curve no longer matches "
                            f"{args.out} (remove it)")
    if stale:
        print(f"warning: {stale}", file=sys.stderr)
    print(f"wrote {args.out}: {t.size} rows of Cauchy stress (Pa)")
    return 0



def add_parser(sub) -> None:
    """Add ``materials``, ``backends`` and ``point`` to the ``cfm`` subcommands."""
    sub.add_parser("materials", help="list materials with their parameters (units, defaults, ranges)")
    b = sub.add_parser("backends", help="list backends: kind and availability")
    b.add_argument("--options", action="store_true",
                   help="also list each backend's run options (name, default, unit, meaning, allowed values)")
    p = sub.add_parser("point", help="material-point driver: Cauchy stress along F(t), or uniaxial stress")
    add_material_options(p)
    p.add_argument("--backend", default=None, help="backend evaluating the stress (default: the numpy reference); "
                                                    "with --uniaxial, along the reference's uniaxial path")
    p.add_argument("--history", help="CSV with header t,F11,F12,F13,F21,F22,F23,F31,F32,F33 (t in s)")
    p.add_argument("--uniaxial", action="store_true", help="uniaxial stress, lateral tractions zero")
    p.add_argument("--rate", type=float, help="engineering strain rate for --uniaxial, 1/s")
    p.add_argument("--stretch", type=float, help="final stretch for --uniaxial, dimensionless (e.g. 0.5)")
    p.add_argument("--steps", type=int, default=None, help=f"steps of the loading ramp for --uniaxial, a whole number "
                                                            f"from 2 to {STEPS_MAX} (-, default {STEPS_DEFAULT})")
    p.add_argument("--hold", type=float, default=None,
                   help=f"hold time at the final stretch for --uniaxial, s (default {HOLD_DEFAULT:g})")
    p.add_argument("--no-plot", action="store_true", help="--uniaxial: do not write the stress-stretch PNG next to --out")
    p.add_argument("--out", required=True, help="output CSV (header t [s],s11 [Pa],...,s13 [Pa]; or t [s],stretch [-],nominal_stress [Pa],"
                                                 "lateral_stretch [-])")


COMMANDS = {"materials": _cmd_materials, "backends": _cmd_backends, "point": _cmd_point}
