"""Result of a backend run: histories only, no post-processing (that lives in postprocess.py).

All arrays are sampled at the same times ``t`` (s). Forces and energies are for the *full* model
(already multiplied by the model's symmetry factor).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Result:
    """Histories of one run.

    t (s); contact_force (N): force of the specimen on the impactor along +z (positive when it
    decelerates a downward-moving impactor); impulse (N s): time integral of contact_force from
    t = 0, exact for the solver's steps (post-processing resamples from it without aliasing);
    acceleration (m/s^2) = contact_force / impactor mass;
    impactor_z (m), impactor_v (m/s): impactor centre position and velocity along z;
    reaction_force (N): sum of z reaction forces at prescribed nodes (scenes with prescribed
    motion); energies (J): 'kinetic', 'internal', 'hourglass', 'contact', 'external' each an array
    over t; steps: number of time steps; wall_time (s, solver only); dt_min, dt_max (s);
    frames: optional list of (t, nodal displacement (n, 3) in m) for visualisation;
    backend: name of the backend that ran; info: free-form diagnostics (str -> JSON-able value).
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
    info: dict = field(default_factory=dict)

    def energy_error(self) -> float:
        """Largest relative energy-balance error over the run (-).

        balance(t) = kinetic + internal + hourglass + contact - external - (kinetic + internal)(0);
        divided by the largest of kinetic+internal energy and external work seen during the run.
        """
        e = self.energies
        if not e:
            return float("nan")
        total = e["kinetic"] + e["internal"] + e["hourglass"] + e["contact"] - e["external"]
        scale = max(float(np.max(e["kinetic"] + e["internal"])), float(np.max(np.abs(e["external"]))), 1e-300)
        return float(np.max(np.abs(total - total[0])) / scale)

    def hourglass_ratio(self) -> float:
        """Final hourglass energy over peak internal energy (-)."""
        e = self.energies
        if not e:
            return float("nan")
        peak = float(np.max(np.abs(e["internal"])))
        return float(np.max(e["hourglass"]) / peak) if peak > 0 else 0.0
