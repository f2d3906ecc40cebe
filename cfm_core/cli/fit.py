"""``cfm fit``: fit a registered material to laboratory tests (stress-strain curves of a testing machine).

One command per user job: the tests (``--test FILE:KIND:RATE[:WEIGHT]``), the parameters to fit
(``--fit``) and the material; writes fit.json, fit_<test>.png and fitted-scene.toml (a drop-test
scene with the fitted material, for ``cfm drop-test --scene`` and ``cfm calibrate --scene``).
Method and file formats: :mod:`cfm_core.studies.fit`, :mod:`cfm_core.studies.lab_tests`.
"""

from __future__ import annotations

import sys

from ..errors import InputError
from ..material.plausible import check_material
from ..material.registry import make_material
from ..scene.scene import load_scene
from ..studies import fit as lab_fit
from ..studies.lab_tests import KINDS
from ..post.staging import check_folder_target, published_files, refuse_inputs
from ..tables import check_count
from .options import EVALUATIONS_MAX, add_material_options, parse_params

#: Most starting points ``--starts`` allows.
STARTS_MAX = 1000


def add_parser(sub) -> None:
    """Add the ``fit`` subcommand to ``sub`` (an argparse subparsers object)."""
    kinds = "; ".join(f"{k}: {v[1]}" for k, v in KINDS.items())
    p = sub.add_parser("fit", help="fit a material's parameters to laboratory tests (stress-strain curves)",
                       description="Least-squares fit of a registered material's parameters (Prony terms "
                                   "included) to material tests, each a CSV with header t,stretch,stress (or "
                                   "t,shear,stress for simple shear) in s, -, Pa (nominal stress). Kinds: "
                                   f"{kinds}. Writes fit.json (values, 95 % intervals, correlations, "
                                   "identifiability warnings), fit_<test>.png and fitted-scene.toml into --out.")
    add_material_options(p)
    p.add_argument("--test", action="extend", nargs="+", metavar="FILE:KIND:RATE[:WEIGHT]", required=True,
                   help="a test curve: CSV file, kind (" + ", ".join(KINDS) + "), the loading's engineering "
                        "strain (or shear) rate in 1/s, optional weight (-, default 1); repeatable")
    p.add_argument("--fit", required=True, action="append", metavar="NAME,...",
                   help="parameters to fit, e.g. c,k1,k2 or k1,k2,prony (prony = every g_i, tau_i); repeatable; "
                        "--param sets the start of these and the value of the others (SI units)")
    p.add_argument("--scene", help="drop-test scene TOML that fitted-scene.toml is based on (default: built-in)")
    p.add_argument("--max-evaluations", type=int, default=400,
                   help=f"most evaluations of the optimiser per start (the finite-difference Jacobian's not counted), "
                        f"a whole number from 1 to "
                        f"{EVALUATIONS_MAX} (-, default 400; recorded in fit.json)")
    p.add_argument("--starts", type=int, default=None,
                   help=f"starting points of the optimiser, a whole number from 1 to {STARTS_MAX} (-, default 6 "
                        f"when a Prony time is fitted, else 1)")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.add_argument("--out", required=True, help="output directory")


def _cmd_fit(args) -> int:
    from ..studies.api import fit as run

    check_count("--max-evaluations", args.max_evaluations, 1, EVALUATIONS_MAX,
                "most residual evaluations of the optimiser per start")
    if args.starts is not None:
        check_count("--starts", args.starts, 1, STARTS_MAX, "starting points of the optimiser")
    check_folder_target(args.out)
    names = lab_fit.fit_names(",".join(args.fit), args.material)
    given = parse_params(args.param)
    start = {k: v for k, v in given.items() if k in names}
    fixed = {k: v for k, v in given.items() if k not in names}
    for text in check_material(make_material(args.material, given, args.moduli, args.elastic)):
        print(f"warning: {text}", file=sys.stderr)  # unit slips of the fixed values and the starting point
    if args.scene:  # its errors, and fitted names no layer takes, before the work
        based_on = load_scene(args.scene)
        if based_on.type != "drop-test":
            raise InputError(f"--scene {args.scene}: a '{based_on.type}' scene; fitted-scene.toml is a drop-test scene "
                             f"with the fitted material, so --scene must be a drop-test scene file (or left out for "
                             f"the built-in drop test).")
        lab_fit.check_scene(based_on, names)
    tests = lab_fit.read_tests(args.test)
    refuse_inputs(args.out, [args.scene, *(t.path for t in tests)])  # before the work is announced
    say = None if args.quiet else (lambda line: print(line, file=sys.stderr, flush=True))
    if say:
        say(f"fitting {', '.join(names)} of '{args.material}' to {len(tests)} test(s)")
    outcome = run(args.material, tests, names, start, fixed, args.moduli, args.elastic, args.max_evaluations,
                  args.starts, args.scene, args.out, say or False)  # the file: an input, never removed
    result = outcome.result
    conf = result.confidence["parameters"]
    for n, u in zip(result.coords.names, result.coords.units):
        ci = conf[n]["ci"]
        ci_text = f"[{ci[0]:.5g}, {ci[1]:.5g}]" if ci else "withheld (see the warnings)"
        print(f"{n:<6} = {result.fitted[n]:<12.6g} {u:<3} start {result.start[n]:<10.5g} 95 % CI {ci_text}")
    for t, e in zip(result.tests, result.rel_rms()):
        print(f"{t.name}: {t.kind} at {t.rate:g} 1/s, rel. RMS {100 * e:.2f} %")
    for w in result.warnings:
        print(f"WARNING: {w}")
    print(f"{result.evaluations} optimiser evaluation(s) (--max-evaluations {args.max_evaluations} per start; "
          f"{result.residual_evaluations} residual evaluations in all, the start's and the finite-difference "
          f"Jacobian's included), {result.wall:.1f} s; {result.status}")
    print(f"wrote {args.out}: {', '.join(published_files(args.out))}")
    return 0


COMMANDS = {"fit": _cmd_fit}
