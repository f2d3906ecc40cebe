"""Backend-neutral model: what a scene becomes before a backend runs it.

Plain numpy arrays and small frozen dataclasses, SI units (m, s, kg, Pa). Backends read these and
nothing else; they never see the scene file. A scene includes only what it needs: ``sphere`` and
``plane`` are ``None`` when absent, ``prescribed`` is ``None`` when no boundary motion is imposed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from ..material.material import Material


@dataclass(frozen=True)
class RigidSphere:
    """Rigid spherical impactor moving along z only (one translational degree of freedom).

    radius (m); mass (kg) of the *modelled part* (a quarter model carries a quarter of the mass);
    center (m) at t = 0; velocity (m/s) along z at t = 0 (negative: moving down onto the specimen).
    """

    radius: float
    mass: float
    center: tuple[float, float, float]
    velocity: float


@dataclass(frozen=True)
class RigidPlane:
    """Rigid fixed plane z = ``z`` (m) with normal +z; the specimen lies above it."""

    z: float = 0.0


@dataclass(frozen=True)
class Prescribed:
    """Prescribed displacement history of some nodes along one direction.

    nodes: node indices; dof: 0, 1 or 2 (x, y, z); times (s) and values (m): piecewise-linear
    displacement u(t) added to the reference coordinate. Reaction force is reported for these nodes.
    """

    nodes: np.ndarray
    dof: int
    times: np.ndarray
    values: np.ndarray

    def displacement(self, t: float) -> float:
        """Displacement (m) at time t (s), piecewise linear, held constant after the last time."""
        return float(np.interp(t, self.times, self.values))

    def velocity(self, t: float) -> float:
        """Velocity (m/s) at time t (s): slope of the segment containing t (zero after the end)."""
        i = int(np.searchsorted(self.times, t, side="right")) - 1
        if i < 0 or i >= len(self.times) - 1:
            return 0.0
        return float((self.values[i + 1] - self.values[i]) / (self.times[i + 1] - self.times[i]))


@dataclass(frozen=True)
class Model:
    """Everything a backend needs to run one scene.

    nodes: (n, 3) reference coordinates (m). hexes: (e, 8) connectivity in meshio/VTK hexahedron
    order (bottom face counter-clockwise seen from above, then top face). density (kg/m^3).
    material: a bound :class:`cfm_core.material.Material`. fixed_dofs: (k, 2) pairs (node, dof)
    whose velocity is held at zero (symmetry planes, clamps). sphere_nodes / plane_nodes: nodes
    that may touch the sphere / the plane. friction: Coulomb coefficient (-) on both contacts.
    end_time (s); output_interval (s): histories are recorded at least this often.
    symmetry_factor: full-model force = factor x modelled force (4 for a quarter model).
    mass_full (kg): the real impactor mass, for acceleration = full contact force / mass_full.
    """

    name: str
    nodes: np.ndarray
    hexes: np.ndarray
    density: float
    material: "Material"
    end_time: float
    output_interval: float
    fixed_dofs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    prescribed: Prescribed | None = None
    sphere: RigidSphere | None = None
    plane: RigidPlane | None = None
    sphere_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    plane_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    friction: float = 0.0
    symmetry_factor: float = 1.0
    mass_full: float | None = None
    gravity: float = 0.0
    stop_after_separation: bool = True
    meta: dict = field(default_factory=dict)

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.shape[0])

    @property
    def n_elements(self) -> int:
        return int(self.hexes.shape[0])
