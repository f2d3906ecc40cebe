"""The NumericalErrors of an explicit run: each names where (element) and when (time, s).

One wording for both explicit backends; the solvers only say what failed.
"""

from __future__ import annotations

import math

import numpy as np

from cfm_core.errors import NumericalError
from cfm_core.material.diagnose import describe_nonfinite, nonfinite_term


#: Fraction of the smallest element edge (-) that the impactor may move per time step before a failure's
#: message advises a smaller step (the paper's drop test: 5 um per step on 1 mm elements, 0.005).
STEP_TRAVEL = 0.1


def fast_impact(model, dt: float) -> str:
    """A sentence for a failure in a run whose first stable step dt (s) moves the impactor
    more than :data:`STEP_TRAVEL` of an element: the step follows the material's wave speed, not the
    impact, so the advice is a smaller step (--option dt_max); "" otherwise, without an impactor, or
    for dt <= 0. 30 m/s on 2 mm elements: steps of 38 us moved the impactor 1.1 mm each, an element
    inverted at 41 us, and the message said only to refine the mesh."""
    from cfm_core.simulation.checks import smallest_edge

    sph = getattr(model, "sphere", None)
    if sph is None or not dt > 0.0:
        return ""
    speed = float(np.linalg.norm(sph.velocity_vector))
    h = smallest_edge(np.asarray(model.nodes), np.asarray(model.hexes))
    if not (speed > 0.0 and h > 0.0) or speed * dt < STEP_TRAVEL * h:
        return ""
    return (f" At {speed:.3g} m/s the impactor moves {1e3 * speed * dt:.3g} mm per step of {dt:.3g} s, "
            f"{100 * speed * dt / h:.3g} % of the smallest element ({1e3 * h:.3g} mm; the step follows the material's "
            f"wave speed, not the impact): give a smaller step first (--option dt_max={0.02 * h / speed:.2g}, s: "
            f"a fiftieth of an element per step).")


def inverted(model, element: int, t: float, J: float, dt0: float = 0.0) -> NumericalError:
    """Element ``element`` has det F = J <= 0 at time t (s); dt0: the run's first stable step (s),
    0 when not known (:func:`fast_impact`)."""
    return NumericalError(
        f"element {element} inverted at t = {t:.6g} s (J = det F = {J:.4g} <= 0) in model "
        f"'{model.name}': the mesh cannot follow this deformation; refine the mesh, lower the load "
        f"or raise the hourglass coefficient (up to 0.15).{fast_impact(model, dt0)}", time=t, element=element,
        quantity="J")


def nonfinite(material, where: str, m, J: float, t: float, index: int, float32: bool = False) -> NumericalError:
    """inf / NaN material derivatives at the eigenvalues m (3,) of C, in ``where`` (e.g. "element 3 at t = ...").

    The material's terms are evaluated one by one in float64 (:mod:`cfm_core.material.diagnose`)
    and the message names the term that failed and its inputs (the volumetric term at J -> 0, a
    fibre exponential beyond exp(709), ...). ``float32``: the run was in float32; when every term
    is finite in float64, the message says that the scene needs float64 (exp overflows float32 at
    an argument of 88.7).
    """
    if float32 and nonfinite_term(material, m) is None:
        return NumericalError(
            f"non-finite stress in {where}: the energy derivatives of material '{material.name}' overflow float32 at "
            f"the eigenvalues of C = ({m[0]:.4g}, {m[1]:.4g}, {m[2]:.4g}), J = {J:.4g} (exp overflows float32 "
            f"once its argument exceeds about 88.7, float64 only at 709; every term is finite in float64 here): "
            f"this scene needs float64; run it with dtype='float64' (CLI: --dtype float64).",
            time=t, element=index, quantity="overflow of the material energy derivative (float32)")
    return NumericalError(f"non-finite stress in {where} (J = {J:.4g}): {describe_nonfinite(material, m)}.",
                          time=t, element=index, quantity=f"non-finite energy derivative of material '{material.name}'")


def collapse(model, t: float, element: int, dtc: float, dt0: float, fraction: float) -> NumericalError:
    """The stable step dtc (s) of ``element`` fell below ``fraction`` x the first step dt0 (s), or is not finite."""
    if not math.isfinite(dtc):
        return NumericalError(
            f"no finite stable time step at t = {t:.6g} s in model '{model.name}': every element has zero "
            f"stiffness (material '{model.material.name}'); give the option dt_max (s).", time=t, quantity="time step")
    return NumericalError(
        f"time-step collapse at t = {t:.6g} s: the stable step of element {element} fell to {dtc:.3g} s, below "
        f"{fraction:g} x the first step {dt0:.3g} s (element crushed or material stiffening without bound)."
        f"{fast_impact(model, dt0)}", time=t, element=element, quantity="time step")


def state(model, t: float) -> NumericalError:
    """Non-finite kinetic energy, momentum or impactor position at time t (s)."""
    return NumericalError(f"non-finite kinematic state at t = {t:.6g} s in model '{model.name}'.",
                          time=t, quantity="state")


#: Steps after which a run whose pace (steps per simulated second) cannot reach its end time within
#: max_steps stops with the projection (:func:`projected_steps`).
PROJECT_AFTER = 4096


def pace(model, steps: int, t: float, limit: int) -> NumericalError | None:
    """The runaway guard of an explicit run, after ``steps`` steps at time t (s): the error to raise, or None.

    Parameters
    ----------
    model : cfm_core.scene.Model
        The model being run (name, end_time in s).
    steps : int
        Steps taken so far.
    t : float
        Simulated time reached (s).
    limit : int
        The option max_steps.

    Returns
    -------
    NumericalError or None
        :func:`max_steps` once ``steps`` reaches ``limit``; :func:`projected_steps` once, after
        :data:`PROJECT_AFTER` steps, the pace so far projects more than ``limit`` steps to the end
        time (mu = 1e306 Pa: a stable step of 1e-155 s, which ran on for hours without a word);
        None while the run can still finish.
    """
    if steps >= limit:
        return max_steps(model, steps, t)
    if steps >= PROJECT_AFTER and steps * float(model.end_time) > limit * t:
        return projected_steps(model, steps, t, limit)
    return None


def projected_steps(model, steps: int, t: float, limit: int) -> NumericalError:
    """At the pace so far (``steps`` steps to time t, s), the run would need more than ``limit`` steps
    (option max_steps) to reach its end time: said at once instead of after hours (safety = 1e-300)."""
    end = float(model.end_time)
    need = steps * end / t if t > 0.0 else float("inf")
    return NumericalError(f"model '{model.name}': {steps} steps reached only t = {t:.6g} s (mean step {t / steps:.3g} "
                          f"s); at that pace the end time {end:g} s needs about {need:.3g} steps, more than option "
                          f"max_steps = {limit}: check the options that set the step (safety, dt_max) and the "
                          f"element size, density and moduli (units).", time=t, quantity="steps")


def max_steps(model, steps: int, t: float) -> NumericalError:
    """The option max_steps was reached at time t (s) before the end time."""
    return NumericalError(f"model '{model.name}': {steps} steps reached at t = {t:.6g} s before the end "
                          f"time {float(model.end_time):g} s (option max_steps).", time=t, quantity="steps")
