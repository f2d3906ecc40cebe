"""Scene -> backend-neutral :class:`cfm_core.scene.Model` (mesh, parts, material, contacts).

Only what the scene needs is built (docs/conventions.md section 4): the drop test gets a rigid sphere and
a rigid plane instead of meshed metal, and a quarter model with symmetry planes by default; the
single element gets a prescribed top-face motion and no contact; the relaxation scene is the
single element without inertia (quasi-static). SI units: m, s, kg, Pa.

Before anything is allocated, the builder refuses (InputError) a scene whose histories would have
more than :data:`MAX_HISTORY_ROWS` rows (output_rate x end time: a solver records at most once per
step, so a rate above its step rate is interpolation, and 1e9 Hz wrote a 568 MB CSV) and a model
whose arrays need more memory than the system has (:func:`cfm_core.scene.model.check_memory`).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .mesh import facing_nodes, nodes_on_plane, structured_hex_mesh
from .layers import bind_material, layer_cells, layer_z, mesh_part_elements
from .model import Model, Part, Prescribed, RigidPlane, RigidSphere, check_memory, too_big
from .scene import Scene
from .sections import read_specimen_mesh
from ..material.registry import make_material

#: Most rows a history may have (output_rate x end time): about 50 MB of CSV at about 50 bytes a
#: row (the drop-test CSV: t, a_raw, a_cfc600). The explicit solvers' steps are 1e-6 .. 1e-5 s for
#: 1 .. 2 mm elements, so a 85 ms drop test reaches this only above 1e7 Hz, far above its step rate.
MAX_HISTORY_ROWS = 1_000_000
#: Bytes of CSV per history row, for the size named in messages (measured: 51 for a drop test).
ROW_BYTES = 50


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
        The scene's material is unknown or its parameters are invalid, its specimen mesh file
        cannot be read, its histories would have more than :data:`MAX_HISTORY_ROWS` rows
        (:func:`check_history_size`), or the model needs more memory than is available (names
        the element count and the GiB needed and available).
    """
    check_history_size(scene)
    if material is None:
        m = scene.material
        material = make_material(m.name, m.parameter_dict, m.moduli, m.elastic)
    build = {"drop-test": _drop_test, "relaxation": _relaxation}.get(scene.type, _single_element)
    if scene.type == "drop-test":
        n_el, n_nodes, what = _specimen_size(scene.specimen)
        check_memory(n_el, n_nodes, what)
    try:
        model = build(scene, material)
    except MemoryError:
        if scene.type != "drop-test":
            raise
        raise InputError(too_big(n_el, n_nodes, what)) from None
    model.meta["checks"] = scene.settings.checks()  # limits of cfm_core.simulation.checks
    _check_tolerance(model)
    return model


def _check_tolerance(model) -> None:
    """Refuse a ``[scene] penetration_tolerance`` of at least half the model's height: the bottoming-out
    check counts an impactor within the tolerance of the plate as having reached it, so such a run stopped
    at first contact blaming an oblique impact (0.05 written for 0.05 mm)."""
    tol = model.meta["checks"].get("penetration_tolerance")
    z = np.asarray(model.nodes)[:, 2] if len(model.nodes) else np.zeros(1)
    height = float(z.max() - z.min())
    if tol is not None and height > 0.0 and tol >= 0.5 * height:
        raise InputError(
            f"[scene] penetration_tolerance = {tol:g} m is not allowed for this {height * 1e3:.3g} mm high specimen: "
            f"it is the penetration (m) the run checks allow, a fraction of an element (the default is 5 % of the "
            f"smallest edge); at half the specimen's height or more every contact reads as bottoming out. Is it in "
            f"mm? Then write {tol * 1e-3:g}.")


def check_history_size(scene: Scene) -> int:
    """Refuse a scene whose histories would have more than :data:`MAX_HISTORY_ROWS` rows.

    Parameters
    ----------
    scene : Scene
        A validated scene ([scene] output_rate in Hz, end time in s).

    Returns
    -------
    int
        The most rows its histories can have: floor(output_rate x end time) + 1.

    Raises
    ------
    InputError
        More than :data:`MAX_HISTORY_ROWS` rows; names output_rate, the end time, the rows, the
        CSV size they would take and the largest rate allowed for this end time.
    """
    rate, end = float(scene.settings.output_rate), float(scene.end_time)
    rows = int(rate * end) + 1
    if rows > MAX_HISTORY_ROWS:
        limit = (MAX_HISTORY_ROWS - 1) / end
        raise InputError(
            f"[scene] output_rate = {rate:g} Hz over the end time {end:g} s{_end_time_source(scene)} would record up "
            f"to {rows:,} history "
            f"rows, a CSV of about {rows * ROW_BYTES / 1e6:,.0f} MB (at most {MAX_HISTORY_ROWS:,} rows are "
            f"allowed). An explicit solver steps every 1e-6 .. 1e-5 s (1 .. 2 mm elements), so rows above its step "
            f"rate only interpolate; an implicit one steps at least once per output interval. Use output_rate <= {limit:.4g} Hz "
            f"(the paper's 50 000 Hz for drop tests, 100 Hz for relaxation) or a shorter end_time (s).")
    return rows


def _end_time_source(scene) -> str:
    """What set an automatic end time, for messages: a slow impactor or a slow ramp gives a long
    run, and naming the value that made it (0.001 m/s; a rate of 1e-6 1/s) points at the slip."""
    if scene.settings.end_time is not None:
        return ""
    if scene.type == "drop-test":
        return (f" (automatic: 10 x the thickness {scene.specimen.thickness:g} m over the impact speed "
                f"{scene.impactor.normal_speed:g} m/s, + 5 ms)")
    sec = scene.element if scene.type == "single-element" else scene.relaxation
    return f" (automatic: the ramp of {sec.load_time:g} s to the stretch {sec.stretch:g} and the hold of {sec.hold:g} s)"


def _specimen_size(sp) -> tuple[int, int, str]:
    """(elements, nodes, what sets them) of a drop-test specimen, before its arrays are built."""
    if sp.mesh is not None:
        nodes, hexes, _ = read_specimen_mesh(sp.mesh, bool(sp.merge_nodes))
        return int(hexes.shape[0]), int(nodes.shape[0]), f"[specimen] mesh '{sp.mesh}'"
    nx, ny, nz = sp.grid
    return nx * ny * nz, (nx + 1) * (ny + 1) * (nz + 1), f"[specimen] element_size = {sp.element_size:g} m"


def _fixed(nodes_dofs: list[tuple[np.ndarray, int]]) -> np.ndarray:
    """(k, 2) int64 array of (node, dof) pairs, sorted, without duplicates."""
    parts = [np.column_stack([n, np.full(len(n), d)]) for n, d in nodes_dofs if len(n)]
    if not parts:
        return np.zeros((0, 2), dtype=np.int64)
    return np.unique(np.vstack(parts).astype(np.int64), axis=0)


def _mirror_lateral(nodes: np.ndarray, nx: int, ny: int, half: float, axes=(0, 1)) -> None:
    """Make x (and y) of a structured grid exactly mirror-symmetric about 0 (in place).

    The coordinates along each axis in ``axes`` become -q[::-1] | q[1:] with q = the quarter
    model's coordinates, so the full, half and quarter models share their nodes exactly and the
    centre lines lie exactly at 0 m.
    """
    idx = np.arange(len(nodes))
    for axis, n, stride, period in ((0, nx, 1, nx + 1), (1, ny, nx + 1, ny + 1)):
        if axis not in axes:
            continue
        q = np.linspace(0.0, half, n // 2 + 1)
        full = np.concatenate([-q[::-1], q[1:]])
        nodes[:, axis] = full[(idx // stride) % period]


#: Symmetry -> (symmetry factor, which translations the modelled impactor has (x, y, z)).
_SYMMETRY = {"quarter": (4.0, (False, False, True)), "half": (2.0, (True, False, True)),
             "none": (1.0, (True, True, True))}


def _block(sp) -> tuple[np.ndarray, np.ndarray, tuple]:
    """Nodes and hexes of the built-in (layered) block of the modelled part, and its grid."""
    nx, ny, nz = grid = sp.grid
    w = sp.width
    if sp.symmetry == "quarter":
        lx = ly = w / 2.0
        origin = (0.0, 0.0, 0.0)
    elif sp.symmetry == "half":  # the mirrored quarter grid in x, y >= 0
        lx, ly = w, w / 2.0
        origin = (-w / 2.0, 0.0, 0.0)
    else:  # the mirrored quarter grid: 2 * nq elements across, a node line at x = 0, y = 0
        lx = ly = w
        origin = (-w / 2.0, -w / 2.0, 0.0)
    nodes, hexes = structured_hex_mesh(lx, ly, sp.thickness, nx, ny, nz, origin)
    if sp.symmetry == "none":
        _mirror_lateral(nodes, nx, ny, w / 2.0)
    elif sp.symmetry == "half":
        _mirror_lateral(nodes, nx, ny, w / 2.0, axes=(0,))
    z = layer_z(sp.layers, sp.element_size) if sp.layers else None
    if z is not None:  # layers of different spacing: exact interfaces
        nodes[:, 2] = z[np.arange(len(nodes)) // ((nx + 1) * (ny + 1))]
    return nodes, hexes, grid


def _parts(scene: Scene, material, n_el: int, nx_ny: int) -> tuple:
    """The model's parts: one per layer (from the plate up) or per [parts.NAME]; () for one material."""
    sp = scene.specimen
    if sp.layers:
        cells = layer_cells(sp.layers, sp.element_size)
        bounds = np.concatenate([[0], np.cumsum(cells)]) * nx_ny
        regions = [(lay, np.arange(bounds[i], bounds[i + 1], dtype=np.int64)) for i, lay in enumerate(sp.layers)]
    elif scene.parts:
        regions = list(zip(scene.parts, mesh_part_elements(sp.mesh, n_el, scene.parts)))
    else:
        return ()
    out = []
    for region, elements in regions:
        mat, rho = bind_material(region, scene.material, sp.density, material)
        out.append(Part(region.name, mat, rho, np.asarray(elements, dtype=np.int64)))
    return tuple(out)


def _drop_test(scene: Scene, material) -> Model:
    """Specimen z in [0, h] centred at x = y = 0 on the plane z = 0; impactor touching its top.

    Quarter symmetry: only x, y >= 0 is meshed, u_x = 0 on x = 0 and u_y = 0 on y = 0, the
    impactor carries a quarter of the mass and moves along z only, factor 4. Half: only y >= 0,
    u_y = 0 on y = 0, half the mass, the impactor moves in x and z, factor 2. None: the whole
    specimen, the impactor free to translate. The impactor's reference point starts at the
    impact point (offset), its lowest point at the top z = h. The bottom is not fixed: the plate
    is a (frictionless by default) contact. Layers and mesh parts become ``Model.parts``.
    """
    sp, imp = scene.specimen, scene.impactor
    if sp.mesh is not None:
        nodes, hexes, _ = read_specimen_mesh(sp.mesh, bool(sp.merge_nodes))
        nodes, hexes = nodes.copy(), hexes.copy()
        grid = None
    else:
        nodes, hexes, grid = _block(sp)
    h = sp.thickness
    tol = 1e-6 * sp.element_size
    if grid is None:  # a user mesh: its top and bottom surfaces, flat or not (mesh.facing_nodes)
        top, bottom = facing_nodes(nodes, hexes, up=True), facing_nodes(nodes, hexes, up=False)
    else:
        top, bottom = nodes_on_plane(nodes, 2, h, tol), nodes_on_plane(nodes, 2, 0.0, tol)
    factor, moves = _SYMMETRY[sp.symmetry]
    planes = {"quarter": [(0, 0), (1, 1)], "half": [(1, 1)], "none": []}[sp.symmetry]
    fixed = _fixed([(nodes_on_plane(nodes, axis, 0.0, tol), dof) for axis, dof in planes])
    v = imp.vector
    (ox, oy) = imp.point
    sphere = RigidSphere(radius=imp.radius, mass=imp.mass / factor, center=(ox, oy, h + imp.bottom),
                         velocity=float(v[2]), shape=imp.shape, edge_radius=imp.edge,
                         velocity_xy=(float(v[0]), float(v[1])), moves=moves)
    parts = _parts(scene, material, len(hexes), 0 if grid is None else grid[0] * grid[1])
    meta = {
        "scene_type": scene.type, "symmetry": sp.symmetry, "thickness": h, "width": sp.width,
        "element_size": sp.element_size, "density": sp.density, "velocity": imp.speed,
        "impactor_mass": imp.mass, "impactor_radius": imp.radius,
        "friction": scene.contact.friction, "mesh": sp.mesh, "grid": grid,
        "moduli": scene.material.moduli, "elastic": scene.material.elastic,
        "end_time_automatic": scene.settings.end_time is None,
        "symmetry_requested": sp.requested_symmetry, "symmetry_reason": scene.symmetry_reason,
        "impactor_shape": imp.shape, "impactor_edge_radius": imp.edge, "velocity_vector": [float(c) for c in v],
        "impact_point": [ox, oy],
    }
    if parts:  # Model.material is the first part's; this is the [material] section's (for scene.toml)
        meta["material_parameters"] = dict(material.values)
        meta["parts"] = [{"name": p.name, "material": p.material.name, "density": p.density,
                          "elements": int(len(p.elements))} for p in parts]
        if sp.layers:
            for entry, lay, n in zip(meta["parts"], sp.layers, layer_cells(sp.layers, sp.element_size)):
                entry.update(thickness=lay.thickness, cells_through_thickness=n)
    return Model(
        name=scene.settings.name, nodes=nodes, hexes=hexes,
        density=parts[0].density if parts else sp.density,
        material=parts[0].material if parts else material, end_time=scene.end_time,
        output_interval=1.0 / scene.settings.output_rate, fixed_dofs=fixed,
        sphere=sphere, plane=RigidPlane(0.0), sphere_nodes=top, plane_nodes=bottom,
        friction=scene.contact.friction, symmetry_factor=factor, mass_full=imp.mass,
        stop_after_separation=True, meta=meta, parts=parts,
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
