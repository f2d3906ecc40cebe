"""Command-line interface: ``cfm materials | backends | point | drop-test``.

User mistakes (InputError) print one paragraph and exit 2; numerical failures (NumericalError)
print where and when and exit 3. No traceback for either, and no partial output file.
"""

from __future__ import annotations

import argparse
import sys

from .errors import InputError, NumericalError


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


def _entries(kind: str) -> dict:
    """Registry entries without RuntimeWarnings: broken plugins are shown in the listing itself."""
    import warnings

    from . import registry

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return registry.entries(kind)


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
    return 0


def _cmd_point(args) -> int:
    from . import point
    from .material import make_material
    from .registry import get_backend
    from .writers import write_csv

    material = make_material(args.material, parse_params(args.param), args.moduli, args.elastic)
    if args.uniaxial:
        if args.history:
            raise InputError("--uniaxial and --history exclude each other: give one of them.")
        if args.rate is None or args.stretch is None:
            raise InputError("--uniaxial needs --rate (engineering strain rate, 1/s) and --stretch (final stretch, -).")
        if args.backend not in (None, "numpy"):
            raise InputError(f"--uniaxial runs on the numpy reference only; drop --backend {args.backend}.")
        t, lam, P, lat = point.uniaxial(material, args.rate, args.stretch, args.steps, args.hold)
        write_csv(args.out, point.UNIAXIAL_HEADER, [t, lam, P, lat])
        print(f"wrote {args.out}: {t.size} rows (t s, stretch -, nominal stress Pa, lateral stretch -)")
        return 0
    if not args.history:
        raise InputError("give --history F.csv (header t,F11,...,F33) or --uniaxial --rate R --stretch L.")
    t, F = point.read_history(args.history)
    backend = get_backend(args.backend) if args.backend else None
    if backend is not None:
        ok, why = backend.available()
        if not ok:
            raise InputError(f"backend '{args.backend}' is not available: {why}.")
    sigma = point.run_history(material, t, F, backend)
    write_csv(args.out, point.STRESS_HEADER, [t] + [sigma[:, k] for k in range(6)])
    print(f"wrote {args.out}: {t.size} rows of Cauchy stress (Pa)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="cfm", description="Circular fiber model framework (SI units: m, s, kg, Pa).")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("materials", help="list materials with their parameters (units, defaults, ranges)")
    sub.add_parser("backends", help="list backends: kind and availability")
    p = sub.add_parser("point", help="material-point driver: Cauchy stress along F(t), or uniaxial stress")
    add_material_options(p)
    p.add_argument("--backend", default=None, help="backend for --history (default: numpy reference)")
    p.add_argument("--history", help="CSV with header t,F11,F12,F13,F21,F22,F23,F31,F32,F33 (t in s)")
    p.add_argument("--uniaxial", action="store_true", help="uniaxial stress, lateral tractions zero")
    p.add_argument("--rate", type=float, help="engineering strain rate for --uniaxial, 1/s")
    p.add_argument("--stretch", type=float, help="final stretch for --uniaxial, dimensionless (e.g. 0.5)")
    p.add_argument("--steps", type=int, default=200, help="steps of the loading ramp for --uniaxial (default 200)")
    p.add_argument("--hold", type=float, default=0.0, help="hold time at the final stretch for --uniaxial, s")
    p.add_argument("--out", required=True, help="output CSV (t,s11,s22,s33,s12,s23,s13 in s and Pa; or t,stretch,nominal_stress,lateral_stretch)")
    from . import scene_cli, study_cli

    scene_cli.add_parser(sub)
    study_cli.add_parser(sub)
    v = sub.add_parser("verify", help="cross-backend verification suite: agreement, work-precision, stability, "
                                      "paper comparison; writes report.md, report.json and PNGs; exit 1 if a check fails")
    mode = v.add_mutually_exclusive_group()
    mode.add_argument("--quick", action="store_true", help="small scenes, CI-sized (default)")
    mode.add_argument("--full", action="store_true", help="full-size drop tests at 5-8 mm, meshes down to 0.5 mm")
    v.add_argument("--backends", default=None, metavar="NAME,...", help="only these backends (default: all installed)")
    v.add_argument("--budget", type=float, default=None, metavar="SECONDS",
                   help="solver time per backend for the scene runs and for the work-precision runs, s "
                        "(default 600/20 quick, 3600/3600 full); runs estimated to exceed it are listed as skipped")
    v.add_argument("--out", required=True, help="output directory for report.md, report.json and figures")
    return parser


def _cmd_verify(args) -> int:
    from cfm_verification.suite import cli as verify_cli  # imported lazily: runs solvers

    return verify_cli(args)


COMMANDS = {"materials": _cmd_materials, "backends": _cmd_backends, "point": _cmd_point, "verify": _cmd_verify}


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from . import scene_cli, study_cli

    handler = COMMANDS.get(args.command) or {**scene_cli.COMMANDS, **study_cli.COMMANDS}[args.command]
    try:
        return handler(args)
    except InputError as exc:
        print(f"cfm {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except NumericalError as exc:
        print(f"cfm {args.command}: numerical failure: {exc}", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print(f"cfm {args.command}: interrupted; no result written.", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
