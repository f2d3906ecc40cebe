"""Run a scene on a backend and post-process it: scene -> model -> backend.run -> outputs.

Backends never post-process; post-processing never knows the backend (docs/conventions.md section 3).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from .. import post as postprocess
from ..post.filters import MIN_RATE_OVER_CFC
from ..scene.builder import build_model
from ..errors import InputError
from ..simulation import checks
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
    """Run a built :class:`~cfm_core.scene.Model` on a backend; returns its Result.

    The end-of-run physics checks (:func:`cfm_core.simulation.checks.check_result`) run here for
    every backend: a failed check raises NumericalError, warnings go to ``result.info["warnings"]``.
    """
    result = backend_for(backend).run(model, progress=progress, **options)
    result.info["warnings"] = checks.check_result(model, result)
    return result


def report_warnings(summary: dict, stream=None) -> None:
    """Print a summary's run-check warnings, one line each, on ``stream`` (default stderr)."""
    for text in summary.get("warnings", []):
        print(f"warning: {text}", file=stream or sys.stderr)


def check_output_rate(scene, cfc: float = 600.0) -> None:
    """InputError naming [scene] output_rate (Hz) when it is below what the CFC filter needs
    (SAE J211/1: at least 10 x CFC), raised before anything is run."""
    rate = float(scene.settings.output_rate)
    if rate < MIN_RATE_OVER_CFC * cfc:
        raise InputError(
            f"[scene] output_rate = {rate:g} Hz is too low: the acceleration is filtered with SAE J211/1 "
            f"CFC {cfc:g}, which needs at least {MIN_RATE_OVER_CFC:g} x CFC = {MIN_RATE_OVER_CFC * cfc:g} Hz. "
            f"Use output_rate >= {MIN_RATE_OVER_CFC * cfc:g} Hz (the paper's 50 000 Hz is the default).")


def drop_test(scene, backend: str = "numba", progress=None, **options) -> DropTestOutcome:
    """Run a drop-test scene and post-process it (SAE J211 CFC 600 at 50 kHz by default)."""
    if scene.type != "drop-test":
        raise InputError(f"scene type is '{scene.type}'; drop_test needs a 'drop-test' scene.")
    check_output_rate(scene)
    model = build_model(scene)
    result = run_model(model, backend, progress, **options)
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
    info["warnings"] = list(result.info.get("warnings", []))
    summary = postprocess.summarize(result, info)
    report_warnings(summary)
    return DropTestOutcome(model, result, t, a_raw, a_cfc, summary)


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
    info["warnings"] = list(result.info.get("warnings", []))
    summary = postprocess.summarize_reaction(result, t, force, info)
    report_warnings(summary)
    return ReactionOutcome(model, result, t, stretch, force, nominal, summary)
