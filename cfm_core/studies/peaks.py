"""Fit material parameters to target peak accelerations of drop tests (e.g. the paper's 80.7 g at 5 mm
and 52.5 g at 8 mm, the only experimental numbers it states).

Residual of target j (thickness h_j, peak p_j in g): r_j = peak_sim(h_j) / p_j - 1, the peak of the
CFC 600-filtered impactor acceleration of the scene's drop test at that thickness. Least squares
(``scipy.optimize.least_squares``, trust region reflective) on ln p within the valid ranges
(:func:`cfm_core.studies.calibrate.coordinates`), forward-difference Jacobian of relative step
``rel_step`` whose drop tests go to the runner together.

Identifiability: with as many targets as parameters the fit has no residual degrees of freedom, so
no interval can be estimated; what is reported is the Jacobian (sensitivity of each peak to each
ln p), its singular values and condition number: a large condition number means a direction in
parameter space that hardly moves either peak (the peaks do not pin the parameters down, even if
they are matched). With more parameters than targets the solution is a family, not a point.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, NumericalError
from .calibrate import coordinates, material_values
from .dask_runner import SerialRunner
from .differences import forward_jacobian, forward_steps
from .sweep import run_all


@dataclass
class PeakFit:
    """Result of :func:`fit_peaks`.

    Attributes
    ----------
    names : list of str
        Fitted parameters.
    fitted, start : dict
        Fitted and starting values (SI units).
    targets, peaks : dict
        {thickness m: target peak g} and {thickness m: simulated peak g at the fitted values}.
    jacobian : ndarray, shape (targets, parameters)
        d (peak / target) / d ln p at the fitted values (-).
    singular_values : list of float
        Of the Jacobian (-).
    status : str
        scipy's termination message.
    drop_tests : int
        Drop tests run.
    wall : float
        Wall time (s).
    history : list of dict
        Parameters and peaks of every evaluation.
    """

    names: list
    fitted: dict
    start: dict
    targets: dict
    peaks: dict
    jacobian: np.ndarray
    singular_values: list
    status: str
    drop_tests: int
    wall: float
    history: list = field(default_factory=list)


def fit_peaks(scene, targets: dict, names: list, start: dict | None = None, backend: str = "numba",
              runner=None, rel_step: float = 1e-2, max_evaluations: int = 30, progress=None) -> PeakFit:
    """Fit ``names`` of the scene's material so that its drop tests reach the target peaks.

    Parameters
    ----------
    scene : Scene
        Drop-test scene (material, mesh, impactor); each target runs it at its thickness.
    targets : dict
        {thickness in m: peak acceleration in g}.
    names : list of str
        Parameters to fit (SI units, see ``cfm materials``).
    start : dict, optional
        Starting values (default: the scene's).
    backend : str
        Backend of the drop tests (default numba).
    runner : object, optional
        Runner of :mod:`cfm_core.studies.dask_runner` (default: serial).
    rel_step : float
        Forward-difference step in ln p (-).
    max_evaluations : int
        Most objective evaluations.
    progress : callable, optional
        Receives a line of text per evaluation.

    Returns
    -------
    PeakFit

    Raises
    ------
    InputError
        Unknown parameter, invalid start or thickness, no targets.
    NumericalError
        A drop test failed.
    """
    from scipy.optimize import least_squares

    if not targets:
        raise InputError("fit_peaks needs at least one target {thickness m: peak g}.")
    runner = runner or SerialRunner()
    scene = scene.with_overrides(parameters=dict(start or {}))
    values = material_values(scene)
    coords = coordinates(names, scene, values)
    thick = sorted(targets)
    cache, history, count = {}, [], [0]

    def peaks(xs):
        todo = [x for x in xs if x.tobytes() not in cache]
        tasks = [(scene.with_overrides(thickness=h), coords.to_params(x), backend) for x in todo for h in thick]
        results = run_all(runner, tasks, lambda i, error: NumericalError(f"drop test failed at {tasks[i][1]}: {error}"))
        out = [r["summary"]["peak_g"] for r in results]
        count[0] += len(tasks)
        for k, x in enumerate(todo):
            cache[x.tobytes()] = np.array(out[k * len(thick):(k + 1) * len(thick)])
            history.append({"parameters": coords.to_params(x), "peaks_g": cache[x.tobytes()].tolist()})
            if progress:
                progress(f"{len(history)}: " + ", ".join(f"{n} = {v:.5g}" for n, v in coords.to_params(x).items())
                         + " -> " + ", ".join(f"{1e3 * h:g} mm {p:.2f} g" for h, p in zip(thick, cache[x.tobytes()])))
        return [cache[x.tobytes()] for x in xs]

    target = np.array([targets[h] for h in thick])

    def residual(x):
        return peaks([np.asarray(x, float)])[0] / target - 1.0

    def jacobian(x):
        x = np.asarray(x, float)
        steps = forward_steps(x, coords.upper, [rel_step] * x.size)
        return forward_jacobian(peaks, x, peaks([x])[0], steps, scale=target)

    t0 = time.perf_counter()
    x0 = np.clip(coords.to_x(values), coords.lower, coords.upper)
    res = least_squares(residual, x0, jac=jacobian, bounds=(coords.lower, coords.upper), method="trf",
                        x_scale=1.0, xtol=1e-4, ftol=1e-6, gtol=1e-8, max_nfev=max_evaluations)
    J = jacobian(res.x)
    final = peaks([res.x])[0]
    return PeakFit(list(names), coords.to_params(res.x), coords.to_params(x0), dict(targets),
                   {h: float(p) for h, p in zip(thick, final)}, J, np.linalg.svd(J, compute_uv=False).tolist(),
                   str(res.message), count[0], time.perf_counter() - t0, history)

