"""ParaView time series of a drop test's fields: specimen and impactor blocks, one ``.pvd``.

Per frame ``specimen_XXXX.vtu`` (points written *deformed*, x = X + u, so ParaView shows the dent
without a filter; the reference mesh is X = x - displacement, "Warp By Vector" with scale -1) with
the element and point fields of :mod:`cfm_core.post.fields`, and ``impactor_XXXX.vtu``, the
lower cap of the rigid sphere at its position at the frame time (triangles, m). ``specimen.pvd``
names each frame's time (s) and holds the two blocks as parts 0 (specimen) and 1 (impactor).
``fields.json`` lists every array with its unit and meaning (the unit is also in each array's
name, e.g. ``von_mises [Pa]``). Frames are computed and written in a few threads (numpy's
eigen-decomposition, base64 and the file writes release the GIL), uncompressed: zlib cost about
8 times the writing time (measured: 122 ms against 14 ms per frame of 5000 elements).

``full=True`` mirrors a quarter model about its symmetry planes x = 0 and y = 0 into the whole
specimen: points and vectors reflect (the normal component changes sign) and tensors transform
as R sigma R with R the reflection, so the shear components 12 and 13 change sign across x = 0,
12 and 23 across y = 0; scalars (J, pressure, von Mises, principal strains, fibre switches) are
copied.
"""

from __future__ import annotations

import json
import math
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from ..errors import InputError, NumericalError
from .fields import FIELDS, cell_fields, deformation_gradients, mean_gradients
from .writers import atomic_write

#: Sign of each Voigt component (11, 22, 33, 12, 23, 13) under a reflection of axis 0 or 1.
_VOIGT_SIGN = {0: np.array([1, 1, 1, -1, 1, -1.0]), 1: np.array([1, 1, 1, -1, -1, 1.0])}
#: VTK hexahedron order of a reflected element (bottom and top faces reversed: positive volume).
_REFLECTED_HEX = np.array([0, 3, 2, 1, 4, 7, 6, 5])


def mirror(nodes, hexes, point, cell, axis: int, at: float = 0.0, tol: float = 1e-12):
    """Mirror a mesh and its fields about the plane x_axis = at; nodes on the plane are shared.

    Parameters
    ----------
    nodes : ndarray, shape (n, 3)
        Coordinates (m), on one side of the plane.
    hexes : ndarray, shape (e, 8)
        Node indices, VTK order.
    point, cell : dict of str to ndarray
        Point fields (n, ...) and cell fields (e, ...); key -> array. Vectors (3 components)
        and Voigt tensors (6 components, key ``cauchy_stress``) are reflected, others copied.
    axis : int
        0 (x) or 1 (y).
    at : float
        Plane position (m).
    tol : float
        Distance (m, relative to the mesh size) below which a node lies on the plane.

    Returns
    -------
    nodes, hexes, point, cell
        The mirrored mesh (the original first, then the mirror image) and fields.
    """
    nodes = np.asarray(nodes, dtype=np.float64)
    scale = max(float(np.ptp(nodes)), 1e-300)
    on = np.abs(nodes[:, axis] - at) <= tol * scale
    new = np.flatnonzero(~on)
    index = np.arange(len(nodes))
    index[new] = len(nodes) + np.arange(len(new))
    image = nodes[new].copy()
    image[:, axis] = 2.0 * at - image[:, axis]
    out_nodes = np.vstack([nodes, image])
    out_hexes = np.vstack([hexes, index[np.asarray(hexes)][:, _REFLECTED_HEX]])

    def reflect(key, a, rows):
        b = np.asarray(a, dtype=np.float64)[rows].copy()
        if key in ("displacement", "velocity"):
            b[:, axis] = -b[:, axis]
        elif key == "cauchy_stress":
            b = b * _VOIGT_SIGN[axis]
        return b

    out_point = {k: np.concatenate([a, reflect(k, a, new)]) for k, a in point.items()}
    out_cell = {k: np.concatenate([a, reflect(k, a, slice(None))]) for k, a in cell.items()}
    return out_nodes, out_hexes, out_point, out_cell


def sphere_cap(radius: float, center, quadrant: bool, n_polar: int = 48, n_azimuth: int = 48):
    """Triangulated lower half of a sphere (the impactor's contact surface).

    Parameters
    ----------
    radius : float
        Sphere radius (m).
    center : sequence of float, shape (3,)
        Centre (m).
    quadrant : bool
        Only the part over x, y >= centre (a quarter model); else the whole lower half.
    n_polar, n_azimuth : int
        Divisions from the pole to the equator and around the axis (whole circle).

    Returns
    -------
    points : ndarray, shape (p, 3)
        Vertices (m).
    triangles : ndarray, shape (q, 3)
        Vertex indices.
    """
    span = 0.5 * math.pi if quadrant else 2.0 * math.pi
    na = n_azimuth // 4 if quadrant else n_azimuth
    theta = np.linspace(0.0, 0.5 * math.pi, n_polar + 1)[1:]
    phi = np.linspace(0.0, span, na + 1)[: na + 1 if quadrant else na]
    cols = len(phi)
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), -np.cos(th)], axis=-1).reshape(-1, 3)
    points = np.vstack([[0.0, 0.0, -1.0], ring]) * radius + np.asarray(center, dtype=np.float64)
    tris = []
    wrap = 0 if quadrant else 1
    for j in range(cols - 1 + wrap):
        j1 = (j + 1) % cols
        tris.append((0, 1 + j, 1 + j1))
        for i in range(n_polar - 1):
            a, b = 1 + i * cols + j, 1 + i * cols + j1
            tris += [(a, a + cols, b + cols), (a, b + cols, b)]
    return points, np.asarray(tris, dtype=np.int64)


def _frame_fields(model, B, u, state, keys):
    x = model.nodes + u
    F = deformation_gradients(B, model.hexes, x)
    cell, exact = cell_fields(model.material, F, keys, state, getattr(model, "material_ids", None))
    point = {"displacement": u} if "displacement" in keys else {}
    if "velocity" in keys and state is not None and "velocity" in state:
        point["velocity"] = np.asarray(state["velocity"], dtype=np.float64)
    return x, point, cell, exact


def _array_names(fields: dict, exact: bool) -> dict:
    suffix = "" if exact else "_instantaneous"
    return {k: FIELDS[k].array_name(suffix if k in ("cauchy_stress", "pressure", "von_mises") else "")
            for k in fields}


def write_field_series(out_dir, model, result, keys, full: bool = False) -> list[str]:
    """Write the specimen and impactor series of a drop test's stored frames.

    Parameters
    ----------
    out_dir : str or path-like
        Existing output folder: a stage (:func:`cfm_core.post.staging.staged_folder`), published
        whole by the caller; the frame files are written uncompressed (binary, base64: zlib
        took most of the writing time) and not one by one atomically.
    model : Model
        The model that ran (reference nodes, hexes, material, sphere, symmetry in ``meta``).
    result : Result
        The run's result with ``frames`` and, when the backend stores them, ``frame_state``
        (velocity m/s, Prony state) and ``impactor_z`` (m) at the output times ``t`` (s).
    keys : sequence of str
        Field keys (:data:`cfm_core.post.fields.FIELDS`).
    full : bool
        Mirror a quarter model into the whole specimen (see the module docstring).

    Returns
    -------
    list of str
        The names written: ``specimen.pvd``, ``fields.json`` and the frame files as
        ``specimen_*.vtu (N frames)`` / ``impactor_*.vtu (N frames)``.

    Raises
    ------
    InputError
        ``full`` for a model that is not a quarter model.
    NumericalError
        A non-finite frame time or displacement (nothing of the series is written).
    """
    import meshio

    out = Path(out_dir)
    quarter = (model.meta or {}).get("symmetry") == "quarter"
    if full and not quarter:
        raise InputError(f"--full mirrors a quarter model; this run's symmetry is "
                         f"{(model.meta or {}).get('symmetry')!r}, already the whole specimen.")
    frames = list(result.frames)
    states = list(getattr(result, "frame_state", None) or [None] * len(frames))
    for k, (t, u) in enumerate(frames):
        if not (math.isfinite(float(t)) and np.isfinite(u).all()):
            raise NumericalError(f"frame {k} (t = {float(t):g} s) has a non-finite time or displacement; "
                                 f"nothing was written.", quantity="displacement")
    B = mean_gradients(model.nodes, model.hexes)
    width = max(4, len(str(len(frames) - 1)))
    sph = model.sphere
    if sph is not None:
        cap_points, cap_tris = sphere_cap(sph.radius, (sph.center[0], sph.center[1], 0.0), quadrant=quarter and not full)

    def write_frame(k):
        (t, u), state = frames[k], states[k]
        x, point, cell, exact = _frame_fields(model, B, np.asarray(u, dtype=np.float64), state, keys)
        hexes = np.asarray(model.hexes, dtype=np.int64)
        if full:
            x, hexes, point, cell = mirror(x, hexes, point, cell, axis=0, at=float(sph.center[0]))
            x, hexes, point, cell = mirror(x, hexes, point, cell, axis=1, at=float(sph.center[1]))
        names = {**_array_names(point, True), **_array_names(cell, exact)}
        mesh = meshio.Mesh(x, [("hexahedron", hexes)], point_data={names[k_]: a for k_, a in point.items()},
                           cell_data={names[k_]: [a] for k_, a in cell.items()})
        name = f"specimen_{k:0{width}d}.vtu"
        meshio.write(out / name, mesh, file_format="vtu", compression=None)  # a stage: published whole
        entries = [f'    <DataSet timestep="{float(t)!r}" group="" part="0" file="{name}"/>']
        if sph is not None:
            z = float(np.interp(t, result.t, result.impactor_z)) if result.impactor_z is not None else sph.center[2]
            iname = f"impactor_{k:0{width}d}.vtu"
            cap = meshio.Mesh(cap_points + np.array([0.0, 0.0, z]), [("triangle", cap_tris)])
            meshio.write(out / iname, cap, file_format="vtu", compression=None)
            entries.append(f'    <DataSet timestep="{float(t)!r}" group="" part="1" file="{iname}"/>')
        return entries, names, exact, "velocity" in keys and "velocity" not in point

    # frames in threads: numpy's eigen-decomposition, base64 and file writes release the GIL
    with ThreadPoolExecutor(max_workers=max(1, min(4, os.cpu_count() or 1))) as pool:
        done = list(pool.map(write_frame, range(len(frames))))
    entries = [e for d in done for e in d[0]]
    names = done[-1][1] if done else {}
    exact = all(d[2] for d in done)
    velocity_left = any(d[3] for d in done)
    notes = {"points": "deformed coordinates x = X + u (m); reference: X = x - displacement",
             "symmetry": "full (mirrored quarter)" if full else (model.meta or {}).get("symmetry"),
             "stress": ("the solver's stress (elastic material or Prony state stored by the backend)" if exact
                        else "instantaneous (elastic) response: the backend stored no Prony state, so the "
                             "viscous part is missing; arrays carry the suffix _instantaneous"),
             "velocity": ("not written: this backend stores no velocities at frames" if velocity_left else
                          "nodal velocity (explicit backends: half-step v^(n+1/2))"),
             "arrays": {names[k_]: {"field": k_, "where": FIELDS[k_].where, "unit": FIELDS[k_].unit,
                                    "components": FIELDS[k_].components, "description": FIELDS[k_].description}
                        for k_ in names},
             "impactor": "impactor_*.vtu: lower cap of the rigid sphere (m), part 1 of specimen.pvd"}
    atomic_write(out / "fields.json", lambda tmp: Path(tmp).write_text(json.dumps(notes, indent=1) + "\n"))
    pvd = "\n".join(['<?xml version="1.0"?>',
                     "<!-- time in s; points in m, deformed; units of each array in its name and fields.json -->",
                     '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                     "  <Collection>", *entries, "  </Collection>", "</VTKFile>", ""])
    atomic_write(out / "specimen.pvd", lambda tmp: Path(tmp).write_text(pvd, encoding="utf-8"))
    written = ["specimen.pvd", "fields.json", f"specimen_*.vtu ({len(frames)} frames)"]
    if sph is not None:
        written.append(f"impactor_*.vtu ({len(frames)} frames)")
    return written
