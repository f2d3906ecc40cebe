"""Scene -> backend-neutral :class:`cfm_core.scene.Model` (mesh, parts, material, contacts).

Only what the scene needs is built (docs/conventions.md section 4): the drop test gets a rigid sphere and
a rigid plane instead of meshed metal, and a quarter model with symmetry planes by default; the
single element gets a prescribed top-face motion and no contact; the relaxation scene is the
single element without inertia (quasi-static). SI units: m, s, kg, Pa.
"""

from __future__ import annotations

import numpy as np

from .mesh import nodes_on_plane, structured_hex_mesh
from .model import Model, Prescribed, RigidPlane, RigidSphere
from .scene import Scene
from .sections import read_specimen_mesh
from ..material.registry import make_material


def build_model(scene: Scene, material=None) -> Model:
    """Build the model of a validated scene.

    Only what the scene needs is built (docs/conventions.md section 4). Drop test: the specimen
    z in [0, thickness] on the rigid plane z = 0, the rigid sphere touching its top at the
    centre moving down at the impact speed; with quarter symmetry only x, y >= 0 is meshed
    (u_x = 0 on x = 0, u_y = 0 on y = 0), the sphere carries a quarter of the mass and
    ``symmetry_factor`` is 4. Single element / relaxation: one cube of edge ``size`` with a
    prescribed top-face displacement ramp to (stretch - 1) size, then a hold; relaxation has no
    inertia (density 0, ``meta["quasi_static"]``).

    Parameters
    ----------
    scene : Scene
        A validated scene.
    material : Material, optional
        An already bound :class:`cfm_core.material.Material` to use instead of the one the scene
        names (for tests and studies); default: ``cfm_core.material.make_material(name,
        parameters, moduli, elastic)`` from the scene's [material] section.

    Returns
    -------
    Model
        The backend-neutral model: nodes (n, 3) in m, hexes (e, 8), rigid bodies, boundary
        conditions, end time and output interval (s), ``meta`` with the scene's values.

    Raises
    ------
    InputError
        The scene's material is unknown or its parameters are invalid, or its specimen mesh
        file cannot be read.
    """
    if material is None:

        m = scene.material
        material = make_material(m.name, m.parameter_dict, m.moduli, m.elastic)
    build = {"drop-test": _drop_test, "relaxation": _relaxation}.get(scene.type, _single_element)
    model = build(scene, material)
    model.meta["checks"] = scene.settings.checks()  # limits of cfm_core.simulation.checks
    return model


def _fixed(nodes_dofs: list[tuple[np.ndarray, int]]) -> np.ndarray:
    """(k, 2) int64 array of (node, dof) pairs, sorted, without duplicates."""
    parts = [np.column_stack([n, np.full(len(n), d)]) for n, d in nodes_dofs if len(n)]
    if not parts:
        return np.zeros((0, 2), dtype=np.int64)
    return np.unique(np.vstack(parts).astype(np.int64), axis=0)


def _mirror_lateral(nodes: np.ndarray, nx: int, ny: int, half: float) -> None:
    """Make x and y of a full structured grid exactly mirror-symmetric about 0 (in place).

    The coordinates become -q[::-1] | q[1:] with q = the quarter model's coordinates, so the full
    and quarter models share their nodes exactly and the centre lines lie exactly at 0 m.
    """
    idx = np.arange(len(nodes))
    for axis, n, stride, period in ((0, nx, 1, nx + 1), (1, ny, nx + 1, ny + 1)):
        q = np.linspace(0.0, half, n // 2 + 1)
        full = np.concatenate([-q[::-1], q[1:]])
        nodes[:, axis] = full[(idx // stride) % period]


def _drop_test(scene: Scene, material) -> Model:
    """Specimen z in [0, h] centred at x = y = 0 on the plane z = 0; sphere touching at the top.

    Quarter symmetry: only x, y >= 0 is meshed; u_x = 0 on x = 0 and u_y = 0 on y = 0; the
    sphere carries a quarter of the mass and the symmetry factor is 4. The bottom is not fixed:
    the plate is a (frictionless by default) contact.
    """
    sp, imp = scene.specimen, scene.impactor
    quarter = sp.symmetry == "quarter"
    if sp.mesh is not None:
        nodes, hexes, _ = read_specimen_mesh(sp.mesh, bool(sp.merge_nodes))
        nodes, hexes = nodes.copy(), hexes.copy()
        grid = None
    else:
        nx, ny, nz = grid = sp.grid
        if quarter:
            lx = ly = sp.width / 2.0
            origin = (0.0, 0.0, 0.0)
        else:  # the mirrored quarter grid: 2 * nq elements across, a node line at x = 0, y = 0
            lx = ly = sp.width
            origin = (-sp.width / 2.0, -sp.width / 2.0, 0.0)
        nodes, hexes = structured_hex_mesh(lx, ly, sp.thickness, nx, ny, nz, origin)
        if not quarter:
            _mirror_lateral(nodes, nx, ny, sp.width / 2.0)
    h = sp.thickness
    tol = 1e-6 * sp.element_size
    top = nodes_on_plane(nodes, 2, h, tol)
    bottom = nodes_on_plane(nodes, 2, 0.0, tol)
    if quarter:
        fixed = _fixed([(nodes_on_plane(nodes, 0, 0.0, tol), 0),
                        (nodes_on_plane(nodes, 1, 0.0, tol), 1)])
        factor = 4.0
    else:
        fixed = _fixed([])
        factor = 1.0
    sphere = RigidSphere(radius=imp.radius, mass=imp.mass / factor,
                         center=(0.0, 0.0, h + imp.radius), velocity=-imp.velocity)
    meta = {
        "scene_type": scene.type, "symmetry": sp.symmetry, "thickness": h, "width": sp.width,
        "element_size": sp.element_size, "density": sp.density, "velocity": imp.velocity,
        "impactor_mass": imp.mass, "impactor_radius": imp.radius,
        "friction": scene.contact.friction, "mesh": sp.mesh, "grid": grid,
        "moduli": scene.material.moduli, "elastic": scene.material.elastic,
        "end_time_automatic": scene.settings.end_time is None,
    }
    return Model(
        name=scene.settings.name, nodes=nodes, hexes=hexes, density=sp.density,
        material=material, end_time=scene.end_time,
        output_interval=1.0 / scene.settings.output_rate, fixed_dofs=fixed,
        sphere=sphere, plane=RigidPlane(0.0), sphere_nodes=top, plane_nodes=bottom,
        friction=scene.contact.friction, symmetry_factor=factor, mass_full=imp.mass,
        stop_after_separation=True, meta=meta,
    )


def _single_element(scene: Scene, material) -> Model:
    """One cube of edge ``size`` in [0, size]^3 in uniaxial stress.

    Fixed: u_z on the bottom face, u_x on x = 0, u_y on y = 0 (free lateral faces, so the
    deformation is homogeneous). The top face moves u_z(t) linearly to (stretch - 1) * size in
    t_load = |stretch - 1| / rate, then holds (the hold point is left out when hold = 0).
    """
    el = scene.element
    a = el.size
    nodes, hexes = structured_hex_mesh(a, a, a, 1, 1, 1)
    tol = 1e-9 * a
    bottom = nodes_on_plane(nodes, 2, 0.0, tol)
    top = nodes_on_plane(nodes, 2, a, tol)
    fixed = _fixed([(bottom, 2), (nodes_on_plane(nodes, 0, 0.0, tol), 0),
                    (nodes_on_plane(nodes, 1, 0.0, tol), 1)])
    t_load = el.load_time
    d = (el.stretch - 1.0) * a
    times, values = [0.0, t_load], [0.0, d]
    if el.hold > 0.0:
        times.append(t_load + el.hold)
        values.append(d)
    prescribed = Prescribed(nodes=top, dof=2, times=np.array(times), values=np.array(values))
    meta = {
        "scene_type": scene.type, "size": a, "stretch": el.stretch, "rate": el.rate,
        "hold": el.hold, "load_time": t_load, "density": el.density,
        "moduli": scene.material.moduli, "elastic": scene.material.elastic,
    }
    return Model(
        name=scene.settings.name, nodes=nodes, hexes=hexes, density=el.density,
        material=material, end_time=scene.end_time,
        output_interval=1.0 / scene.settings.output_rate, fixed_dofs=fixed,
        prescribed=prescribed, stop_after_separation=False, meta=meta,
    )


def _relaxation(scene: Scene, material) -> Model:
    """One cube of edge ``size`` in [0, size]^3, quasi-static (no inertia).

    Fixed: u_z on the bottom face, u_x on x = 0, u_y on y = 0; with lateral = "confined" also
    u_x on x = size and u_y on y = size (uniaxial strain), else the lateral faces are free
    (uniaxial stress). The top face moves u_z(t) linearly to (stretch - 1) * size in load_time,
    then holds until load_time + hold. ``meta["quasi_static"]`` is True and density is 0: the
    scene has no inertia (explicit backends cannot run it).
    """
    rx = scene.relaxation
    a = rx.size
    nodes, hexes = structured_hex_mesh(a, a, a, 1, 1, 1)
    tol = 1e-9 * a
    sets = [(nodes_on_plane(nodes, 2, 0.0, tol), 2), (nodes_on_plane(nodes, 0, 0.0, tol), 0),
            (nodes_on_plane(nodes, 1, 0.0, tol), 1)]
    if rx.lateral == "confined":
        sets += [(nodes_on_plane(nodes, 0, a, tol), 0), (nodes_on_plane(nodes, 1, a, tol), 1)]
    top = nodes_on_plane(nodes, 2, a, tol)
    d = (rx.stretch - 1.0) * a
    prescribed = Prescribed(nodes=top, dof=2, times=np.array([0.0, rx.load_time, rx.load_time + rx.hold]),
                            values=np.array([0.0, d, d]))
    meta = {
        "scene_type": scene.type, "size": a, "stretch": rx.stretch, "load_time": rx.load_time,
        "hold": rx.hold, "lateral": rx.lateral, "quasi_static": True,
        "moduli": scene.material.moduli, "elastic": scene.material.elastic,
    }
    return Model(
        name=scene.settings.name, nodes=nodes, hexes=hexes, density=0.0,
        material=material, end_time=scene.end_time,
        output_interval=1.0 / scene.settings.output_rate, fixed_dofs=_fixed(sets),
        prescribed=prescribed, stop_after_separation=False, meta=meta,
    )
