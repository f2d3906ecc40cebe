"""Run a scene on a backend and post-process it: scene -> model -> backend.run -> outputs.

Backends never post-process; post-processing never knows the backend (docs/conventions.md section 3).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from .. import post as postprocess
from ..scene.builder import build_model
from ..errors import InputError
from ..simulation.registry import get_backend


@dataclass
class DropTestOutcome:
    """A finished drop test: the model, the raw result, the 50 kHz histories and the summary.

    t (s, from first contact), a_raw and a_cfc (m/s^2, positive decelerating, CFC 600).
    """

    model: object
    result: object
    t: np.ndarray
    a_raw: np.ndarray
    a_cfc: np.ndarray
    summary: dict


@dataclass
class ReactionOutcome:
    """A finished prescribed-motion run (single element, relaxation): the model, the raw result,
    t (s), stretch (-), reaction force (N, negative in compression), nominal stress (Pa) and
    the summary."""

    model: object
    result: object
    t: np.ndarray
    stretch: np.ndarray
    force: np.ndarray
    nominal: np.ndarray
    summary: dict


def default_backend(scene) -> str:
    """The backend a scene runs on when none is named: 'skfem' for quasi-static scenes
    (relaxation: no inertia, holds of seconds), 'numba' otherwise."""
    return "skfem" if scene.type == "relaxation" else "numba"


def backend_for(name: str):
    """An available backend instance, or InputError naming why it cannot run here."""
    backend = get_backend(name)
    ok, why = backend.available()
    if not ok:
        raise InputError(f"backend '{name}' is not available: {why}.")
    return backend


def run_model(model, backend: str = "numba", progress=None, **options):
    """Run a built :class:`~cfm_core.scene.Model` on a backend; returns its Result."""
    return backend_for(backend).run(model, progress=progress, **options)


def drop_test(scene, backend: str = "numba", progress=None, **options) -> DropTestOutcome:
    """Run a drop-test scene and post-process it (SAE J211 CFC 600 at 50 kHz by default)."""
    if scene.type != "drop-test":
        raise InputError(f"scene type is '{scene.type}'; drop_test needs a 'drop-test' scene.")
    model = build_model(scene)
    result = run_model(model, backend, progress, **options)
    return drop_test_outcome(scene, model, result)


def drop_test_outcome(scene, model, result) -> DropTestOutcome:
    """The post-processed outcome of a drop-test run (filtered histories and summary)."""
    rate = float(scene.settings.output_rate)
    t, a_raw, a_cfc = postprocess.acceleration_histories(result, model.mass_full, rate=rate)
    info = {
        "impactor_mass": model.mass_full, "sample_rate": rate, "elements": model.n_elements * int(model.symmetry_factor),
        "elements_modelled": model.n_elements,
        "thickness": model.meta["thickness"], "element_size": model.meta["element_size"],
        "velocity": model.meta["velocity"], "symmetry": model.meta["symmetry"],
        "material": model.material.name, "moduli": model.material.moduli, "elastic": model.material.elastic,
        "parameters": dict(model.material.values),
        "units": {"thickness": "m", "element_size": "m", "velocity": "m/s", "elements_modelled": "-",
                  "parameters": "SI (Pa, s, -)"},
    }
    for key in ("compile_time", "hourglass_coefficient", "newton_iterations", "rejected_steps", "penetration_ratio"):
        if key in result.info:
            info[key] = result.info[key]
    summary = postprocess.summarize(result, info)
    return DropTestOutcome(model, result, t, a_raw, a_cfc, summary)


def batch_key(model) -> str:
    """What drop tests must share to run as one batch (mesh, density, constraints, contact, sphere
    radius, friction, material definition), as a hash; runs with equal keys may be batched."""
    h = hashlib.sha256()
    for a in (model.nodes, model.hexes, model.fixed_dofs, model.sphere_nodes, model.plane_nodes):
        arr = np.ascontiguousarray(a)
        h.update(str(arr.shape).encode() + arr.tobytes())
    sph = model.sphere
    h.update(repr((model.density, model.friction, model.gravity, model.symmetry_factor, model.plane,
                   model.stop_after_separation, sph.radius if sph else None, tuple(sph.center[:2]) if sph else None,
                   model.prescribed is None, model.material.spec.name,
                   len(model.material.prony_arrays()[0]))).encode())
    return h.hexdigest()


def drop_tests(scenes, backend: str = "torch", batch_size: int = 64, **options) -> list:
    """Run drop-test scenes; those sharing a mesh run as batches where the backend can (``run_batch``).

    Parameters
    ----------
    scenes : sequence of Scene
        Drop-test scenes.
    backend : str
        Backend name; one with a ``run_batch`` method (torch) runs each group of scenes sharing a
        mesh (:func:`batch_key`) as batches of at most ``batch_size``, others one by one.
    batch_size : int
        Largest batch.
    **options
        Backend options.

    Returns
    -------
    list of DropTestOutcome or Exception
        In the order of ``scenes``; a failed run's entry is its exception (InputError,
        NumericalError), the others are unaffected.
    """
    be = backend_for(backend)
    out: list = [None] * len(scenes)
    models = []
    for i, scene in enumerate(scenes):
        try:
            if scene.type != "drop-test":
                raise InputError(f"scene type is '{scene.type}'; drop_tests needs 'drop-test' scenes.")
            models.append((i, build_model(scene)))
        except (ValueError, RuntimeError) as exc:
            out[i] = exc
    if not hasattr(be, "run_batch"):
        for i, model in models:
            try:
                out[i] = drop_test_outcome(scenes[i], model, be.run(model, **options))
            except (ValueError, RuntimeError) as exc:
                out[i] = exc
        return out
    groups: dict = {}
    for i, model in models:
        groups.setdefault(batch_key(model), []).append((i, model))
    for members in groups.values():
        for k in range(0, len(members), batch_size):
            part = members[k:k + batch_size]
            try:
                results = be.run_batch([m for _, m in part], raise_errors=False, **options)
            except (ValueError, RuntimeError) as exc:
                results = [exc] * len(part)
            for (i, model), res in zip(part, results):
                try:
                    out[i] = res if isinstance(res, Exception) else drop_test_outcome(scenes[i], model, res)
                except (ValueError, RuntimeError) as exc:
                    out[i] = exc
    return out


def reaction_test(scene, backend: str | None = None, progress=None, **options) -> ReactionOutcome:
    """Run a single-element or relaxation scene; reaction-force histories and their summary."""
    if scene.type not in ("single-element", "relaxation"):
        raise InputError(f"scene type is '{scene.type}'; reaction_test needs a 'single-element' or "
                         f"'relaxation' scene (drop tests: drop_test).")
    backend = backend or default_backend(scene)
    model = build_model(scene)
    result = run_model(model, backend, progress, **options)
    t, stretch, force, nominal = postprocess.reaction_histories(result, model)
    meta = model.meta
    info = {k: meta[k] for k in ("scene_type", "size", "stretch", "load_time", "hold", "rate", "lateral")
            if k in meta}
    info.update(material=model.material.name, moduli=model.material.moduli, elastic=model.material.elastic,
                parameters=dict(model.material.values), elements=model.n_elements)
    info["units"] = {"parameters": "SI (Pa, s, -)"}
    summary = postprocess.summarize_reaction(result, t, force, info)
    return ReactionOutcome(model, result, t, stretch, force, nominal, summary)
