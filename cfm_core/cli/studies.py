"""``cfm sweep`` (parameter studies) and ``cfm calibrate`` (fit to measured curves), on Dask.

Both run many drop tests through :func:`cfm_core.studies.dask_runner.open_runner`: a local Dask cluster
by default (``--workers N``, default: this machine's cores), an existing scheduler with
``--scheduler tcp://host:8786``, or a loop in this process with ``--serial``.
"""

from __future__ import annotations

import sys
import time

from ..errors import InputError
from ..post.staging import check_folder_target, published_files
from ..scene.scene import builtin_scene
from ..runs.pipeline import is_material_warning, warnings_once
from ..scene.plausible import check_plausible
from ..studies import calibrate, measured, sweep
from ..studies.dask_runner import WORKERS_PER_CORE, check_runner_options, max_local_workers, open_runner
from ..tables import check_count
from .options import EVALUATIONS_MAX, parse_params, plan_from_args, scene_named


def _runner_options(p) -> None:
    p.add_argument("--backend", default=None, help="backend name (default: the --scene file's [run] backend, else "
                                                   "numba; see 'cfm backends'); the file's dtype and options apply "
                                                   "too, --option overrides them")
    p.add_argument("--option", action="append", metavar="NAME=VALUE",
                   help="a backend option of every drop test, SI units, repeatable (e.g. hourglass=0.05; "
                        "'cfm backends --options' lists them); part of the run ids")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="Dask scheduler to run on, e.g. tcp://host:8786 ('none': serial); "
                            "default: a local Dask cluster")
    where.add_argument("--serial", action="store_true", help="run the drop tests one after another in this "
                                                             "process (no Dask)")
    p.add_argument("--workers", type=int, help=f"worker processes of the local Dask cluster, a whole number from 1 "
                                               f"to {max_local_workers()} (at most {WORKERS_PER_CORE} per core; default: "
                                               f"the number of cores)")
    p.add_argument("--worker-timeout", type=float, default=None, metavar="SECONDS",
                   help="with Dask: stop waiting after this many seconds with no worker left (the runs not "
                        "done fail with a message; finished runs are kept and a rerun resumes); default 30 s, below 1e6 s")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")


def add_parser(sub) -> None:
    p = sub.add_parser("sweep", help="parameter study: drop tests for every combination of values (Dask)",
                       description="Runs the drop test for the cartesian product of --vary values (scene values "
                                   "and material parameters, SI units) and writes sweep.csv (+ sweep.parquet), "
                                   "runs/<id>/acceleration.csv and summary.json, and peaks.png into --out. "
                                   "Rerunning skips the runs already complete.")
    p.add_argument("--scene", help="drop-test scene TOML file, or a built-in drop-test scene's name (drop-test, "
                                   "flat-impactor, layered-tissue; default: drop-test)")
    p.add_argument("--vary", action="append", metavar="NAME=V1,V2,...", required=True,
                   help="a scene value (thickness, velocity, element_size, width, mass, radius, density, "
                        "friction) or material parameter (c, k1, k2, kappa, g1, tau1, ...) and its values, "
                        "SI units; repeatable")
    _runner_options(p)
    p.add_argument("--yes", action="store_true",
                   help=f"start without asking when the sweep has more than {sweep.CONFIRM_RUNS} runs (asked only "
                        f"when run from a terminal; scripts proceed)")
    p.add_argument("--out", required=True, help="output directory (an earlier sweep's table and plot there are "
                                                "removed at the start; its runs/ cache is reused)")
    c = sub.add_parser("calibrate", help="fit material parameters to measured acceleration histories (Dask)",
                       description="Least-squares fit of material parameters to measured drop-test curves "
                                   "(CSV t,a in s and m/s^2, t = 0 at first contact), both filtered with CFC 600. "
                                   "Writes fit.json, fit_<curve>.png, objective.png and fitted-scene.toml "
                                   "into --out.")
    c.add_argument("--data", action="extend", nargs="+", metavar="FILE[:THICKNESS]", required=True,
                   help="measured curve, with the specimen thickness in m (e.g. drop5.csv:0.005); "
                        "without it the --scene file's thickness applies")
    c.add_argument("--fit", required=True, action="append", metavar="NAME,...",
                   help="parameters to fit, e.g. k1,k2 or k1,k2,prony (prony = g1,tau1); repeatable")
    c.add_argument("--scene", help="drop-test scene TOML file: impactor, velocity, mesh, fixed parameters; or a "
                                   "built-in drop-test scene's name (default: drop-test)")
    c.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="starting value of a fitted parameter, SI units (default: the scene's); repeatable")
    c.add_argument("--rel-step", type=float, default=None,
                   help="relative finite-difference step of the Jacobian (default 1e-3)")
    c.add_argument("--max-evaluations", type=int, default=60,
                   help=f"most objective evaluations of the optimiser, a whole number from 1 to {EVALUATIONS_MAX} "
                        f"(-, default 60; recorded in fit.json)")
    _runner_options(c)
    c.add_argument("--out", required=True, help="output directory")


def _scene(path):
    return scene_named(path) if path else builtin_scene("drop-test")


def _progress(args):
    if args.quiet:
        return None
    return lambda line: print(line, file=sys.stderr, flush=True)


def _planned(args, scene):
    """(the scene without its [run] section, backend, options) of a study's drop tests: the --scene
    file's [run] section overridden by --backend and --option, as ``cfm run`` plans a run (notes on
    stderr for what the command line changed; warnings for input files changed since)."""
    plan = plan_from_args(args, scene, default="numba")
    for text in plan.notes:
        print(f"note: {text}", file=sys.stderr)
    for text in plan.warnings:
        print(f"warning: {text}", file=sys.stderr)
    return scene.with_run(None), plan.backend, plan.options


def _runner_args(args) -> tuple:
    """(scheduler, workers, worker_timeout) of :func:`open_runner` from the command line."""
    return "none" if args.serial else args.scheduler, args.workers, args.worker_timeout


def _open(args):
    return open_runner(*_runner_args(args))


def _confirm(n: int, seconds: float, yes: bool) -> None:
    """Above :data:`sweep.CONFIRM_RUNS` runs from a terminal, ask before starting unless --yes.

    Not from a terminal (a script, a batch job), the sweep proceeds: it was written on purpose, and
    its log holds the count and the estimate printed before the first run."""
    if yes or n <= sweep.CONFIRM_RUNS or not sys.stdin.isatty():
        return
    try:
        answer = input(f"start {n} drop tests (about {_duration(seconds)})? [y/N] ")
    except EOFError:
        answer = ""
    if answer.strip().lower() not in ("y", "yes"):
        raise InputError(f"sweep of {n} runs not started (more than {sweep.CONFIRM_RUNS}); answer y, or add --yes "
                         f"to start without asking.")


def _duration(seconds: float) -> str:
    if seconds < 1:
        return "under 1 s"
    if seconds < 120:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h"


def _cmd_sweep(args) -> int:
    from ..studies.api import sweep as run

    check_runner_options(*_runner_args(args))  # --workers, --worker-timeout: before any work
    scene, backend, options = _planned(args, _scene(args.scene))
    axes = sweep.parse_vary(args.vary, scene)
    sweep.check_cases(scene, axes)  # every value, before any run (exit 2 naming it)
    sweep.run_key(scene, backend, options)  # backend and options checked too
    sweep.check_backend(scene, axes, backend)  # and what the backend accepts (skfem: no friction)
    out = check_folder_target(args.out, inputs=[args.scene])  # before any run; never removes the --scene file
    n = len(sweep.cases(axes))
    seconds = sweep.estimate_seconds(scene, axes)
    if not args.quiet or n > sweep.CONFIRM_RUNS:
        speed = "" if backend == "numba" else f" at numba's speed; {backend} runs at its own"
        print(f"sweep of {n} drop tests, about {_duration(seconds)} of serial runs (a rough estimate from the mesh "
              f"sizes{speed}; complete runs in {out}/runs are reused)", file=sys.stderr, flush=True)
    _confirm(n, seconds, args.yes)
    with _open(args) as runner:
        say = _progress(args)
        if say:
            say(f"running on {runner.label}")
        result = run(scene, {a.name: list(a.values) for a in axes}, backend, runner, out, say or False, options)
    print(f"{n} runs: {n - result.failed} complete ({result.skipped} from an earlier invocation), "
          f"{result.failed} failed; {result.wall:.1f} s")
    print("wrote " + ", ".join(str(f) for f in result.files) + f" and {out}/runs/")
    warned = sum(bool(r.get("warnings")) for r in result.rows if r["status"] == "ok")
    if warned:  # also for runs read back from an earlier invocation, whose warnings were said then
        print(f"warning: {warned} of {n} runs finished with warnings (e.g. a pulse cut short by the end time, "
              f"high hourglass energy); they are in the 'warnings' column of {out}/sweep.csv.", file=sys.stderr)
    if result.failed:
        print(f"cfm sweep: {result.failed} run(s) failed; their errors are in the 'error' column of "
              f"{out}/sweep.csv. Rerun the command to retry them (complete runs are skipped).", file=sys.stderr)
        return 1
    return 0


def _cmd_calibrate(args) -> int:
    from ..studies.api import calibrate as run

    check_count("--max-evaluations", args.max_evaluations, 1, EVALUATIONS_MAX,
                "most objective evaluations of the optimiser")
    check_runner_options(*_runner_args(args))  # --workers, --worker-timeout: before any work
    scene, backend, options = _planned(args, _scene(args.scene))
    names = calibrate.fit_names(",".join(args.fit), scene)
    start = parse_params(args.param)
    extra = sorted(set(start) - set(names))
    if extra:
        raise InputError(f"--param {', '.join(extra)}: only fitted parameters take a starting value here "
                         f"(fitted: {', '.join(names)}); set fixed values in the --scene file.")
    curves = measured.read_curves(args.data, scene, scene_given=args.scene is not None)
    check_folder_target(args.out, inputs=[args.scene, *(c.path for c in curves)])  # files it reads: never removed
    for text in check_plausible(scene.with_overrides(parameters=start)):  # the user's values, once: the fit's
        if is_material_warning(text):                                      # trial values are not said
            print(f"warning: {text}", file=sys.stderr)
    t0 = time.perf_counter()
    with _open(args) as runner, warnings_once(material=False):
        say = _progress(args)
        if say:
            say(f"fitting {', '.join(names)} to {len(curves)} curve(s) on {runner.label}")
        outcome = run(scene, curves, names, start, backend, runner, args.out, say or False, args.rel_step,
                      args.max_evaluations, options)
    result = outcome.result
    conf = result.confidence["parameters"]
    for n, u in zip(result.problem.coords.names, result.problem.coords.units):
        ci = conf[n]["ci"]
        ci_text = f"[{ci[0]:.5g}, {ci[1]:.5g}]" if ci else "not identifiable (J^T J singular)"
        if conf[n].get("withheld"):
            ci_text = ("withheld" if not ci else ci_text) + f" ({conf[n]['withheld']})"
        print(f"{n:<6} = {result.final.params[n]:<12.6g} {u:<3} start {result.start.params[n]:<10.5g} "
              f"95 % CI {ci_text}")
    for combo in result.confidence.get("identifiability", {}).get("combinations", []):
        (a, b), (_, k) = combo["parameters"], combo["coefficients"]
        print(f"determined (linearised at the fit): {a} + {k:.4g} {b} = {combo['value']:.6g}")
    for text in result.confidence.get("warnings", []):
        print(f"warning: {text}", file=sys.stderr)
    for c, e in zip(result.problem.curves, result.final.rel_l2):
        print(f"{c.name}: rel. L2 {100 * e:.2f} % ({1e3 * c.thickness:g} mm)")
    print(f"{result.problem.runs} drop tests, {len(result.problem.history)} evaluations, "
          f"{time.perf_counter() - t0:.1f} s; {result.status}")
    print(f"wrote {args.out}: {', '.join(published_files(args.out))}")
    return 0


COMMANDS = {"sweep": _cmd_sweep, "calibrate": _cmd_calibrate}
