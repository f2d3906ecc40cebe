"""Atomic writers for results: CSV, JSON, the drop-test output folder and VTU/PVD series.

Every file is written to a hidden temporary file in the target directory and then moved into
place with ``os.replace`` (atomic on POSIX and Windows), so no partial file ever carries the final
name. Data are checked first: non-finite values raise :class:`cfm_core.errors.NumericalError`
before anything is written. Units: SI (times in s, displacements in m, accelerations in m/s^2).
"""

from __future__ import annotations

import json
import math
import os
import secrets
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import InputError, NumericalError
from ..tables import unit_header
from .histories import _finite
from .staging import check_folder_target

#: Units of the acceleration.csv columns, merged into summary.json["units"]; the CSV header writes
#: them as ``name [unit]`` (:func:`cfm_core.tables.unit_header`), as sweep.csv does.
DROP_TEST_COLUMN_UNITS = {"t": "s", "a_raw": "m/s^2", "a_cfc600": "m/s^2"}
REACTION_COLUMN_UNITS = {"t": "s", "stretch": "-", "reaction_force": "N", "nominal_stress": "Pa"}


def atomic_write(path, write: Callable[[str], None]) -> Path:
    """Call ``write(tmp_path)`` on a temporary file next to ``path``, then rename it to ``path``.

    On any exception the temporary file is removed and ``path`` is left as it was. The file is
    fsynced before the rename (``os.replace``, atomic on POSIX and Windows).

    Parameters
    ----------
    path : str or path-like
        Final file name; its folder is created if missing.
    write : callable
        ``write(tmp_path: str) -> None`` writes the whole content to ``tmp_path``.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputError
        The folder of ``path`` cannot be created (a file of that name exists, no permission), or
        ``path`` cannot be replaced (another user's file, immutable, a read-only mount).
    """
    path = Path(path)
    try:  # --out dir/file.csv: the folder is made too
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the folder of {path}: {exc.strerror or exc}; choose another output path.") from None
    # Not mkstemp: its 0600 mode would survive the rename; a random name gives normal permissions.
    tmp = str(path.parent / f".{path.name}.{os.getpid()}.{secrets.token_hex(6)}.tmp")
    try:
        write(tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        try:
            os.replace(tmp, path)
        except OSError as exc:  # a file of another user in a shared folder, chattr +i, a read-only mount
            raise InputError(f"{path} cannot be replaced: {exc.strerror or exc}; it is left as it was. Choose "
                             f"another output path, or make that file writable.") from None
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    return path


def write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically (:func:`atomic_write`).

    Parameters
    ----------
    path : str or path-like
        The file; its folder is created if missing.
    text : str
        The whole content.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))


def output_folder(out, marker: str | None = None, create: bool = True, what: str = "--out") -> Path:
    """The output folder of a run or a study, checked, created, and without a stale completion file.

    Parameters
    ----------
    out : str or path-like
        The folder.
    marker : str, optional
        Name of the file whose presence means the output is complete (``summary.json``,
        ``fit.json``); removed first, so that an interrupted run leaves none behind.
    create : bool
        Create the folder (with its parents) if missing.
    what : str
        How the message names the folder: ``"--out"`` (the command line) or ``"output
        directory"`` (the Python API).

    Returns
    -------
    pathlib.Path
        ``out``.

    Raises
    ------
    InputError
        ``out`` exists and is not a directory, or cannot be written
        (:func:`cfm_core.post.staging.check_folder_target`).
    """
    out = check_folder_target(out, what)  # the one check of output folders (kinds, writability)
    if create:
        out.mkdir(parents=True, exist_ok=True)
    if marker is not None:
        (out / marker).unlink(missing_ok=True)
    return out


def _finite_array(name: str, a, ndim: int | None = None) -> np.ndarray:
    """``a`` as a float array, checked before anything is written (see :func:`.histories._finite`)."""
    return _finite(name, a, ndim, then="nothing was written")


def _check_line(kind: str, text: str) -> str:
    text = str(text)
    if "\n" in text or "\r" in text:
        raise InputError(f"{kind} {text!r} contains a line break; use one line per entry.")
    return text


def write_csv(path, header: list[str], columns: list, comments: list[str] = ()) -> Path:
    """Write equal-length 1-D ``columns`` as CSV under ``header`` (one name per column).

    The header is the first line unless ``comments`` are given, which then precede it as lines
    starting with ``"# "``. Values are written with Python's shortest round-trip repr (exact).
    Written atomically (:func:`atomic_write`).

    Parameters
    ----------
    path : str or path-like
        The CSV file.
    header : list of str
        Column names, without commas or line breaks (units belong in the name or the summary).
    columns : list of array_like, each shape (n,)
        The data, finite, in SI units.
    comments : list of str
        Lines written before the header, each prefixed with ``"# "``; no line breaks.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputError
        A name with a comma or line break, a comment with a line break, not one name per
        column, a column that is not 1-D, or columns of different lengths.
    NumericalError
        A non-finite value (names the column and the first index); nothing is written.
    """
    header = [_check_line("column name", h) for h in header]
    if any("," in h for h in header):
        raise InputError(f"column names must not contain commas; got {header}.")
    if len(header) != len(columns):
        raise InputError(f"{len(header)} column names for {len(columns)} columns; give one name per column.")
    cols = [_finite_array(f"column {h!r}", c, ndim=1) for h, c in zip(header, columns)]
    if len({c.size for c in cols}) > 1:
        raise InputError(f"columns have different lengths {[c.size for c in cols]}; they must be equal.")
    lines = [f"# {_check_line('comment', c)}" for c in comments]
    lines.append(",".join(header))
    rows = zip(*(c.tolist() for c in cols))
    lines.extend(",".join(repr(v) for v in row) for row in rows)
    text = "\n".join(lines) + "\n"

    def write(tmp):
        with open(tmp, "w", encoding="utf-8", newline="\n") as f:
            f.write(text)

    return atomic_write(path, write)


def _json_default(o):
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"object of type {type(o).__name__} is not JSON serialisable")


def write_json(path, data) -> Path:
    """Write ``data`` as indented JSON; NaN or inf anywhere raises NumericalError, nothing written.

    numpy scalars and arrays and paths are converted to plain JSON values. Written atomically.

    Parameters
    ----------
    path : str or path-like
        The JSON file.
    data : dict or list
        JSON-able content.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    NumericalError
        NaN or inf anywhere in ``data``.
    InputError
        An object that cannot be written as JSON.
    """
    try:
        text = json.dumps(data, indent=2, allow_nan=False, default=_json_default)
    except ValueError as exc:  # raised by allow_nan=False
        raise NumericalError(f"refusing to write {Path(path).name}: {exc} (NaN or inf in the data).") from None
    except TypeError as exc:
        raise InputError(f"cannot write {Path(path).name}: {exc}.") from None

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text + "\n")

    return atomic_write(path, write)


def write_history(out_dir, filename: str, column_units: dict, columns: list, summary: dict) -> Path:
    """Write ``filename`` (CSV, header ``name [unit]`` from column_units) then ``summary.json`` in out_dir.

    Both are checked before the disk is touched; a stale summary.json is removed first and the
    new one is written last, so its presence means the run's output is complete.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder (created).
    filename : str
        Name of the CSV file in ``out_dir``.
    column_units : dict of str to str
        Column name -> SI unit, in column order.
    columns : list of array_like, each shape (n,)
        The data, in the order of ``column_units``.
    summary : dict
        JSON-able summary; the column units are added under ``"units"`` (its own units win).

    Returns
    -------
    pathlib.Path
        ``out_dir``.

    Raises
    ------
    InputError
        A column that is not 1-D or columns of different lengths; ``out_dir`` exists and is not a
        directory.
    NumericalError
        A non-finite value in a column or in the summary; nothing is written.
    """
    out = Path(out_dir)
    arrays = [_finite_array(n, a, ndim=1) for n, a in zip(column_units, columns)]
    summary = dict(summary)
    summary["units"] = {**column_units, **dict(summary.get("units") or {})}
    try:  # check the summary before touching the disk
        json.dumps(summary, allow_nan=False, default=_json_default)
    except ValueError as exc:
        raise NumericalError(f"refusing to write summary.json: {exc} (NaN or inf in the summary).") from None
    output_folder(out, marker="summary.json", what="output directory")
    write_csv(out / filename, unit_header(column_units), arrays)
    write_json(out / "summary.json", summary)
    return out


def write_drop_test(out_dir, t, a_raw, a_cfc, summary: dict) -> Path:
    """``acceleration.csv`` (header ``t [s],a_raw [m/s^2],a_cfc600 [m/s^2]``) and summary.json; see
    :func:`write_history`.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder (created).
    t : array_like, shape (n,)
        Times (s).
    a_raw, a_cfc : array_like, shape (n,)
        Impactor acceleration (m/s^2), box-averaged and SAE J211/1 CFC 600 filtered.
    summary : dict
        JSON-able summary (see :func:`cfm_core.post.summarize`).

    Returns
    -------
    pathlib.Path
        ``out_dir``.

    Raises
    ------
    InputError
        A column that is not 1-D or columns of different lengths.
    NumericalError
        A non-finite value in a column or in the summary; nothing is written.
    """
    return write_history(out_dir, "acceleration.csv", DROP_TEST_COLUMN_UNITS, [t, a_raw, a_cfc], summary)


def write_reaction(out_dir, t, stretch, force, nominal, summary: dict) -> Path:
    """``reaction.csv`` (header ``t [s],stretch [-],reaction_force [N],nominal_stress [Pa]``) of a
    prescribed-motion scene and summary.json; see :func:`write_history`.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder (created).
    t : array_like, shape (n,)
        Times (s).
    stretch : array_like, shape (n,)
        Stretch of the loaded face (-).
    force : array_like, shape (n,)
        Reaction force (N).
    nominal : array_like, shape (n,)
        Nominal stress (Pa).
    summary : dict
        JSON-able summary (see :func:`cfm_core.post.summarize_reaction`).

    Returns
    -------
    pathlib.Path
        ``out_dir``.

    Raises
    ------
    InputError
        A column that is not 1-D or columns of different lengths.
    NumericalError
        A non-finite value in a column or in the summary; nothing is written.
    """
    return write_history(out_dir, "reaction.csv", REACTION_COLUMN_UNITS, [t, stretch, force, nominal], summary)


def write_vtu_series(out_dir, nodes, hexes, frames) -> Path:
    """Write ``specimen_XXXX.vtu`` per frame and the ParaView collection ``specimen.pvd``.

    Displacements are stored as point data "displacement" on the reference mesh (use ParaView's
    "Warp By Vector"). Every frame is checked before anything is written; each file is written
    atomically and the .pvd last.

    Parameters
    ----------
    out_dir : str or path-like
        Output folder (created).
    nodes : array_like, shape (n, 3)
        Reference coordinates (m).
    hexes : array_like, shape (m, 8)
        Integer node indices (VTK hexahedron order).
    frames : list of (float, array_like)
        ``(t (s), displacement (n, 3) in m)`` per frame.

    Returns
    -------
    pathlib.Path
        The path of ``specimen.pvd``.

    Raises
    ------
    InputError
        ``nodes`` not (n, 3), ``hexes`` not an integer (m, 8) array or referring to missing
        nodes, or a displacement whose shape differs from ``nodes``.
    NumericalError
        A non-finite coordinate, frame time or displacement (names the frame); nothing is
        written.
    """
    import meshio

    out = Path(out_dir)
    nodes = _finite_array("nodes", nodes, ndim=2)
    hexes = np.asarray(hexes)
    if nodes.shape[1] != 3:
        raise InputError(f"nodes must have shape (n, 3) in m; got {nodes.shape}.")
    if hexes.ndim != 2 or hexes.shape[1] != 8 or not np.issubdtype(hexes.dtype, np.integer):
        raise InputError(f"hexes must be an integer array of shape (m, 8); got {hexes.dtype} {hexes.shape}.")
    if hexes.size and (hexes.min() < 0 or hexes.max() >= len(nodes)):
        raise InputError(f"hexes refer to nodes outside 0..{len(nodes) - 1}.")
    checked = []
    for k, (t, u) in enumerate(frames):
        t = float(t)
        if not math.isfinite(t):
            raise NumericalError(f"frame {k} has time {t!r} s; nothing was written.", quantity="time")
        u = _finite_array(f"frame {k} displacement", u, ndim=2)
        if u.shape != nodes.shape:
            raise InputError(f"frame {k} displacement has shape {u.shape}; expected {nodes.shape} (m).")
        checked.append((t, u))
    out.mkdir(parents=True, exist_ok=True)
    width = max(4, len(str(len(checked) - 1)))
    entries = []
    for k, (t, u) in enumerate(checked):
        name = f"specimen_{k:0{width}d}.vtu"
        mesh = meshio.Mesh(nodes, [("hexahedron", hexes.astype(np.int64))], point_data={"displacement": u})
        atomic_write(out / name, lambda tmp, m=mesh: meshio.write(tmp, m, file_format="vtu"))
        entries.append(f'    <DataSet timestep="{t!r}" group="" part="0" file="{name}"/>')
    pvd = "\n".join(['<?xml version="1.0"?>',
                     '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
                     "  <Collection>", *entries, "  </Collection>", "</VTKFile>", ""])

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(pvd)

    return atomic_write(out / "specimen.pvd", write)
