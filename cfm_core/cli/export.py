"""``cfm export``: a material as a Fortran user material for Abaqus or LS-DYNA."""

from __future__ import annotations

import argparse
import sys

from ..export import TARGETS, check_density, export, layout, lsdyna
from ..material.plausible import check_material
from ..material.registry import make_material
from ..scene.plausible import density_warning
from .options import parse_params, typed


def _number(text: str) -> str:
    """A number's text, kept as typed (``--density 1e400`` reads as inf: the message names 1e400)."""
    try:
        float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid float value: {text!r}") from None
    return text


def add_parser(sub) -> None:
    """Add the ``export`` subcommand.

    Parameters
    ----------
    sub : argparse subparsers object
        Where the ``export`` parser is added.
    """
    p = sub.add_parser(
        "export", help="write a material as a Fortran user material (Abaqus UMAT/VUMAT, LS-DYNA umat41/utan41)",
        description="Generate a Fortran user material from the material's single definition (energy terms, "
                    "Prony series, moduli convention): the source (fixed form, double precision), a ready "
                    "material card with the material's values (SI units: m, s, kg, Pa) and manifest.json "
                    "(constants, state variables, calling convention). Targets: " + "; ".join(
                        f"{k}: {v['solver']}" for k, v in TARGETS.items()) + ". Verified through each "
                    "solver's calling convention by the project's gfortran harness; not run in the "
                    "commercial solvers here.")
    p.add_argument("material", help="registered material name (see 'cfm materials'), e.g. cfm")
    p.add_argument("--to", required=True, choices=list(TARGETS), help="target solver interface")
    p.add_argument("--out", required=True, help="output folder (new, or holding an earlier cfm output)")
    p.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="a value for the example card, SI units (Pa, s, -); repeatable. The source reads every "
                        "constant from the card, so one build serves every parameter set")
    p.add_argument("--moduli", choices=["instantaneous", "long-term"], default=None,
                   help="moduli convention written on the card (constant 'moduli'); default: the material's")
    p.add_argument("--elastic", action="store_true", help="card with the Prony coefficients g_i = 0")
    p.add_argument("--density", type=_number, default=None,
                   help="density on the explicit cards (VUMAT *DENSITY, LS-DYNA RO), kg/m^3, 1 to 100000 (default "
                        "950); like every value of the card in SI units: docs/user/export.md gives the factors to "
                        "mm-s-tonne and mm-ms-kg models")


def _cmd_export(args) -> int:
    density = None if args.density is None else check_density(float(args.density), typed(args.density))
    material = make_material(args.material, parse_params(args.param), args.moduli, args.elastic)
    for text in check_material(material):  # unit slips (k1 = 1.32 for 1.32 kPa) go into the card as given
        print(f"warning: {text}", file=sys.stderr)
    slip = density_warning("--density", density, option="--density",  # g/cm^3 (1.06 for 1060), or unusual
                           as_given="the card holds it as given") if density is not None else None
    if slip:
        print(f"warning: {slip}", file=sys.stderr)
    rounding = (lsdyna.gamma_inf_warning(layout.constants(material.spec, lsdyna=True, material=material))
                if args.to == "lsdyna-umat" else None)
    if rounding:
        print(f"warning: {rounding}", file=sys.stderr)
    files = export(material, args.to, args.out, density)
    print(f"wrote {', '.join(str(f) for f in files)}: {material.name} for {TARGETS[args.to]['solver']}")
    return 0


COMMANDS = {"export": _cmd_export}
