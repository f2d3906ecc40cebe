"""Result of a backend run: histories only, no post-processing (that lives in :mod:`cfm_core.post`).

All arrays are sampled at the same times ``t`` (s). Forces and energies are for the *full* model
(already multiplied by the model's symmetry factor).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Result:
    """Histories of one run, all sampled at the times ``t``; forces and energies of the full model.

    Histories a scene does not have are None (contact for prescribed-motion scenes, reaction
    force for the drop test).

    Parameters
    ----------
    t : ndarray, shape (m,)
        Output times (s).
    backend : str
        Name of the backend that ran.
    steps : int
        Number of time steps.
    wall_time : float
        Solver wall-clock time (s), solver only.
    contact_force : ndarray, shape (m,), optional
        Force of the specimen on the impactor along +z (N), positive when it decelerates a
        downward-moving impactor.
    impulse : ndarray, shape (m,), optional
        Time integral of contact_force from t = 0 (N s), exact for the solver's steps
        (post-processing resamples from it without aliasing).
    acceleration : ndarray, shape (m,), optional
        contact_force / impactor mass (m/s^2).
    impactor_z, impactor_v : ndarray, shape (m,), optional
        Impactor centre position (m) and velocity (m/s) along z.
    reaction_force : ndarray, shape (m,), optional
        Sum of z reaction forces at the prescribed nodes (N), scenes with prescribed motion.
    energies : dict of str to ndarray, shape (m,)
        ``"kinetic"``, ``"internal"``, ``"hourglass"``, ``"contact"``, ``"external"`` (J); empty
        when not recorded.
    dt_min, dt_max : float
        Smallest and largest time step (s); NaN when not recorded.
    frames : list of (float, ndarray)
        Optional ``(t (s), nodal displacement (n, 3) in m)`` for visualisation.
    frame_state : list of dict
        Empty, or one dict per frame with what the backend stores besides the displacement:
        ``velocity`` (n, 3) (m/s) and, for a viscoelastic material, its Prony state ``prony_H``
        (k, e, 6), ``prony_S0`` (e, 6) (Pa, Voigt 11, 22, 33, 12, 23, 13) and ``prony_dt`` (s),
        from which :mod:`cfm_core.post.fields` recovers the solver's stress at the frame.
    info : dict
        Free-form diagnostics (str -> JSON-able value).
    impactor_lateral : dict of str to ndarray, shape (m,), optional
        For an impactor free to move in x or y (no symmetry plane holds it): ``"force_x"``,
        ``"force_y"`` (N, force of the specimen on the impactor, full model), ``"x"``, ``"y"``
        (m, reference point) and ``"vx"``, ``"vy"`` (m/s); None otherwise.
    """

    t: np.ndarray
    backend: str
    steps: int
    wall_time: float
    contact_force: np.ndarray | None = None
    impulse: np.ndarray | None = None
    acceleration: np.ndarray | None = None
    impactor_z: np.ndarray | None = None
    impactor_v: np.ndarray | None = None
    reaction_force: np.ndarray | None = None
    energies: dict[str, np.ndarray] = field(default_factory=dict)
    dt_min: float = float("nan")
    dt_max: float = float("nan")
    frames: list = field(default_factory=list)
    frame_state: list = field(default_factory=list)
    info: dict = field(default_factory=dict)
    impactor_lateral: dict | None = None

    def energy_error(self) -> float:
        """Largest relative energy-balance error over the run (-).

        With total(t) = kinetic + internal + hourglass + contact [+ numerical_dissipation] - external,
        the error is ``max_t |total(t) - total(0)|`` divided by the largest of kinetic + internal energy
        and ``|external work|`` seen during the run (docs/conventions.md section 5).
        ``numerical_dissipation`` (J), when a backend reports it, is the energy its time integrator
        removes (the implicit backend's generalized-alpha method).

        Returns
        -------
        float
            The relative error (-); NaN when no energies were recorded.
        """
        e = self.energies
        if not e:
            return float("nan")
        total = e["kinetic"] + e["internal"] + e["hourglass"] + e["contact"] - e["external"]
        if "numerical_dissipation" in e:
            total = total + e["numerical_dissipation"]
        scale = max(float(np.max(e["kinetic"] + e["internal"])), float(np.max(np.abs(e["external"]))), 1e-300)
        return float(np.max(np.abs(total - total[0])) / scale)

    def hourglass_ratio(self) -> float:
        """Largest hourglass energy over the largest ``|internal energy|`` of the run (-).

        Returns
        -------
        float
            The ratio (-); NaN when no energies were recorded, 0 when the internal energy
            stays 0.
        """
        e = self.energies
        if not e:
            return float("nan")
        peak = float(np.max(np.abs(e["internal"])))
        return float(np.max(e["hourglass"]) / peak) if peak > 0 else 0.0
