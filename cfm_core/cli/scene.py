"""``cfm drop-test`` (the main job) and ``cfm run`` (any scene file)."""

from __future__ import annotations

import sys
from pathlib import Path

from ..errors import InputError
from ..post import figure_process
from ..post.staging import staged_folder
from ..runs.provenance import scene_paths
from ..runs import pipeline
from ..runs.outcomes import output_bytes
from ..scene.builder import check_history_size
from ..scene.layers import refuse_unused
from ..scene.scene import builtin_scene, builtin_scenes
from ..post.fields import parse_fields
from .fields import add_vtu_options, check_vtu_options
from .options import add_material_options, parse_params, plan_from_args, scene_named


def add_parser(sub) -> None:
    p = sub.add_parser("drop-test", help="the paper's drop test: impactor acceleration history (CFC 600)",
                       description="Rigid hemispherical impactor on a fat specimen on a rigid plate (SI units). "
                                   "Writes acceleration.csv (t s, a_raw and a_cfc600 m/s^2), summary.json and "
                                   "acceleration.png into --out.")
    p.add_argument("--scene", help="drop-test scene TOML file, or a built-in drop-test scene's name (drop-test, "
                                   "flat-impactor, layered-tissue; default: drop-test)")
    p.add_argument("--backend", default=None, help="backend name (default: the scene's [run] backend, else numba; "
                                                   "see 'cfm backends')")
    p.add_argument("--device", help="device for backends that have a choice (torch: cpu, cuda or cuda:N; default cpu)")
    p.add_argument("--dtype", choices=["float64", "float32"],
                   help="floating-point type for backends that have a choice (torch; default float64)")
    p.add_argument("--option", action="append", metavar="NAME=VALUE",
                   help="a backend option in SI units, repeatable (e.g. hourglass=0.05, safety=0.5, linear_solver=direct; "
                        "'cfm backends --options' lists them with units and ranges)")
    p.add_argument("--thickness", type=float, help="specimen thickness, m (paper: 0.0048 .. 0.0083; default 0.008)")
    p.add_argument("--element-size", type=float, help="hexahedron edge, m (default 0.001)")
    p.add_argument("--velocity", type=float, help="impact speed, m/s (default 1.0)")
    p.add_argument("--mass", type=float, help="impactor mass, kg (default 0.220; 220 g is 0.220, not 220)")
    p.add_argument("--radius", type=float, help="impactor (hemisphere) radius, m (default 0.055)")
    p.add_argument("--width", type=float, help="specimen width (square), m (default 0.050)")
    p.add_argument("--density", type=float, help="specimen density, kg/m^3 (default 950, an assumption)")
    p.add_argument("--mesh", help="hexahedral specimen mesh file, coordinates in m: an Abaqus .inp (read by cfm's "
                                  "own reader) or a format meshio reads (.vtu, .msh, ...); replaces the structured "
                                  "mesh, and width and thickness come from it")
    p.add_argument("--friction", type=float, help="Coulomb friction coefficient on both contacts, - (default 0)")
    p.add_argument("--symmetry", choices=["auto", "quarter", "half", "none"],
                   help="auto (default: quarter for a centred vertical impact, half (y >= 0) when only y is "
                        "symmetric, else none), quarter, half or the full specimen (none)")
    add_material_options(p, default_material=None)
    add_vtu_options(p)
    p.add_argument("--no-plot", action="store_true", help="do not write acceleration.png")
    _add_output_options(p)
    add_run_parser(sub)


def _add_output_options(p) -> None:
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.add_argument("--no-overwrite", action="store_true",
                   help="refuse an --out folder that holds an earlier run (default: its files are replaced; files "
                        "cfm did not write are always kept)")
    p.add_argument("--out", required=True, help="output directory (checked before the run; written whole when the "
                                                "run succeeded)")


def scene_from_args(args):
    """The scene of ``cfm drop-test`` with the command-line overrides applied."""
    scene = scene_named(args.scene) if args.scene else builtin_scene("drop-test")
    if scene.type != "drop-test":
        raise InputError(f"--scene {args.scene}: a '{scene.type}' scene; cfm drop-test runs drop-test scenes. Run "
                         f"this one with 'cfm run --scene {args.scene} --out DIR'.")
    return _apply_overrides(scene, args, ("thickness", "element_size", "velocity", "mass", "radius", "width", "density", "mesh",
                                         "friction", "symmetry"))


def _apply_overrides(scene, args, keys=()):
    """The scene with the command line's material options and the given scene keys applied
    (options left at None change nothing). Where the scene is a file, each value that changes what
    the file says gets a note on stderr (``--param k2=2.5 overrides scene.toml [material.parameters]
    k2 = 1.66``), as the backend options do: a repeat from a written scene.toml says how it differs."""
    over = {k: getattr(args, k) for k in (*keys, "material", "moduli") if getattr(args, k) is not None}
    if args.elastic:
        over["elastic"] = True
    params = parse_params(args.param)
    if params:
        over["parameters"] = params
    if not over:
        return scene
    keys_given = [k for k in ("density", "material", "moduli", "elastic") if k in over]
    refuse_unused(scene, [*keys_given, *params],
                  lambda name: f"--{name}" if name in keys_given else f"--param {name}", "the value would not be applied")
    if "material" in over and over["material"] != scene.material.name and scene.material.parameter_dict:
        scene = _without_foreign_parameters(scene, over["material"])
    new = scene.with_overrides(**over)
    if getattr(args, "scene", None) and Path(args.scene).exists():
        for text in _override_notes(scene, new, over, Path(args.scene).name):
            print(f"note: {text}", file=sys.stderr)
    return new


def _without_foreign_parameters(scene, material: str):
    """The scene without the [material] parameters that ``material`` (replacing the scene's material
    by --material) does not have: they were values of the other material (a cfm run's scene.toml
    holds c, k1, ...), and "material 'neo-hookean' has no parameter 'c'" blamed the user for them.
    Says on stderr which were left out; an unknown material name is left to the scene's own error."""
    from ..material.registry import get_material

    try:
        names = {p.name for p in get_material(material).parameters}
    except InputError:
        return scene
    given = scene.material.parameter_dict
    dropped = sorted(k for k in given if k not in names)
    if not dropped:
        return scene
    print(f"note: --material {material} replaces the scene's material '{scene.material.name}'; its parameters "
          f"{', '.join(dropped)}, which {material} does not have, are left out (give {material}'s own with --param).",
          file=sys.stderr)
    kept = {k: v for k, v in given.items() if k in names}
    return scene.with_overrides(parameters=None).with_overrides(parameters=kept)


def _override_notes(old, new, over: dict, where: str) -> list[str]:
    """What the command-line overrides ``over`` changed from scene ``old`` (a file named ``where``) to ``new``."""
    notes = []
    for key, value in over.items():
        if key == "parameters":
            was = old.material.parameter_dict
            for name, v in value.items():
                if name in was and was[name] != v:
                    notes.append(f"--param {name}={v:g} overrides {where} [material.parameters] {name} = {was[name]:g}")
                elif name not in was:  # the file ran with the material's default: say so too
                    default = _default_value(old.material.name, name)
                    if default is not None and default != v:
                        notes.append(f"--param {name}={v:g} overrides the default {name} = {default:g} that {where} "
                                     f"runs with (no [material.parameters] {name} there)")
            continue
        flag, attr = "--" + key.replace("_", "-"), "name" if key == "material" else key
        for section in ("material", "specimen", "impactor", "contact"):
            a, b = getattr(old, section, None), getattr(new, section, None)
            if a is not None and b is not None and hasattr(a, attr) and getattr(a, attr) != getattr(b, attr):
                shown = "" if key == "elastic" else f" {value}"
                vector = key == "velocity" and isinstance(getattr(a, attr), (tuple, list))
                notes.append(f"{flag}{shown} overrides {where} [{section}] {attr} = {list(getattr(a, attr)) if vector else getattr(a, attr)}"
                             + (": the impact is now vertical (the file's direction is dropped; to keep it, give "
                                "[impactor] velocity as a speed with an angle in the file)" if vector else ""))
                break
    return notes


def _default_value(material: str, name: str) -> float | None:
    """The default of parameter ``name`` of registered ``material`` (SI), None when either is unknown."""
    from ..material.registry import get_material

    try:
        return next((float(p.default) for p in get_material(material).parameters if p.name == name), None)
    except InputError:
        return None


def _run_and_write(args, scene) -> tuple:
    """Check --out, run the scene, write its files into a stage and publish them: (outcome, the
    --out folder, the names written). An unwritable, full or wrong-kind --out is refused before
    the run; a failed run leaves --out as it was."""
    plan = plan_from_args(args, scene)
    plot, vtu = not args.no_plot, getattr(args, "vtu", False)
    fields, full = check_vtu_options(args, scene)
    if not vtu and scene.type == "drop-test" and plan.options.get("frame_interval") is not None:
        # a repeat of a --vtu run: its [run] frame_interval stores frames, so they are written as its VTU was,
        # with the fields and mirroring its [run] records
        run = scene.run
        vtu, fields, full = True, parse_fields(run.fields if run else None), bool(run and run.full)
        print(f"note: the scene's [run] frame_interval = {plan.options['frame_interval']:g} s stores specimen "
              f"frames: they are written as VTU (specimen.pvd) with the fields {','.join(fields)}"
              f"{', mirrored into the whole specimen' if full else ''}, as by --vtu", file=sys.stderr)
    check_history_size(scene)   # before the free-space check: an end time of 5e5 s is the cause, not the disk
    need = output_bytes(scene, plan.options, plot=plot, vtu=vtu) * (4 if vtu and full else 1)
    with staged_folder(args.out, "--out", need_bytes=need, overwrite=not args.no_overwrite,
                       inputs=scene_paths(scene)) as stage, figure_process.started(plot):
        outcome = pipeline.run_planned(scene, plan, progress=not args.quiet)
        try:
            names = (outcome.write(stage, plot=plot, vtu=vtu, fields=fields, full=full) if scene.type == "drop-test"
                     else outcome.write(stage, plot=plot))
        except OSError as exc:  # a disk that filled up during the run, a folder removed meanwhile
            raise InputError(f"--out {args.out}: the run finished but its files could not be written "
                             f"({exc.strerror or exc}); nothing was published, --out is as it was.") from None
    return outcome, Path(args.out), names


def _drop_test(args, scene) -> int:
    """Run a drop-test scene and write acceleration.csv, scene.toml, the plot and summary.json (last)."""
    outcome, out, names = _run_and_write(args, scene)
    s = outcome.summary
    hourglass = "n/a" if s.get("hourglass_ratio") is None else f"{100 * s['hourglass_ratio'] + 0.0:.2f} %"
    hourglass = hourglass.replace("-0.00 %", "0.00 %")   # a round-off below zero (hourglass = 0) shown as 0
    energy = (f"energy error {100 * s['energy_error']:.2f} %" if "energy_error" in s
              else f"energy balance: not available ({s.get('energy_error_note', 'no energies recorded')})")
    print(f"peak {s['peak_g']:.1f} g at {1e3 * s['t_peak']:.2f} ms, contact {1e3 * s['duration']:.2f} ms, "
          f"{s['steps']} steps, {s['wall_time']:.2f} s solver, {energy}, hourglass/internal {hourglass}")
    print(f"wrote {out}/: {', '.join(names)}")
    return 0


def _cmd_drop_test(args) -> int:
    return _drop_test(args, scene_from_args(args))


def add_run_parser(sub) -> None:
    p = sub.add_parser("run", help="run any scene (drop-test, single-element, relaxation) on a backend",
                       description="Run a scene file or a built-in scene (SI units). Drop tests write "
                                   "acceleration.csv (t s, a_raw and a_cfc600 m/s^2); single-element and "
                                   "relaxation scenes write reaction.csv (t s, stretch -, reaction_force N, "
                                   "nominal_stress Pa); both write summary.json (last) and a PNG plot into --out.")
    p.add_argument("--scene", required=True,
                   help=f"scene TOML file, or a built-in scene name ({', '.join(builtin_scenes())})")
    p.add_argument("--backend", default=None,
                   help="backend name (default: skfem for the quasi-static relaxation scene, numba otherwise)")
    p.add_argument("--device", help="device for backends that have a choice (torch: cpu, cuda or cuda:N)")
    p.add_argument("--dtype", choices=["float64", "float32"], help="floating-point type (torch; default float64)")
    p.add_argument("--option", action="append", metavar="NAME=VALUE",
                   help="a backend option in SI units, repeatable ('cfm backends --options' lists them)")
    add_material_options(p, default_material=None)
    add_vtu_options(p)
    p.add_argument("--no-plot", action="store_true", help="do not write the PNG plot")
    _add_output_options(p)


def _scene_for_run(args):
    return _apply_overrides(scene_named(args.scene), args)


def _cmd_run(args) -> int:
    scene = _scene_for_run(args)
    if scene.type == "drop-test":
        return _drop_test(args, scene)
    outcome, out, names = _run_and_write(args, scene)
    s = outcome.summary
    print(f"largest |reaction force| {abs(s['peak_force']):.4g} N at {1e3 * s['t_peak_force']:.3g} ms, final "
          f"{s['final_force']:.4g} N ({100 * s['final_over_peak']:.2f} % of it); {s['steps']} steps, "
          f"{s['wall_time']:.2f} s solver")
    print(f"wrote {out}/: {', '.join(names)}")
    return 0


COMMANDS = {"drop-test": _cmd_drop_test, "run": _cmd_run, }
