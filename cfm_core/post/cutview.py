"""Cut view of a written field series: one field at one time on the plane y = 0 (matplotlib).

Reads ``specimen.pvd`` and the frame nearest the time asked for; the elements the plane y = y_cut
passes through are drawn as their faces nearest the plane (deformed coordinates, x-z plane), coloured
by the element value; a quarter model is shown mirrored about x = 0 (scalars are symmetric), and a
cut at negative y of a quarter or half model is drawn from its mirror image y -> -y; the
impactor's section is drawn as its outline (every shape). Units: mm on the axes, the field's unit (kPa for stresses)
on the colour bar.

Every file of the run folder (``fields.json``, ``specimen.pvd``, the ``specimen_XXXX.vtu`` and
``impactor_XXXX.vtu`` frames) is read through :func:`_read_run_file`: a missing, empty,
unreadable or inconsistent file is an :class:`~cfm_core.errors.InputError` naming the file, what is
wrong and how to write the folder again; meshio's own messages are kept off the terminal.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..tables import decode
from .fields import FIELDS

#: What to do about a damaged or incomplete run folder (ends every file message).
_REWRITE = "rerun the drop test with --vtu ('cfm drop-test --vtu --out DIR', or 'cfm run --scene ... --vtu')"
#: The counts in a VTU file's header (the first bytes are enough to find them).
_VTU_COUNTS = re.compile(rb'<Piece\s+NumberOfPoints="(\d+)"\s+NumberOfCells="(\d+)"')
_HEADER_BYTES = 65536
#: ``symmetry`` values of ``fields.json`` (:func:`cfm_core.post.vtu.write_field_series`).
_SYMMETRIES = ("quarter", "half", "none", "full (mirrored quarter)", "full (mirrored half)")
#: Scalar views of multi-component fields: name -> (field key, component or None for the value).
SCALARS = {"von_mises": ("von_mises", None), "pressure": ("pressure", None), "J": ("J", None),
           "max_shear_strain": ("max_shear_strain", None), "energy_density": ("energy_density", None),
           "material_id": ("material_id", None), "part": ("part", None),
           **{f"cauchy_stress_{c}": ("cauchy_stress", i) for i, c in enumerate(("11", "22", "33", "12", "23", "13"))},
           **{f"log_strain_{i + 1}": ("log_strain", i) for i in range(3)},
           **{f"fibre_switch_{p}": ("fibre_switch", i) for i, p in enumerate(("12", "23", "13"))},
           "fibres_active": ("fibre_switch", "sum")}
#: Views whose sign changes under a reflection of axis 0 (x) or 1 (y): the shear components.
_ODD = {0: ("cauchy_stress_12", "cauchy_stress_13"), 1: ("cauchy_stress_12", "cauchy_stress_23")}


def _damaged(run_dir, name: str, what: str) -> InputError:
    """The one-paragraph error for a file of the run folder: which file, what is wrong, what to do."""
    return InputError(f"RUN_DIR {run_dir}: {name} {what}; the run folder is damaged or incomplete: {_REWRITE}.")


def _read_run_file(run_dir, name: str, parse, head: int | None = None):
    """Read one file of a run folder through ``parse``; every failure is an :class:`InputError`.

    Parameters
    ----------
    run_dir : str or path-like
        The run folder (as the user named it).
    name : str
        File name inside it (as ``specimen.pvd`` lists it).
    parse : callable
        ``parse(path, data)`` with ``data`` the file's bytes (the first ``head`` bytes when given);
        returns the parsed content. Any exception it raises (or a ``SystemExit`` of a library) is
        turned into an :class:`InputError`; its printed output is discarded.
    head : int, optional
        Read only this many bytes (a header).

    Returns
    -------
    object
        What ``parse`` returned.

    Raises
    ------
    InputError
        The file is missing, not a file, empty, unreadable or ``parse`` failed; names the file and
        says how to write the folder again.
    """
    path = Path(run_dir) / name
    if not path.exists():
        raise _damaged(run_dir, name, "is missing" + (" (specimen.pvd lists it)" if name.endswith(".vtu") else ""))
    if not path.is_file():
        raise _damaged(run_dir, name, "is not a file")
    try:
        with path.open("rb") as f:
            data = f.read(head) if head is not None else f.read()
    except OSError as exc:
        raise _damaged(run_dir, name, f"cannot be read ({exc.strerror or exc})") from None
    if not data.strip():
        raise _damaged(run_dir, name, "is empty")
    noise = io.StringIO()
    try:
        with contextlib.redirect_stdout(noise), contextlib.redirect_stderr(noise), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return parse(path, data)
    except InputError:
        raise
    except (Exception, SystemExit) as exc:  # meshio prints and calls sys.exit(1) on some files
        said = noise.getvalue().strip().splitlines()
        detail = " ".join(str(exc).split()) or (said[-1].strip() if said else "") or "truncated or another format"
        kind = {".json": "JSON", ".pvd": "a ParaView collection (XML)", ".vtu": "a VTU mesh (XML)"}.get(path.suffix,
                                                                                                      "its format")
        raise _damaged(run_dir, name, f"cannot be read as {kind} ({detail[:200]})") from None


def _rel(run_dir, path: Path) -> str:
    """``path`` as named inside the run folder (as ``specimen.pvd`` lists it)."""
    try:
        return str(path.relative_to(Path(run_dir)))
    except ValueError:
        return str(path)


def _parse_json(path, data: bytes):
    return json.loads(decode(path, data, "JSON"))  # a UTF-8 byte-order mark skipped, as in CSV files


def _parse_xml(path, data: bytes):
    return ET.fromstring(data)


def _parse_vtu(path, data: bytes):
    import meshio.vtu

    return meshio.vtu.read(str(path))


def _parse_vtu_counts(path, data: bytes) -> tuple[int, int]:
    m = _VTU_COUNTS.search(data)
    if m is None:
        raise ValueError("no <Piece NumberOfPoints=... NumberOfCells=...> header")
    return int(m.group(1)), int(m.group(2))


def read_notes(run_dir) -> dict:
    """``fields.json`` of a run folder, checked: a JSON object whose ``symmetry`` is one the writer uses.

    Raises
    ------
    InputError
        Missing, empty or malformed ``fields.json``, or an unknown ``symmetry`` (names the file).
    """
    notes = _read_run_file(run_dir, "fields.json", _parse_json)
    if not isinstance(notes, dict):
        raise _damaged(run_dir, "fields.json", f"holds a JSON {type(notes).__name__}, not the object --vtu writes")
    sym = notes.get("symmetry")
    if sym not in _SYMMETRIES:
        raise _damaged(run_dir, "fields.json", f"has symmetry {sym!r}; allowed: {', '.join(map(repr, _SYMMETRIES))}")
    return notes


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
        The files are listed, not read (:func:`render_cut` reads the one it draws).

    Raises
    ------
    InputError
        The folder has no ``specimen.pvd`` (names the folder and says how to write one), or the
        file is empty, not XML, lists no specimen frame, or has a data set without a file or with
        a time that is not a finite number of seconds.
    """
    folder = Path(run_dir)
    if not folder.is_dir():
        raise InputError(f"RUN_DIR {run_dir}: {'no such folder' if not folder.exists() else 'not a folder'}; give "
                         f"the output folder of a run written with --vtu ('cfm drop-test --vtu --out DIR').")
    if not (folder / "specimen.pvd").exists():
        raise InputError(f"RUN_DIR {run_dir}: no specimen.pvd; write one with 'cfm drop-test --vtu --out DIR' "
                         f"(or 'cfm run --scene ... --vtu').")
    root = _read_run_file(run_dir, "specimen.pvd", _parse_xml)
    frames: dict = {}
    for ds in root.iter("DataSet"):
        t, part, name = ds.get("timestep"), ds.get("part", "0"), ds.get("file")
        try:
            time, part = float(t), int(part)
        except (TypeError, ValueError):
            time, part = math.nan, -1
        if not (math.isfinite(time) and part >= 0 and name):
            raise _damaged(run_dir, "specimen.pvd", f"has a data set with timestep {t!r}, part {ds.get('part')!r}, "
                                                    f"file {name!r}; each needs a finite time (s), a part 0 or 1 "
                                                    f"and a file")
        frames.setdefault(time, [None, None])[part > 0] = folder / name
    out = [(t, s, i) for t, (s, i) in sorted(frames.items()) if s is not None]
    if not out:
        raise _damaged(run_dir, "specimen.pvd", "lists no specimen frame (no <DataSet ... part=\"0\" file=...>)")
    return out


def _finite_option(option: str, value, unit: str, low: float | None = None) -> float:
    """``value`` as a float, refused (InputError naming ``option``) when not finite or below ``low``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not math.isfinite(v) or (low is not None and v < low):
        allowed = f"a finite number ({unit})" + (f", {low:g} or more" if low is not None else "")
        raise InputError(f"{option} {value!r} is not allowed; it must be {allowed}.")
    return v


def _read_frame(run_dir, spec_file: Path, first: Path):
    """The specimen frame ``spec_file``, checked against itself and the node and element counts of
    the series' first frame ``first``; returns the meshio mesh."""
    name = _rel(run_dir, spec_file)
    mesh = _read_run_file(run_dir, name, _parse_vtu)
    hexes = mesh.cells_dict.get("hexahedron")
    x = np.asarray(mesh.points, dtype=np.float64)
    if hexes is None or not len(hexes):
        raise _damaged(run_dir, name, "has no hexahedron elements")
    if x.ndim != 2 or x.shape[1] != 3 or not np.isfinite(x).all():
        raise _damaged(run_dir, name, "has points that are not finite (x, y, z) coordinates in m")
    if hexes.min() < 0 or hexes.max() >= len(x):
        raise _damaged(run_dir, name, f"has elements naming nodes outside its {len(x)} points")
    for key, a in mesh.point_data.items():
        if len(a) != len(x):
            raise _damaged(run_dir, name, f"has point array '{key}' with {len(a)} rows for {len(x)} points")
    for key, blocks in mesh.cell_data.items():
        if sum(len(b) for b in blocks) != len(hexes):
            raise _damaged(run_dir, name, f"has cell array '{key}' with {sum(len(b) for b in blocks)} rows for "
                                          f"{len(hexes)} elements")
    if first != spec_file:
        first_name = _rel(run_dir, first)
        n, e = _read_run_file(run_dir, first_name, _parse_vtu_counts, head=_HEADER_BYTES)
        if (n, e) != (len(x), len(hexes)):
            raise _damaged(run_dir, name, f"has {len(x)} nodes and {len(hexes)} elements but the first frame "
                                          f"{first_name} has {n} and {e}: the frames are not of one run")
    return mesh


def _cell_value(mesh, field: str, run_dir=".", file: str = "the frame"):
    key, comp = SCALARS[field]
    for name, blocks in mesh.cell_data.items():
        if name.split(" [")[0] in (key, key + "_instantaneous"):
            a = np.asarray(blocks[0], dtype=np.float64)
            width = FIELDS[key].components
            if (a.ndim, a.shape[1:]) != ((1, ()) if width == 1 else (2, (width,))):
                raise _damaged(run_dir, file, f"has array '{name}' of shape {a.shape}; {key} has {width} "
                                              f"component(s) per element")
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
        Unknown field; ``at`` not finite, negative or outside the stored frames (by more than one
        frame interval); ``y_cut`` not finite or outside the specimen (a quarter or half model
        counts mirrored about y = 0: a negative ``y_cut`` draws the mirror image, the shear
        components 12 and 23 with the opposite sign); or a file of the folder missing, empty,
        malformed or inconsistent (:func:`_read_run_file`).
    """
    from matplotlib.collections import LineCollection, PolyCollection

    from .plots import _figure, _save

    if field not in SCALARS:
        raise InputError(f"--field {field!r} is not known; allowed: {', '.join(SCALARS)}.")
    at = _finite_option("--at", at, "s", low=0.0)
    y_cut = _finite_option("--y", y_cut, "m")
    frames = read_series(run_dir)
    notes = read_notes(run_dir)
    times = np.array([f[0] for f in frames])
    k = int(np.argmin(np.abs(times - at)))
    gap = float(np.max(np.diff(times))) if len(times) > 1 else 0.0
    if abs(times[k] - at) > max(gap, 1e-12):
        ms = (f" Is it in ms? --at {at * 1e-3:g} is {at:g} ms." if times[0] - gap <= at * 1e-3 <= times[-1] + gap
              else "")
        raise InputError(f"--at {at:g} s is outside the stored frames ({times[0]:g} .. {times[-1]:g} s).{ms}")
    t, spec_file, imp_file = frames[k]
    mesh = _read_frame(run_dir, spec_file, frames[0][1])
    value, name = _cell_value(mesh, field, run_dir, _rel(run_dir, spec_file))
    hexes = mesh.cells_dict["hexahedron"]
    x = mesh.points
    # the material section: the elements the plane crossed in the reference configuration (X = x - u),
    # drawn deformed; a section taken on the deformed y would lose elements that moved across it
    disp = next((a for k_, a in mesh.point_data.items() if k_.startswith("displacement")), None)
    if disp is not None and np.shape(disp) != np.shape(x):
        raise _damaged(run_dir, _rel(run_dir, spec_file),
                       f"has a displacement array of shape {np.shape(disp)}, not {np.shape(x)}")
    ref = x - disp if disp is not None else x
    sym = notes["symmetry"]
    quarter = sym == "quarter"
    # a quarter or half model holds the side y >= 0 of the plane y = 0; y < 0 is its mirror image
    y_lo, y_hi = float(ref[:, 1].min()), float(ref[:, 1].max())
    tol = 1e-9 * max(float(np.ptp(ref)), 1e-300)
    y_eff, sign = y_cut, 1.0
    if sym in ("quarter", "half") and not (y_lo - tol <= y_cut <= y_hi + tol) and y_lo - tol <= -y_cut <= y_hi + tol:
        y_eff, sign = -y_cut, (-1.0 if field in _ODD[1] else 1.0)
    if not (y_lo - tol <= y_eff <= y_hi + tol):
        covered = (f"{min(y_lo, -y_hi):g} .. {max(y_hi, -y_lo):g} m (the {sym} model covers {y_lo:g} .. {y_hi:g} m "
                   f"and is mirrored about y = 0)" if sym in ("quarter", "half") else f"{y_lo:g} .. {y_hi:g} m")
        raise InputError(f"--y {y_cut:g} m is outside the specimen; the cut plane must lie within {covered}.")
    y = ref[hexes][:, :, 1]
    cut = (y.min(axis=1) <= y_eff + 1e-12) & (y.max(axis=1) >= y_eff - 1e-12)
    side = (y.mean(axis=1) - y_eff) * (1.0 if y_eff == y_cut else -1.0) >= 0.0
    if (cut & side).any():  # a plane on element faces: the layer on its +y side (in the mirror image too)
        cut &= side
    if not cut.any():
        raise InputError(f"--y {y_cut:g} m: the plane crosses no element of {spec_file.name}.")
    faces = []
    for e in np.flatnonzero(cut):
        corners = x[hexes[e]]
        near = np.argsort(np.abs(ref[hexes[e]][:, 1] - y_eff))[:4]
        quad = corners[near][:, [0, 2]]
        c = quad.mean(axis=0)
        quad = quad[np.argsort(np.arctan2(quad[:, 1] - c[1], quad[:, 0] - c[0]))]
        faces.append(quad * 1e3)
    v = sign * value[cut]
    unit = FIELDS[SCALARS[field][0]].unit
    scale, shown = (1e-3, "kPa") if unit == "Pa" else (1.0, unit)
    if quarter:  # scalars are symmetric about x = 0; a shear component 12 or 13 changes sign there
        faces += [f * np.array([-1.0, 1.0]) for f in faces]
        v = np.concatenate([v, (-1.0 if field in _ODD[0] else 1.0) * v])
    fig, ax = _figure("")
    pc = PolyCollection(faces, array=v * scale, cmap="viridis", edgecolors="face", linewidths=0.2)
    ax.add_collection(pc)
    if imp_file is not None:
        imp_name = _rel(run_dir, imp_file)
        imp = _read_run_file(run_dir, imp_name, _parse_vtu)
        tri = imp.cells_dict.get("triangle", np.zeros((0, 3), dtype=np.int64))
        pts = np.asarray(imp.points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3 or not np.isfinite(pts).all() or (
                len(tri) and (tri.min() < 0 or tri.max() >= len(pts))):
            raise _damaged(run_dir, imp_name, "has points that are not finite (x, y, z) in m or triangles naming "
                                              "points it does not have")
        seg = section(pts, tri, y_eff)   # the section at -y of a mirrored model is the one at y
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
