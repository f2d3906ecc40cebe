"""Cut view of a written field series: one field at one time on the plane y = 0 (matplotlib).

Reads ``specimen.pvd`` and the frame nearest the time asked for; the elements the plane y = y_cut
passes through are drawn as their faces nearest the plane (deformed coordinates, x-z plane), coloured
by the element value; a quarter model is shown mirrored about x = 0 (scalars are symmetric); the
impactor's section is drawn as its outline (every shape). Units: mm on the axes, the field's unit (kPa for stresses)
on the colour bar.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from ..errors import InputError
from .fields import FIELDS

_PVD = re.compile(r'<DataSet timestep="([^"]+)" group="[^"]*" part="(\d+)" file="([^"]+)"/>')
#: Scalar views of multi-component fields: name -> (field key, component or None for the value).
SCALARS = {"von_mises": ("von_mises", None), "pressure": ("pressure", None), "J": ("J", None),
           "max_shear_strain": ("max_shear_strain", None), "energy_density": ("energy_density", None),
           "material_id": ("material_id", None), "part": ("part", None),
           **{f"cauchy_stress_{c}": ("cauchy_stress", i) for i, c in enumerate(("11", "22", "33", "12", "23", "13"))},
           **{f"log_strain_{i + 1}": ("log_strain", i) for i in range(3)},
           **{f"fibre_switch_{p}": ("fibre_switch", i) for i, p in enumerate(("12", "23", "13"))},
           "fibres_active": ("fibre_switch", "sum")}


def read_series(run_dir) -> list[tuple[float, Path, Path | None]]:
    """The frames of a written series: (t (s), specimen file, impactor file or None), by time.

    Parameters
    ----------
    run_dir : str or path-like
        An output folder of ``cfm drop-test --vtu`` / ``cfm run --vtu``.

    Returns
    -------
    list of tuple
        Per frame: time (s), path of ``specimen_XXXX.vtu``, path of ``impactor_XXXX.vtu`` or None.

    Raises
    ------
    InputError
        The folder has no ``specimen.pvd`` (names the folder and says how to write one).
    """
    folder = Path(run_dir)
    pvd = folder / "specimen.pvd"
    if not pvd.is_file():
        raise InputError(f"RUN_DIR {run_dir}: no specimen.pvd; write one with 'cfm drop-test --vtu --out DIR' "
                         f"(or 'cfm run --scene ... --vtu').")
    frames: dict = {}
    for t, part, name in _PVD.findall(pvd.read_text(encoding="utf-8")):
        frames.setdefault(float(t), [None, None])[int(part) > 0] = folder / name
    return [(t, s, i) for t, (s, i) in sorted(frames.items()) if s is not None]


def _cell_value(mesh, field: str):
    key, comp = SCALARS[field]
    for name, blocks in mesh.cell_data.items():
        if name.split(" [")[0] in (key, key + "_instantaneous"):
            a = np.asarray(blocks[0], dtype=np.float64)
            v = a if comp is None else (a.sum(axis=1) if comp == "sum" else a[:, comp])
            return v, name
    raise InputError(f"--field {field}: the series has no array '{key}' (it has "
                     f"{', '.join(mesh.cell_data) or 'none'}); write it with --fields {key}.")


def render_cut(run_dir, at: float, field: str, png, y_cut: float = 0.0) -> dict:
    """Draw ``field`` at the frame nearest ``at`` on the cut plane y = y_cut into ``png``.

    Parameters
    ----------
    run_dir : str or path-like
        Folder with ``specimen.pvd`` (:func:`read_series`).
    at : float
        Time (s); the nearest stored frame is shown (its time is in the title).
    field : str
        A name of :data:`SCALARS` (e.g. ``von_mises``, ``cauchy_stress_33``, ``log_strain_3``).
    png : str or path-like
        Output image.
    y_cut : float
        Cut plane position (m); 0 is the symmetry plane through the impact point.

    Returns
    -------
    dict
        ``t`` (s, the frame shown), ``file`` (its VTU), ``min``, ``max`` (in the field's unit) and
        ``unit`` (of the colour bar).

    Raises
    ------
    InputError
        Unknown field, a time outside the stored frames (by more than one frame interval), or no
        element crossed by the plane.
    """
    import meshio
    from matplotlib.collections import LineCollection, PolyCollection

    from .plots import _figure, _save

    if field not in SCALARS:
        raise InputError(f"--field {field!r} is not known; allowed: {', '.join(SCALARS)}.")
    frames = read_series(run_dir)
    times = np.array([f[0] for f in frames])
    k = int(np.argmin(np.abs(times - at)))
    gap = float(np.max(np.diff(times))) if len(times) > 1 else 0.0
    if not frames or abs(times[k] - at) > max(gap, 1e-12):
        raise InputError(f"--at {at:g} s is outside the stored frames ({times[0]:g} .. {times[-1]:g} s).")
    t, spec_file, imp_file = frames[k]
    mesh = meshio.read(spec_file)
    value, name = _cell_value(mesh, field)
    hexes = mesh.cells_dict["hexahedron"]
    x = mesh.points
    # the material section: the elements the plane crossed in the reference configuration (X = x - u),
    # drawn deformed; a section taken on the deformed y would lose elements that moved across it
    disp = next((a for k_, a in mesh.point_data.items() if k_.startswith("displacement")), None)
    ref = x - disp if disp is not None else x
    y = ref[hexes][:, :, 1]
    cut = (y.min(axis=1) <= y_cut + 1e-12) & (y.max(axis=1) >= y_cut - 1e-12)
    if (cut & (y.mean(axis=1) >= y_cut)).any():  # a plane on element faces: the layer on its +y side
        cut &= y.mean(axis=1) >= y_cut
    if not cut.any():
        raise InputError(f"the plane y = {y_cut:g} m crosses no element of {spec_file.name}.")
    faces = []
    for e in np.flatnonzero(cut):
        corners = x[hexes[e]]
        near = np.argsort(np.abs(ref[hexes[e]][:, 1] - y_cut))[:4]
        quad = corners[near][:, [0, 2]]
        c = quad.mean(axis=0)
        quad = quad[np.argsort(np.arctan2(quad[:, 1] - c[1], quad[:, 0] - c[0]))]
        faces.append(quad * 1e3)
    v = value[cut]
    unit = FIELDS[SCALARS[field][0]].unit
    scale, shown = (1e-3, "kPa") if unit == "Pa" else (1.0, unit)
    notes = json.loads((Path(run_dir) / "fields.json").read_text()) if (Path(run_dir) / "fields.json").is_file() else {}
    quarter = notes.get("symmetry") == "quarter"
    if quarter:  # scalars are symmetric about x = 0; a shear component 12 or 13 changes sign there
        sign = -1.0 if field in ("cauchy_stress_12", "cauchy_stress_13") else 1.0
        faces += [f * np.array([-1.0, 1.0]) for f in faces]
        v = np.concatenate([v, sign * v])
    fig, ax = _figure("")
    pc = PolyCollection(faces, array=v * scale, cmap="viridis", edgecolors="face", linewidths=0.2)
    ax.add_collection(pc)
    if imp_file is not None:
        imp = meshio.read(imp_file)
        tri = imp.cells_dict.get("triangle", np.zeros((0, 3), dtype=np.int64))
        seg = section(imp.points, tri, y_cut)
        if quarter and len(seg):                 # the clipped quarter surface, mirrored about x = 0
            seg = np.concatenate([seg, seg * np.array([-1.0, 1.0])])
        if len(seg):
            ax.add_collection(LineCollection(seg * 1e3, colors="0.3", linewidths=1.0, label="impactor"))
    pts = np.concatenate(faces)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.05 * (hi[0] - lo[0])
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + max(pad, 0.5 * (hi[1] - lo[1])))
    ax.set_aspect("equal")
    ax.grid(False)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("z (mm)")
    label = name.split(" [")[0].replace("_instantaneous", " (instantaneous)")
    ax.set_title(f"{label}, cut y = {1e3 * y_cut:g} mm, t = {1e3 * t:.3f} ms", fontsize=9)
    fig.colorbar(pc, ax=ax, label=f"{field} ({shown})", shrink=0.8)
    _save(fig, png)
    return {"t": t, "file": spec_file.name, "min": float(np.nanmin(v)), "max": float(np.nanmax(v)), "unit": unit}


def section(points, triangles, y_cut: float) -> np.ndarray:
    """The section of a triangulated surface with the plane y = y_cut, as line segments.

    Every triangle with vertices on both sides of the plane gives the segment between the two
    points where its edges cross it (linear interpolation along the edge); this draws the exact
    section of the triangulation for any impactor shape, position and cut. The plane is moved by
    a round-off margin into +y, so that a surface clipped at the plane (a quarter model's) is cut
    just inside its edge.

    Parameters
    ----------
    points : ndarray, shape (p, 3)
        Surface vertices (m).
    triangles : ndarray, shape (t, 3)
        Vertex indices of each triangle.
    y_cut : float
        The plane (m).

    Returns
    -------
    ndarray, shape (s, 2, 2)
        Segments, each two (x, z) points (m); empty when the plane misses the surface.
    """
    points = np.asarray(points, dtype=np.float64)
    tri = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    if not len(tri):
        return np.zeros((0, 2, 2))
    eps = 1e-9 * (1.0 + float(np.ptp(points))) if len(points) else 0.0
    d = points[:, 1] - (y_cut + eps)
    out = []
    for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):   # the vertex alone on its side, the other two
        i, j, k = tri[:, a], tri[:, b], tri[:, c]
        lone = (np.sign(d[i]) != np.sign(d[j])) & (np.sign(d[j]) == np.sign(d[k])) & (d[j] != 0.0)
        if not lone.any():
            continue
        i, j, k = i[lone], j[lone], k[lone]
        p1 = points[i] + (d[i] / (d[i] - d[j]))[:, None] * (points[j] - points[i])
        p2 = points[i] + (d[i] / (d[i] - d[k]))[:, None] * (points[k] - points[i])
        out.append(np.stack([p1[:, [0, 2]], p2[:, [0, 2]]], axis=1))
    return np.concatenate(out) if out else np.zeros((0, 2, 2))
