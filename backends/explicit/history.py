"""The history of an explicit run (one row per step) and the Result assembled from it.

Both explicit backends record the same 15 columns per step (forces, impulses and energies of the
full model, i.e. times ``model.symmetry_factor``; SI units) and build their Result here.
"""

from __future__ import annotations

import math

import numpy as np

from cfm_core.simulation.result import Result

COLUMNS = ("t", "force", "impulse", "z", "v", "reaction", "kinetic", "internal", "hourglass", "contact",
           "external", "internal_force_work", "dt", "penetration", "momentum_z",
           "force_x", "force_y", "x", "y", "vx", "vy", "momentum_x", "momentum_y")
"""History columns: t^n (s); contact force on the impactor, + decelerating (N); impulse (N s);
impactor centre z (m) and velocity (m/s); reaction at prescribed nodes (N); kinetic, internal,
hourglass, contact energy and external work (J); work of the internal nodal forces (J, diagnostic);
the step dt_{n+1/2} taken from t^n (s); largest sphere penetration after correction (m); z momentum
of nodes and impactor (kg m/s); then the impactor's in-plane contact force (N), reference point
(m) and velocity (m/s), and the x and y momentum of nodes and impactor (kg m/s). A backend may
record only the first 15 (an impactor held in x and y)."""

#: The first columns every explicit history has; the in-plane ones follow.
BASE_COLUMNS = 15

COL = {name: i for i, name in enumerate(COLUMNS)}
ENERGIES = ("kinetic", "internal", "hourglass", "contact", "external")


def end_on_end_time(h: np.ndarray, end: float) -> np.ndarray:
    """The history of a prescribed-motion run ending at its end time: its last row, the first at or
    past the end time (up to one stable step after it, where the motion already holds), replaced by
    the row at the end time, linearly interpolated in time between the rows around it (every
    column but ``dt``, the step taken from the last row). The load curves' final
    values are reached at the end time, so the last row is the final state, as skfem writes it
    (single element: 5.0035 ms -> 5 ms).

    Parameters
    ----------
    h : (m, k) ndarray
        History rows in :data:`COLUMNS` order, times increasing.
    end : float
        The end time (s).

    Returns
    -------
    (m, k) ndarray
        ``h`` itself when its last row is at the end time, before it, or the only row past none;
        else a copy with the last row interpolated.
    """
    if len(h) < 2 or not (h[-2, 0] < end < h[-1, 0]):
        return h
    w = (end - h[-2, 0]) / (h[-1, 0] - h[-2, 0])
    out = h.copy()
    out[-1] = h[-2] + w * (h[-1] - h[-2])
    out[-1, 0] = end
    out[-1, COL["dt"]] = h[-1, COL["dt"]]
    return out


def assemble(model, h: np.ndarray, *, backend: str, steps: int, wall: float, dt0: float, dtmin: float,
             dtmax: float, maxpen: float, frames: list, stop: str, options, info: dict) -> Result:
    """The Result of an explicit run from its history.

    Parameters
    ----------
    model : cfm_core.scene.model.Model
        The model that was run.
    h : (steps, 15) or (steps, 23) ndarray
        History rows in :data:`COLUMNS` order (the in-plane columns may be left out when the
        impactor moves along z only).
    backend : str
        Backend name.
    steps : int
        Steps taken.
    wall : float
        Solver wall time (s), compilation excluded.
    dt0, dtmin, dtmax : float
        First stable step, smallest and largest step taken (s).
    maxpen : float
        Largest sphere penetration left after the contact correction (m).
    frames : list of (float, (n, 3) ndarray)
        Stored (t s, displacement m) frames.
    stop : str
        Stop reason ("end_time", "separated").
    options : ExplicitOptions
        The run's options (hourglass, hourglass_wave, safety are recorded).
    info : dict
        Backend-specific entries (threads, compile_time, device, ...), merged into ``Result.info``.

    Returns
    -------
    Result
        Histories, energies and ``info`` (elements, nodes, stop reason, ns per element-cycle,
        energy error, hourglass ratio, ...).
    """
    if model.prescribed is not None:
        h = end_on_end_time(h, float(model.end_time))
    ne = model.n_elements
    sphere = model.sphere is not None
    mass_full = model.mass_full if model.mass_full else (model.sphere.mass * model.symmetry_factor if sphere else None)
    col = {name: h[:, i] for i, name in enumerate(COLUMNS[:h.shape[1]])}
    duration = float(col["t"][-1]) if len(h) else 0.0
    pz = col["momentum_z"]
    res = Result(
        t=col["t"], backend=backend, steps=steps, wall_time=wall,
        contact_force=col["force"] if sphere else None,
        impulse=col["impulse"] if sphere else None,
        acceleration=col["force"] / mass_full if sphere else None,
        impactor_z=col["z"] if sphere else None,
        impactor_v=col["v"] if sphere else None,
        reaction_force=col["reaction"] if model.prescribed is not None else None,
        energies={k: col[k] for k in ENERGIES}, dt_min=float(dtmin), dt_max=float(dtmax), frames=frames,
        info={
            "n_elements": ne, "n_nodes": model.n_nodes, "material": model.material.name,
            "hourglass": options.hourglass, "hourglass_wave": options.hourglass_wave, "safety": options.safety,
            **info, "stop_reason": stop,
            "dt_first": dt0, "steps_at_first_dt": int(math.ceil(duration / dt0)) if dt0 > 0 else None,
            "ns_per_element_cycle": wall / max(steps * ne, 1) * 1e9,
            "max_sphere_penetration": float(maxpen),
            "internal_force_work": float(col["internal_force_work"][-1]) if len(h) else 0.0,
            "momentum_z_drift": float(np.max(np.abs(pz - pz[0]))) if len(h) else 0.0,
            "prony_terms": int(np.asarray(model.material.prony_arrays()[0]).size),
        },
    )
    lateral = sphere and model.sphere.lateral and "force_x" in col
    if lateral:
        res.impactor_lateral = {k: col[k] for k in ("force_x", "force_y", "x", "y", "vx", "vy")}
        for k in ("momentum_x", "momentum_y"):
            res.info[f"{k}_drift"] = float(np.max(np.abs(col[k] - col[k][0]))) if len(h) else 0.0
    res.info["energy_error"] = res.energy_error()
    res.info["hourglass_ratio"] = res.hourglass_ratio()
    return res
