"""ParaView time series of a drop test's fields: specimen and impactor blocks, one ``.pvd``.

Per frame ``specimen_XXXX.vtu`` (points written *deformed*, x = X + u, so ParaView shows the dent
without a filter; the reference mesh is X = x - displacement, "Warp By Vector" with scale -1) with
the element and point fields of :mod:`cfm_core.post.fields` (each element with its own part's
material; a model with parts names them in a header note of each file: ``part ids: 0 = skin
(material neo-hookean, material_id 0); ...``), and ``impactor_XXXX.vtu``, the impactor's surface
(:mod:`cfm_core.post.impactor_mesh`, every shape) at its reference point at the frame time
(z from the history, x and y too when it moves in-plane; triangles, m). ``specimen.pvd``
names each frame's time (s) and holds the two blocks as parts 0 (specimen) and 1 (impactor).
``fields.json`` lists every array with its unit and meaning (the unit is also in each array's
name, e.g. ``von_mises [Pa]``). Frames are computed and written in a few threads (numpy's
eigen-decomposition, base64 and the file writes release the GIL), uncompressed: zlib cost about
8 times the writing time (measured: 122 ms against 14 ms per frame of 5000 elements).

``full=True`` mirrors a symmetric model into the whole specimen: a quarter model about its
symmetry planes x = 0 and y = 0 (through the impact point), a half model about y = 0. Points and
vectors reflect (the normal component changes sign) and tensors transform as R sigma R with R the
reflection, so the shear components 12 and 13 change sign across x = 0, 12 and 23 across y = 0;
scalars (J, pressure, von Mises, principal strains, fibre switches, part ids) are copied. The
symmetry is ``model.meta["symmetry"]`` ("quarter", "half", "none"), else read from the
model's ``symmetry_factor`` (4, 2, 1).
"""

from __future__ import annotations

import json
import math
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from ..errors import InputError, NumericalError
from .fields import FIELDS, deformation_gradients, distinct_materials, mean_gradients, model_cell_fields
from .impactor_mesh import impactor_positions, impactor_surface
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


def _frame_fields(model, B, u, state, keys):
    x = model.nodes + u
    F = deformation_gradients(B, model.hexes, x)
    cell, exact = model_cell_fields(model, F, keys, state)
    point = {"displacement": u} if "displacement" in keys else {}
    if "velocity" in keys and state is not None and "velocity" in state:
        point["velocity"] = np.asarray(state["velocity"], dtype=np.float64)
    return x, point, cell, exact


def _array_names(fields: dict, exact: bool) -> dict:
    suffix = "" if exact else "_instantaneous"
    return {k: FIELDS[k].array_name(suffix if k in ("cauchy_stress", "pressure", "von_mises") else "")
            for k in fields}


def symmetry_of(model) -> str:
    """The model's symmetry: ``meta["symmetry"]`` ("quarter", "half", "none"), else from its
    ``symmetry_factor`` (4: quarter, 2: half, otherwise none)."""
    sym = (model.meta or {}).get("symmetry")
    if sym in ("quarter", "half", "none"):
        return sym
    return {4: "quarter", 2: "half"}.get(int(round(float(model.symmetry_factor))), "none")


def _mirror_planes(model, sym: str) -> list[tuple[int, float]]:
    """(axis, position m) of the planes a full specimen is mirrored about."""
    if sym == "quarter":
        c = model.sphere.center if model.sphere is not None else (0.0, 0.0, 0.0)
        return [(0, float(c[0])), (1, float(c[1]))]
    return [(1, 0.0)]


def parts_note(model) -> tuple[str, list[dict]]:
    """The id -> name mapping of the parts: one line for the VTU header and a list for fields.json.

    Returns
    -------
    note : str
        ``part ids: 0 = skin (material neo-hookean, material_id 0); 1 = fat (...)``.
    parts : list of dict
        ``id``, ``name``, ``material``, ``material_id``, ``density`` (kg/m^3), ``elements``.
    """
    parts = model.part_list()
    _, of_part = distinct_materials(parts)
    rows = [{"id": i, "name": p.name, "material": p.material.name, "material_id": of_part[i],
             "density": float(p.density), "elements": int(len(p.elements))} for i, p in enumerate(parts)]
    text = "; ".join(f"{r['id']} = {r['name']} (material {r['material']}, material_id {r['material_id']})" for r in rows)
    return "part ids: " + text.replace("--", "- -"), rows


def _with_header_note(path: Path, note: str) -> None:
    """Put ``note`` as an XML comment at the head of a VTU file meshio wrote."""
    data = path.read_bytes()
    at = data.index(b"<UnstructuredGrid")
    path.write_bytes(data[:at] + f"<!-- {note} -->\n".encode("utf-8") + data[at:])


def _plane_extent(model, sym: str, full: bool) -> tuple[float, float, float, float]:
    """(xmin, xmax, ymin, ymax) (m) a plane impactor's patch covers: the specimen's reference
    footprint (mirrored when ``full``) and 10 % of its size around it."""
    X = np.asarray(model.nodes, dtype=np.float64)
    lo, hi = X[:, :2].min(axis=0), X[:, :2].max(axis=0)
    if full:
        for axis, at in _mirror_planes(model, sym):
            lo[axis], hi[axis] = min(lo[axis], 2 * at - hi[axis]), max(hi[axis], 2 * at - lo[axis])
    pad = 0.1 * float(max(hi - lo))
    return (lo[0] - pad, hi[0] + pad, lo[1] - pad, hi[1] + pad)


def write_field_series(out_dir, model, result, keys, full: bool = False) -> list[str]:
    """Write the specimen and impactor series of a drop test's stored frames.

    Parameters
    ----------
    out_dir : str or path-like
        Existing output folder: a stage (:func:`cfm_core.post.staging.staged_folder`), published
        whole by the caller; the frame files are written uncompressed (binary, base64: zlib
        took most of the writing time) and not one by one atomically.
    model : Model
        The model that ran (reference nodes, hexes, parts and materials, impactor, symmetry in
        ``meta``).
    result : Result
        The run's result with ``frames`` and, when the backend stores them, ``frame_state``
        (velocity m/s, Prony state in a structure of :mod:`cfm_core.post.part_state`),
        ``impactor_z`` (m) and ``impactor_lateral`` (x, y in m) at the output times ``t`` (s).
    keys : sequence of str
        Field keys (:data:`cfm_core.post.fields.FIELDS`).
    full : bool
        Mirror a quarter or half model into the whole specimen (see the module docstring).

    Returns
    -------
    list of str
        The names written: ``specimen.pvd``, ``fields.json`` and the frame files as
        ``specimen_*.vtu (N frames)`` / ``impactor_*.vtu (N frames)``.

    Raises
    ------
    InputError
        ``full`` for a model without symmetry (already the whole specimen).
    NumericalError
        A non-finite frame time or displacement (nothing of the series is written).
    """
    import meshio

    out = Path(out_dir)
    sym = symmetry_of(model)
    if full and sym not in ("quarter", "half"):
        raise InputError(f"--full mirrors a quarter or half model; this run's symmetry is {sym!r}, already the "
                         f"whole specimen.")
    frames = list(result.frames)
    states = list(getattr(result, "frame_state", None) or [None] * len(frames))
    for k, (t, u) in enumerate(frames):
        if not (math.isfinite(float(t)) and np.isfinite(u).all()):
            raise NumericalError(f"frame {k} (t = {float(t):g} s) has a non-finite time or displacement; "
                                 f"nothing was written.", quantity="displacement")
    B = mean_gradients(model.nodes, model.hexes)
    width = max(4, len(str(len(frames) - 1)))
    sph = model.sphere
    note, part_rows = parts_note(model)
    multi = len(part_rows) > 1
    if sph is not None:
        side = 1 if float(np.max(model.nodes[:, 1])) >= -float(np.min(model.nodes[:, 1])) else -1
        sector = None if full or sym == "none" else sym
        surf_points, surf_tris = impactor_surface(sph, sector, side, _plane_extent(model, sym, full)
                                                  if sph.shape == "plane" else None)
        positions = impactor_positions(model, result, [float(t) for t, _ in frames])

    def write_frame(k):
        (t, u), state = frames[k], states[k]
        x, point, cell, exact = _frame_fields(model, B, np.asarray(u, dtype=np.float64), state, keys)
        hexes = np.asarray(model.hexes, dtype=np.int64)
        if full:
            for axis, at in _mirror_planes(model, sym):
                x, hexes, point, cell = mirror(x, hexes, point, cell, axis=axis, at=at)
        names = {**_array_names(point, True), **_array_names(cell, exact)}
        mesh = meshio.Mesh(x, [("hexahedron", hexes)], point_data={names[k_]: a for k_, a in point.items()},
                           cell_data={names[k_]: [a] for k_, a in cell.items()})
        name = f"specimen_{k:0{width}d}.vtu"
        meshio.write(out / name, mesh, file_format="vtu", compression=None)  # a stage: published whole
        if multi:
            _with_header_note(out / name, note)
        entries = [f'    <DataSet timestep="{float(t)!r}" group="" part="0" file="{name}"/>']
        if sph is not None:
            # a plane's patch is placed in x, y once (it covers the specimen); only its height moves
            shift = positions[k] if sph.shape != "plane" else np.array([0.0, 0.0, positions[k][2]])
            iname = f"impactor_{k:0{width}d}.vtu"
            meshio.write(out / iname, meshio.Mesh(surf_points + shift, [("triangle", surf_tris)]),
                         file_format="vtu", compression=None)
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
             "symmetry": f"full (mirrored {sym})" if full else sym,
             "stress": ("the solver's stress (elastic material or Prony state stored by the backend)" if exact
                        else "instantaneous (elastic) response: the backend stored no Prony state, so the "
                             "viscous part is missing; arrays carry the suffix _instantaneous"),
             "velocity": ("not written: this backend stores no velocities at frames" if velocity_left else
                          "nodal velocity (explicit backends: half-step v^(n+1/2))"),
             "arrays": {names[k_]: {"field": k_, "where": FIELDS[k_].where, "unit": FIELDS[k_].unit,
                                    "components": FIELDS[k_].components, "description": FIELDS[k_].description}
                        for k_ in names},
             "parts": part_rows,
             "impactor_shape": sph.shape if sph is not None else None,
             "impactor": (f"impactor_*.vtu: surface of the rigid {sph.shape} impactor (m) at its position, part 1 "
                          f"of specimen.pvd" + (" (a square patch of the plane over the specimen)"
                                                if sph.shape == "plane" else "")) if sph is not None else None}
    atomic_write(out / "fields.json", lambda tmp: Path(tmp).write_text(json.dumps(notes, indent=1) + "\n"))
    pvd = "\n".join(['<?xml version="1.0"?>',
                     "<!-- time in s; points in m, deformed; units of each array in its name and fields.json -->",
                     *([f"<!-- {note} -->"] if multi else []),
                     '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                     "  <Collection>", *entries, "  </Collection>", "</VTKFile>", ""])
    atomic_write(out / "specimen.pvd", lambda tmp: Path(tmp).write_text(pvd, encoding="utf-8"))
    written = ["specimen.pvd", "fields.json", f"specimen_*.vtu ({len(frames)} frames)"]
    if sph is not None:
        written.append(f"impactor_*.vtu ({len(frames)} frames)")
    return written
