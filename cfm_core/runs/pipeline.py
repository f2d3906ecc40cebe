"""Run a scene end to end: scene -> model -> backend.run -> post-processing -> outcome.

Backends never post-process; post-processing never knows the backend (docs/conventions.md
section 3). The outcome keeps the resolved scene, so that what it writes can be run again.
"""

from __future__ import annotations

import hashlib
import re
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

import numpy as np

from .. import post
from ..errors import InputError, NumericalError
from ..post.filters import MIN_RATE_OVER_CFC
from ..post.metrics import filter_warning
from ..scene.builder import build_model
from ..scene.model import too_big
from ..scene.plausible import check_plausible
from ..scene.scene import Scene, scene_to_dict
from ..simulation import checks
from ..simulation.registry import backend_for
from .outcomes import DropTestOutcome, ReactionOutcome
from .progress import FALLBACK_SIZE, _progress, bar_size  # noqa: F401 (bar_size, FALLBACK_SIZE: this module's API before)
from .parts import describe_model, parts_info
from .provenance import json_ready, provenance, scene_files, scene_paths
from .settings import RunPlan, plan_run, run_record

#: Run statistics a backend may report that are copied into the summary.
_RESULT_INFO = ("threads", "vector_width", "compile_time", "hourglass_coefficient", "newton_iterations", "rejected_steps", "penetration_ratio")


def default_backend(scene: Scene) -> str:
    """The backend a scene runs on when none is named: the first quasi-static-capable backend
    ('skfem') for scenes without inertia (relaxation), 'numba' otherwise."""
    return "skfem" if scene.type == "relaxation" else "numba"


def run_model(model, backend: str = "numba", progress: Callable[[float], None] | None = None, **options):
    """Run a built :class:`~cfm_core.scene.Model` on a backend, with the end-of-run physics checks.

    The checks (:func:`cfm_core.simulation.checks.check_result`) run here for every backend; the
    backends run the state checks (:class:`cfm_core.simulation.checks.Monitor`) during the run.

    Parameters
    ----------
    model : Model
        From :func:`cfm_core.build_model`.
    backend : str
        Registered backend name (``cfm backends``).
    progress : callable, optional
        Called with the simulated time (s) from time to time.
    **options
        The backend's options (``cfm backends --options``).

    Returns
    -------
    Result
        Raw histories (no post-processing); ``info["warnings"]``: the checks' warnings (text).

    Raises
    ------
    InputError
        Unknown or unavailable backend, bad options, a model the backend cannot run.
    NumericalError
        The run failed or its physics broke (penetration, bottoming out, folded element, contact
        at the automatic end time, a stop limit): names where and when.
    """
    be = backend_for(backend)
    try:
        result = be.run(model, progress=progress, **options)
    except MemoryError:
        raise InputError(too_big(model.n_elements, model.n_nodes, f"model '{model.name}' on backend '{backend}'")) from None
    except NumericalError as exc:
        hg = options.get("hourglass")
        if isinstance(hg, (int, float)) and hg > HOURGLASS_STABLE:   # the likelier cause: say it first
            raise NumericalError(
                f"{exc} The option hourglass = {hg:g} is above {HOURGLASS_STABLE:g}: the viscous hourglass forces "
                f"are not in the stable time step, and above about {HOURGLASS_STABLE:g} they can make the run "
                f"unstable as an element stiffens (the default drop test failed at 0.5 and 1 and ran at 0.3, and at 1 "
                f"with safety = 0.2); lower it, or lower the option safety.",
                time=exc.time, element=exc.element, quantity=exc.quantity) from None
        raise
    result = _checked(be, model, result)
    interval = options.get("frame_interval")
    if result.frames is not None and len(result.frames) <= 1 and isinstance(interval, (int, float)) and len(result.t):
        result.info["warnings"].append(
            f"option frame_interval = {interval:g} s is longer than the run ({float(result.t[-1]):.4g} s): only the "
            f"frame at t = 0 was stored{' (was it meant in ms?)' if interval >= 0.05 else ''}; give the interval in s, "
            f"e.g. frame_interval = {float(result.t[-1]) / 20:.2g} for 20 frames.")
    return result


def _checked(be, model, result):
    """A finished run's result with the end-of-run checks' warnings and whether the backend has
    hourglass control (False: the summary says n/a), as every drop test and run returns it."""
    result.info["warnings"] = checks.check_result(model, result)
    result.info.setdefault("hourglass_control", bool(be.hourglass_control))
    return result


#: Viscous hourglass coefficient above which a failed explicit run names it as a likely cause (LS-DYNA's manual
#: recommends at most 0.15 for its viscous hourglass forms).
HOURGLASS_STABLE = 0.15

#: Within :func:`warnings_once`: the warnings said so far, by their text without its numbers.
_SAID: set | None = None
#: Within :func:`warnings_once` with ``material=False``: the material's plausibility warnings are not said.
_QUIET_MATERIAL = False


def is_material_warning(text: str) -> bool:
    """Whether a warning is about the [material] section's values (:func:`cfm_core.material.plausible.check_material`)."""
    return text.startswith("[material]")


@contextmanager
def warnings_once(material: bool = True):
    """Within this block :func:`report_warnings` prints each warning once, however many runs give it:
    the runs of one study (a calibration's evaluations) differ only in their parameters, and a warning
    that differs only in its numbers (a Poisson ratio at each k1 tried) is said once. The runs'
    summaries still hold every warning.

    material: False leaves out the material's plausibility warnings ("[material] k1 = ... Pa is 1000x
    above ... Was it converted from kPa to Pa twice?"): in a fit they are about the optimiser's trial
    values, not the user's, whose start values the caller checks once before."""
    global _SAID, _QUIET_MATERIAL
    outer, _SAID = _SAID, set()
    quiet, _QUIET_MATERIAL = _QUIET_MATERIAL, not material
    try:
        yield
    finally:
        _SAID, _QUIET_MATERIAL = outer, quiet


def report_warnings(summary: dict, stream=None) -> None:
    """Print a summary's run-check warnings on stderr (within :func:`warnings_once`, each kind once).

    Parameters
    ----------
    summary : dict
        A run summary; its ``"warnings"`` (list of text), if any, are printed one per line.
    stream : file, optional
        Where to print (default ``sys.stderr``).
    """
    for text in summary.get("warnings", []):
        if _QUIET_MATERIAL and is_material_warning(text):
            continue
        if _SAID is not None:
            key = re.sub(r"[-+]?\d[\d.,]*(e[-+]?\d+)?", "#", text)
            if key in _SAID:
                continue
            _SAID.add(key)
        print(f"warning: {text}", file=stream or sys.stderr)


def check_output_rate(scene: Scene, cfc: float = 600.0) -> None:
    """Refuse a drop-test scene whose output rate is too low for the CFC filter, before running.

    Parameters
    ----------
    scene : Scene
        The drop-test scene ([scene] output_rate in Hz).
    cfc : float
        Channel frequency class of the filter (Hz, default 600).

    Raises
    ------
    InputError
        output_rate below 10 x CFC (SAE J211/1), naming [scene] output_rate.
    """
    rate = float(scene.settings.output_rate)
    if rate < MIN_RATE_OVER_CFC * cfc:
        raise InputError(
            f"[scene] output_rate = {rate:g} Hz is too low: the acceleration is filtered with SAE J211/1 "
            f"CFC {cfc:g}, which needs at least {MIN_RATE_OVER_CFC:g} x CFC = {MIN_RATE_OVER_CFC * cfc:g} Hz. "
            f"Use output_rate >= {MIN_RATE_OVER_CFC * cfc:g} Hz (the paper's 50 000 Hz is the default).")


def named_in_mesh_file(exc: NumericalError, scene: Scene, model) -> NumericalError:
    """A run's error that names an element of the model, with that element also named as the user's
    mesh file names it: the model counts elements from 0 in the file's order, an Abaqus file numbers
    them itself ("element 22 is folded" was element 123, nodes 1001-, of the file).

    Parameters
    ----------
    exc : NumericalError
        The run's error (its ``element``: a 0-based element of the model, or None).
    scene : Scene
        The scene that was run (its [specimen] mesh file, if any).
    model : Model
        The model built from it.

    Returns
    -------
    NumericalError
        ``exc`` itself when the scene has no mesh file or the error names no element; else a new
        error of the same time, element and quantity whose message ends "In FILE, element e of the
        model is element 123 (the 23rd hexahedron of the file; nodes 1010, ...)."
        (:meth:`cfm_core.scene.mesh.MeshNames.element`, corners in the order the message counts).
    """
    from ..scene.mesh import file_mesh_names

    paths = scene_paths(scene)
    e = exc.element
    if not paths or e is None or not 0 <= int(e) < model.n_elements:
        return exc
    try:
        names = file_mesh_names(paths[0])
    except (InputError, OSError):
        return exc
    if len(names.corners) != model.n_elements:     # not the file's elements one for one
        return exc
    text = (f"{exc} In {Path(paths[0]).name}, element {int(e)} of the model is "
            f"{names.element(int(e), with_nodes=True)}.")
    return NumericalError(text, time=exc.time, element=exc.element, quantity=exc.quantity)


def _run(scene: Scene, backend: str, progress, label: str, options: dict, say_model: bool = False):
    model = build_model(scene)
    if say_model and (model.multi_material or (model.meta or {}).get("symmetry", "quarter") != "quarter"
                      or (model.sphere is not None and model.sphere.shape != "hemisphere")):
        print(f"note: {describe_model(model)}", file=sys.stderr)  # the paper's set-up: printed as before
    callback = _progress(progress, scene, label)
    try:
        result = run_model(model, backend, callback, **options)
    except BaseException as exc:
        if hasattr(callback, "close"):
            callback.close()
        if isinstance(exc, NumericalError):
            named = named_in_mesh_file(exc, scene, model)
            if named is not exc:
                raise named from exc
        raise
    if hasattr(callback, "close"):
        callback.close(float(result.t[-1]) if len(result.t) else None)
    return model, result


def drop_test(scene: Scene, backend: str | None = None, progress=None, **options) -> DropTestOutcome:
    """Run a drop-test scene and post-process it (SAE J211/1 CFC 600 at the scene's output rate).

    The scene's ``[run]`` section (a ``scene.toml`` written by an earlier run, read with
    :func:`cfm_core.load_scene`) gives the backend, dtype, device and options, so that the run
    is repeated exactly; ``backend`` and ``options`` given here override it (a note on stderr
    says which). Without a section: numba with its default options.

    Parameters
    ----------
    scene : Scene
        A ``drop-test`` scene, e.g. ``cfm.builtin_scene("drop-test").with_overrides(thickness=0.005)``
        (SI units).
    backend : str, optional
        ``"numba"``, ``"torch"``, ``"skfem"`` or any registered backend; default: the scene's
        ``[run] backend``, else ``"numba"``.
    progress : bool or callable, optional
        True for a progress bar on stderr, or a callable taking the simulated time (s).
    **options
        Backend options (``cfm backends --options``), e.g. ``device="cuda"`` for torch; they
        override the scene's ``[run]`` options of the same name.

    Returns
    -------
    DropTestOutcome
        Histories (t s, a_raw and a_cfc m/s^2), summary (``peak_g``, ``t_peak`` s, ``duration``
        s, ..., ``provenance``), ``to_dataframe()``, ``save(dir)``.

    Raises
    ------
    InputError
        Not a drop-test scene, unknown backend, bad options (also in the scene's ``[run]``).
    NumericalError
        The run failed or its physics broke (names where and when).
    """
    return run_planned(scene, plan_run(scene, backend, options), progress)


def run_planned(scene: Scene, plan: RunPlan, progress=None):
    """Run a scene with a :class:`~cfm_core.runs.settings.RunPlan` (:func:`plan_run`): its notes
    and warnings printed first, then :func:`drop_test` or :func:`reaction_test`'s work.

    Parameters
    ----------
    scene : Scene
        Any scene.
    plan : RunPlan
        Backend and options (the scene's ``[run]`` already merged in).
    progress : bool or callable, optional
        As for :func:`drop_test`.

    Returns
    -------
    DropTestOutcome or ReactionOutcome
        By the scene's type.

    Raises
    ------
    InputError, NumericalError
        As for :func:`drop_test` and :func:`reaction_test`.
    """
    for text in plan.notes:
        print(f"note: {text}", file=sys.stderr)
    if scene.type != "drop-test":
        return _reaction_test(scene, plan, progress)
    check_output_rate(scene)
    notes = [*plan.warnings, *check_plausible(scene)]  # unit slips (220 for 0.220 kg): warned before running
    report_warnings({"warnings": notes})
    label = f"drop test {1e3 * scene.specimen.thickness:.1f} mm ({plan.backend})"
    model, result = _run(scene, plan.backend, progress, label, plan.options, say_model=True)
    return drop_test_outcome(scene, model, result, notes, options=plan.options)


def drop_test_outcome(scene: Scene, model, result, notes=(), options: dict | None = None) -> DropTestOutcome:
    """The post-processed outcome of a finished drop-test run.

    Parameters
    ----------
    scene : Scene
        The drop-test scene that ran.
    model : Model
        The model built from it.
    result : Result
        The backend's result (after the run checks).
    notes : sequence of str
        Warnings about the scene's values already printed before the run
        (:func:`cfm_core.scene.plausible.check_plausible`); listed first in the summary's warnings.
    options : dict, optional
        The backend options the run was given (recorded, resolved, in the provenance and [run]).

    Returns
    -------
    DropTestOutcome
        Filtered histories (SAE J211/1 CFC 600) and the summary (with ``provenance``); its scene
        holds every material parameter value and the [run] section, so that the scene.toml it
        writes repeats the run even if defaults change.
    """
    scene = resolved(scene, model, result.backend, options)
    rate = float(scene.settings.output_rate)
    t, a_raw, a_cfc = post.acceleration_histories(result, model.mass_full, rate=rate)
    cut = filter_warning(t, a_raw, a_cfc, 600.0)
    if cut:
        result.info.setdefault("warnings", []).append(cut)
    info = {
        "scene_name": scene.settings.name or "",
        "impactor_mass": model.mass_full, "impactor_radius": scene.impactor.radius, "sample_rate": rate,
        "elements": model.n_elements * int(model.symmetry_factor), "elements_modelled": model.n_elements,
        "thickness": model.meta["thickness"], "width": scene.specimen.width, "element_size": model.meta["element_size"],
        "density": scene.specimen.density, "friction": scene.contact.friction, "mesh": scene.specimen.mesh or "",
        "velocity": model.meta["velocity"], "symmetry": model.meta["symmetry"],
        "material": model.material.name, "moduli": model.material.moduli, "elastic": model.material.elastic,
        "parameters": dict(model.material.values), "scene": json_ready(scene_to_dict(scene)),
        "units": {"thickness": "m", "width": "m", "element_size": "m", "velocity": "m/s", "elements_modelled": "-",
                  "impactor_radius": "m", "density": "kg/m^3", "friction": "-", "parameters": "SI (Pa, s, -)",
                  "scene": "SI (as in scene.toml)"},
    }
    info.update(parts_info(model))
    sph = model.sphere
    if sph is not None and sph.shape != "hemisphere":  # the paper's hemisphere: summary as before
        info.update(impactor_shape=sph.shape, impactor_edge_radius=float(sph.edge_radius))
        info["units"]["impactor_edge_radius"] = "m"
    info.update({key: result.info[key] for key in _RESULT_INFO if key in result.info})
    info["warnings"] = [*notes, *result.info.get("warnings", [])]
    extra = _provenance(scene, model, result.backend, options)
    info.update(extra, units={**info["units"], **extra["units"]})
    summary = post.summarize(result, info, (t, a_raw, a_cfc))
    report_warnings({"warnings": result.info.get("warnings", [])})
    return DropTestOutcome(scene, model, result, t, a_raw, a_cfc, summary)


def resolved(scene: Scene, model, backend: str | None = None, options: dict | None = None) -> Scene:
    """The scene with every material parameter value written out (defaults included) and, given
    the backend, the [run] section of the run (:func:`cfm_core.runs.settings.run_record`).

    Parameters
    ----------
    scene : Scene
        The scene that ran.
    model : Model
        The model built from it (its bound material holds every value, SI units).
    backend : str, optional
        The backend it ran on (None: the [run] section is left as it is).
    options : dict, optional
        The options it was given.

    Returns
    -------
    Scene
        The same scene with ``[material.parameters]`` complete (a relative mesh path made
        absolute, so that the scene reads the same file from any folder) and its [run] section.
    """
    # several parts: [material] is not what each part ran (their values are in summary.json "parts")
    over = {} if model.multi_material else {"parameters": dict(model.material.values)}
    mesh = getattr(getattr(scene, "specimen", None), "mesh", None)
    if mesh and not Path(mesh).is_absolute():
        spec = scene.specimen
        over.update(mesh=str(Path(mesh).absolute()), width=spec.width, thickness=spec.thickness,
                    element_size=spec.element_size)
    scene = scene.with_overrides(**over)
    return scene if backend is None else scene.with_run(run_record(scene, backend, options))


def _provenance(scene: Scene, model, backend: str, options: dict | None) -> dict:
    """Summary entries naming how the run was made: dtype, device and the provenance record."""
    record = json_ready(provenance(backend, options, model.material, scene_files(scene), parts=model.part_list()))
    return {"dtype": record["backend"]["dtype"], "device": record["backend"]["device"], "provenance": record,
            "units": {"provenance": "record of what produced this output (code, backend with resolved options in SI, "
                                    "material, input-file digests)"}}


def batch_key(model) -> str:
    """What drop tests must share to run as one batch, as a hash.

    Parameters
    ----------
    model : Model
        A drop-test model.

    Returns
    -------
    str
        SHA-256 of the mesh, density, constraints, contact sets, sphere radius and position, friction
        and material definition; models with equal keys may run in one batch.
    """
    h = hashlib.sha256()
    for a in (model.nodes, model.hexes, model.fixed_dofs, model.sphere_nodes, model.plane_nodes):
        arr = np.ascontiguousarray(a)
        h.update(str(arr.shape).encode() + arr.tobytes())
    sph = model.sphere
    h.update(repr((model.density, model.friction, model.gravity, model.symmetry_factor, model.plane,
                   model.stop_after_separation, sph.radius if sph else None, tuple(sph.center[:2]) if sph else None,
                   model.prescribed is None, model.material.spec.name,
                   len(model.material.prony_arrays()[0]))).encode())
    if model.multi_material:  # every part's elements, density and material definition (one material: as before)
        for p in model.part_list():
            arr = np.ascontiguousarray(np.asarray(p.elements, dtype=np.int64))
            h.update(repr((p.name, float(p.density), p.material.spec.name, len(p.material.prony_arrays()[0]))).encode()
                     + arr.tobytes())
    if sph is not None and (sph.shape != "hemisphere" or sph.lateral):  # the paper's impactor: key as before
        h.update(repr((sph.shape, sph.edge_radius, tuple(sph.moves))).encode())
    return h.hexdigest()


def drop_test_models(scenes) -> list:
    """The models of drop-test scenes, each checked and built once, or the reason it cannot run.

    Parameters
    ----------
    scenes : sequence of Scene
        Drop-test scenes.

    Returns
    -------
    list of Model or Exception
        In the order of ``scenes``: the built model, or the InputError (not a drop-test scene, an
        output rate too low for the filter, an invalid value) or other ValueError/RuntimeError its
        build raised.
    """
    models: list = []
    for scene in scenes:
        try:
            if scene.type != "drop-test":
                raise InputError(f"scene type is '{scene.type}'; drop_tests needs 'drop-test' scenes.")
            check_output_rate(scene)
            models.append(build_model(scene))
        except (ValueError, RuntimeError) as exc:
            models.append(exc)
    return models


def batch_groups(keys, batch_size: int) -> list[list[int]]:
    """Indices of equal keys, in groups of at most ``batch_size``: the runs of one batch each.

    Parameters
    ----------
    keys : sequence of hashable or None
        One per run, e.g. :func:`batch_key` of its model; None for a run that is left out.
    batch_size : int
        Largest group (>= 1).

    Returns
    -------
    list of list of int
        Groups in the order their keys first appear, each in the order of ``keys``.
    """
    groups: dict = {}
    for i, key in enumerate(keys):
        if key is not None:
            groups.setdefault(key, []).append(i)
    return [members[k:k + batch_size] for members in groups.values() for k in range(0, len(members), batch_size)]


def drop_tests(scenes, backend: str = "torch", batch_size: int = 64, models: list | None = None, **options) -> list:
    """Run drop-test scenes; those sharing a mesh run as batches where the backend can (``run_batch``).

    Every run gets the same end-of-run checks as :func:`run_model`.

    Parameters
    ----------
    scenes : sequence of Scene
        Drop-test scenes.
    backend : str
        Backend name; one with a ``run_batch`` method (torch) runs each group of scenes sharing a
        mesh (:func:`batch_key`) as batches of at most ``batch_size``, others one by one.
    batch_size : int
        Largest batch.
    models : list of Model or Exception, optional
        :func:`drop_test_models` of ``scenes``, when the caller has built them already (default:
        built here).
    **options
        Backend options.

    Returns
    -------
    list of DropTestOutcome or Exception
        In the order of ``scenes``; a failed run's entry is its exception (InputError,
        NumericalError), the others are unaffected.
    """
    be = backend_for(backend)
    built = drop_test_models(scenes) if models is None else list(models)
    out: list = [m if isinstance(m, Exception) else None for m in built]
    models = [(i, m) for i, m in enumerate(built) if not isinstance(m, Exception)]

    def finish(i, model, result, checked: bool):
        """The outcome of one run, or its exception; ``checked``: run_model already ran the checks."""
        if isinstance(result, Exception):
            return result
        try:
            if not checked:
                _checked(be, model, result)
            return drop_test_outcome(scenes[i], model, result, check_plausible(scenes[i]), options=options)
        except (ValueError, RuntimeError) as exc:
            return exc

    if not hasattr(be, "run_batch"):
        for i, model in models:
            try:
                result = run_model(model, backend, **options)
            except (ValueError, RuntimeError) as exc:
                result = exc
            out[i] = finish(i, model, result, checked=True)
        return out
    for part in batch_groups([None if isinstance(m, Exception) else batch_key(m) for m in built], batch_size):
        try:
            results = be.run_batch([built[i] for i in part], raise_errors=False, **options)
        except (ValueError, RuntimeError) as exc:
            results = [exc] * len(part)
        for i, res in zip(part, results):
            out[i] = finish(i, built[i], res, checked=False)
    return out


def reaction_test(scene: Scene, backend: str | None = None, progress=None, **options) -> ReactionOutcome:
    """Run a single-element or relaxation scene: reaction-force histories and their summary.

    The scene's ``[run]`` section gives the backend and options as for :func:`drop_test`.

    Parameters
    ----------
    scene : Scene
        A ``single-element`` or ``relaxation`` scene (SI units).
    backend : str, optional
        Backend name; default: the scene's ``[run] backend``, else :func:`default_backend`
        (skfem for relaxation, numba otherwise).
    progress, **options
        As for :func:`drop_test`.

    Returns
    -------
    ReactionOutcome
        t (s), stretch (-), force (N), nominal stress (Pa), summary; ``to_dataframe()``, ``save(dir)``.

    Raises
    ------
    InputError
        Wrong scene type, unknown backend, a quasi-static scene on an explicit backend.
    NumericalError
        The run failed (names where and when).
    """
    if scene.type not in ("single-element", "relaxation"):
        raise InputError(f"scene type is '{scene.type}'; reaction_test needs a 'single-element' or "
                         f"'relaxation' scene (drop tests: drop_test).")
    return run_planned(scene, plan_run(scene, backend, options, default=default_backend(scene)), progress)


def _reaction_test(scene: Scene, plan: RunPlan, progress) -> ReactionOutcome:
    notes = [*plan.warnings, *check_plausible(scene)]  # unit slips of the material: warned before running
    report_warnings({"warnings": notes})
    backend, options = plan.backend, plan.options
    model, result = _run(scene, backend, progress, f"{scene.type} ({backend})", options)
    scene = resolved(scene, model, result.backend, options)
    t, stretch, force, nominal = post.reaction_histories(result, model)
    meta = model.meta
    info = {k: meta[k] for k in ("scene_type", "size", "stretch", "load_time", "hold", "rate", "lateral")
            if k in meta}
    info.update(scene_name=scene.settings.name or "", material=model.material.name, moduli=model.material.moduli,
                elastic=model.material.elastic, parameters=dict(model.material.values), elements=model.n_elements,
                scene=json_ready(scene_to_dict(scene)))
    extra_parts = parts_info(model)
    units = extra_parts.pop("units", {})
    info.update(extra_parts)
    info.update(_provenance(scene, model, result.backend, options))
    info["units"] = {**info["units"], **units, "parameters": "SI (Pa, s, -)", "scene": "SI (as in scene.toml)"}
    info["warnings"] = [*notes, *result.info.get("warnings", [])]
    summary = post.summarize_reaction(result, t, force, info)
    report_warnings({"warnings": result.info.get("warnings", [])})
    return ReactionOutcome(scene, model, result, t, stretch, force, nominal, summary)
