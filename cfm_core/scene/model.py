"""Backend-neutral model: what a scene becomes before a backend runs it.

Plain numpy arrays and small frozen dataclasses, SI units (m, s, kg, Pa). Backends read these and
nothing else; they never see the scene file. A scene includes only what it needs: ``sphere`` and
``plane`` are ``None`` when absent, ``prescribed`` is ``None`` when no boundary motion is imposed.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError

#: Memory a run needs per element at least (bytes): the numba backend's arrays measured 2.6 kB per
#: element (tracemalloc peak of its set-up, 5 000 and 40 000 elements); torch and the implicit
#: skfem backend (sparse matrix, factorisation) need more.
BYTES_PER_ELEMENT = 2600
#: Memory per node at least (bytes): coordinates, velocities, forces, masses (float64).
BYTES_PER_NODE = 200

if TYPE_CHECKING:  # pragma: no cover
    from ..material.material import Material


IMPACTOR_SHAPES = ("hemisphere", "sphere", "flat", "plane")


@dataclass(frozen=True)
class RigidSphere:
    """Rigid impactor that translates without rotating (a guided drop-tower carriage).

    The name is historical: the shape is ``shape``. Its surface and outward normal are given by
    :func:`cfm_core.scene.impactor.gap` (one formula per shape).

    Parameters
    ----------
    radius : float
        Sphere or hemisphere radius; for ``"flat"`` the radius of the cylinder; unused for
        ``"plane"`` (m).
    mass : float
        Mass of the *modelled part* (kg): a quarter model carries a quarter of the mass.
    center : tuple of float, shape (3,)
        Reference point at t = 0 (m): the centre of the sphere / hemisphere; the centre of the
        flat bottom face of ``"flat"``; a point of the plane (its height) for ``"plane"``.
    velocity : float
        Velocity along z at t = 0 (m/s); negative: moving down onto the specimen.
    shape : str
        ``"hemisphere"`` (only the lower half, n_z < 0, can touch: the paper's impactor),
        ``"sphere"``, ``"flat"`` (cylinder of radius ``radius`` with axis z, bottom face down, its
        rim rounded with ``edge_radius``), ``"plane"`` (infinite rigid plane z = centre z, the
        specimen below it).
    edge_radius : float
        Radius of the rounded rim of ``"flat"`` (m), 0 <= edge_radius < radius; 0 otherwise.
    velocity_xy : tuple of float, shape (2,)
        In-plane velocity components (vx, vy) at t = 0 (m/s), oblique impacts.
    moves : tuple of bool, shape (3,)
        Which translations the modelled impactor has (x, y, z): a symmetry plane x = 0 holds x,
        y = 0 holds y. Default z only.
    """

    radius: float
    mass: float
    center: tuple[float, float, float]
    velocity: float
    shape: str = "hemisphere"
    edge_radius: float = 0.0
    velocity_xy: tuple[float, float] = (0.0, 0.0)
    moves: tuple[bool, bool, bool] = (False, False, True)

    @property
    def velocity_vector(self) -> np.ndarray:
        """(3,) initial velocity (m/s)."""
        return np.array([float(self.velocity_xy[0]), float(self.velocity_xy[1]), float(self.velocity)])

    @property
    def lateral(self) -> bool:
        """True when the impactor may move in x or y (no symmetry plane holds it)."""
        return bool(self.moves[0] or self.moves[1])

    @property
    def bottom(self) -> float:
        """Offset (m) of the lowest point below the reference point's z: radius for a sphere or
        hemisphere, 0 for ``"flat"`` and ``"plane"``."""
        return float(self.radius) if self.shape in ("sphere", "hemisphere") else 0.0


#: The general name of the rigid impactor (the same class).
RigidImpactor = RigidSphere


@dataclass(frozen=True)
class Part:
    """One region of the specimen with its own material and density.

    Parameters
    ----------
    name : str
        Part name (a layer's or a mesh cell set's), for messages and outputs.
    material : Material
        A bound :class:`cfm_core.material.Material`.
    density : float
        Mass density (kg/m^3).
    elements : ndarray, shape (k,)
        Indices of the part's hexahedra in ``Model.hexes`` (int64, sorted, disjoint from the
        other parts'; together the parts cover every element).
    """

    name: str
    material: "Material"
    density: float
    elements: np.ndarray


@dataclass(frozen=True)
class RigidPlane:
    """Rigid fixed plane z = ``z`` (m) with normal +z; the specimen lies above it.

    Parameters
    ----------
    z : float
        Height of the plane (m).
    """

    z: float = 0.0


@dataclass(frozen=True)
class Prescribed:
    """Prescribed displacement history of some nodes along one direction.

    Reaction force is reported for these nodes.

    Parameters
    ----------
    nodes : ndarray, shape (k,)
        Node indices (int).
    dof : int
        Direction: 0, 1 or 2 (x, y, z).
    times : ndarray, shape (p,)
        Increasing times of the breakpoints (s), starting at 0.
    values : ndarray, shape (p,)
        Displacement u at those times (m), added to the reference coordinate; piecewise linear
        in between, held after the last time.
    """

    nodes: np.ndarray
    dof: int
    times: np.ndarray
    values: np.ndarray

    def displacement(self, t: float) -> float:
        """Displacement (m) at time t (s), piecewise linear, held constant after the last time.

        Parameters
        ----------
        t : float
            Time (s).

        Returns
        -------
        float
            u(t) (m); ``values[0]`` before the first time.
        """
        return float(np.interp(t, self.times, self.values))

    def velocity(self, t: float) -> float:
        """Velocity (m/s) at time t (s): slope of the segment containing t (zero after the end).

        Parameters
        ----------
        t : float
            Time (s); at a breakpoint the slope of the segment that starts there.

        Returns
        -------
        float
            du/dt (m/s); 0 before the first and from the last time on.
        """
        i = int(np.searchsorted(self.times, t, side="right")) - 1
        if i < 0 or i >= len(self.times) - 1:
            return 0.0
        return float((self.values[i + 1] - self.values[i]) / (self.times[i + 1] - self.times[i]))


@dataclass(frozen=True)
class Model:
    """Everything a backend needs to run one scene (made by :func:`cfm_core.scene.build_model`).

    Parameters
    ----------
    name : str
        Scene name, for messages and outputs.
    nodes : ndarray, shape (n, 3)
        Reference coordinates (m).
    hexes : ndarray, shape (e, 8)
        Connectivity in meshio/VTK hexahedron order (bottom face counter-clockwise seen from
        above, then top face).
    density : float
        Mass density (kg/m^3); 0 for a quasi-static scene.
    material : Material
        A bound :class:`cfm_core.material.Material`.
    end_time : float
        Simulated end time (s).
    output_interval : float
        Histories are recorded at least this often (s).
    fixed_dofs : ndarray, shape (k, 2)
        (node, dof) pairs whose velocity is held at zero (symmetry planes, clamps).
    prescribed : Prescribed, optional
        Imposed boundary motion; None when there is none.
    sphere, plane : RigidSphere, RigidPlane, optional
        Rigid bodies; None when absent.
    sphere_nodes, plane_nodes : ndarray, shape (k,)
        Nodes that may touch the sphere / the plane.
    friction : float
        Coulomb coefficient (-) on both contacts.
    symmetry_factor : float
        Full-model force = factor x modelled force (4 for a quarter model).
    mass_full : float, optional
        The real impactor mass (kg), for acceleration = full contact force / mass_full.
    gravity : float
        Gravitational acceleration on the impactor (m/s^2); its magnitude acts along -z. 0 in
        the built-in scenes.
    stop_after_separation : bool
        End the run once the impactor has left the specimen.
    meta : dict
        The scene's values for summaries (scene_type, thickness in m, ...; ``quasi_static``).
    parts : tuple of Part
        Regions with their own material and density; empty for a one-material model, whose one
        part is ``material`` and ``density`` on every element (:meth:`part_list`). When given,
        ``material`` and ``density`` are those of the first part.
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
    parts: tuple = ()

    def part_list(self) -> tuple[Part, ...]:
        """The parts of the model.

        Returns
        -------
        tuple of Part
            ``parts``, or one part named after the material on every element when ``parts`` is
            empty.
        """
        if self.parts:
            return tuple(self.parts)
        return (Part(self.material.name, self.material, float(self.density),
                     np.arange(self.n_elements, dtype=np.int64)),)

    @property
    def multi_material(self) -> bool:
        """True when more than one part (the backends group elements by part)."""
        return len(self.parts) > 1

    def element_part(self) -> np.ndarray:
        """Part of each element.

        Returns
        -------
        ndarray, shape (e,)
            int64 index in :meth:`part_list` of each element's part.
        """
        out = np.zeros(self.n_elements, dtype=np.int64)
        for i, p in enumerate(self.part_list()):
            out[np.asarray(p.elements, dtype=np.int64)] = i
        return out

    def element_density(self) -> np.ndarray:
        """Mass density of each element.

        Returns
        -------
        ndarray, shape (e,)
            Density of each element's part (kg/m^3).
        """
        rho = np.array([float(p.density) for p in self.part_list()])
        return rho[self.element_part()]

    @property
    def n_nodes(self) -> int:
        """Number of nodes n."""
        return int(self.nodes.shape[0])

    @property
    def n_elements(self) -> int:
        """Number of hexahedra e."""
        return int(self.hexes.shape[0])


def available_memory() -> int | None:
    """Memory the system can still give this process (bytes), or None where it cannot tell.

    Returns
    -------
    int or None
        ``MemAvailable`` of ``/proc/meminfo`` (Linux), else the free physical pages
        (``os.sysconf``), else None.
    """
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def memory_needed(n_elements: int, n_nodes: int) -> int:
    """A lower bound of the memory a run of a model needs (bytes).

    Parameters
    ----------
    n_elements, n_nodes : int
        Hexahedra and nodes of the modelled part.

    Returns
    -------
    int
        ``n_elements * BYTES_PER_ELEMENT + n_nodes * BYTES_PER_NODE`` (bytes).
    """
    return int(n_elements) * BYTES_PER_ELEMENT + int(n_nodes) * BYTES_PER_NODE


def check_memory(n_elements: int, n_nodes: int, what: str) -> None:
    """Refuse a model too big for the memory available, before its arrays are allocated.

    Parameters
    ----------
    n_elements, n_nodes : int
        Hexahedra and nodes of the modelled part.
    what : str
        Where the size comes from, for the message (e.g. "[specimen] element_size = 1e-4 m").

    Raises
    ------
    InputError
        :func:`memory_needed` exceeds :func:`available_memory`; the message names the element
        and node counts and the GiB needed and available.
    """
    need, have = memory_needed(n_elements, n_nodes), available_memory()
    if have is not None and need > have:
        raise InputError(too_big(n_elements, n_nodes, what, have))


def too_big(n_elements: int, n_nodes: int, what: str, have: int | None = None) -> str:
    """The message for a model too big for memory (also after a MemoryError), one paragraph.

    Parameters
    ----------
    n_elements, n_nodes : int
        Hexahedra and nodes of the modelled part.
    what : str
        Where the size comes from.
    have : int, optional
        Available memory (bytes); default :func:`available_memory`.

    Returns
    -------
    str
        Names the counts, the GiB needed (at least) and available, and what to change.
    """
    have = available_memory() if have is None else have
    avail = f"{have / 2**30:.3g} GiB available" if have is not None else "the available memory is unknown"
    return (f"{what} gives a model of {n_elements:,} elements and {n_nodes:,} nodes, which needs at least "
            f"{memory_needed(n_elements, n_nodes) / 2**30:.3g} GiB ({BYTES_PER_ELEMENT} bytes per element, "
            f"{BYTES_PER_NODE} per node), but {avail}. Use a coarser mesh (a larger element_size, m), quarter "
            f"symmetry or a machine with more memory.")
