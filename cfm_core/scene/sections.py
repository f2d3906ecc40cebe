"""Sections of a scene file as frozen dataclasses, each validated at construction (SI units).

Every bad value, wrong type or out-of-range number raises :class:`cfm_core.errors.InputError`
naming the section, the key, the value, the unit and the allowed range. :mod:`cfm_core.scene`
assembles the sections into a :class:`~cfm_core.scene.Scene` and reads and writes TOML.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import InputError
from .mesh import mean_edge_length, read_cell_sets, read_hex_mesh
from .layers import layer_cells, make_layers

SCENE_TYPES = ("drop-test", "single-element", "relaxation")
#: [scene] output_rate (Hz) when a scene gives none: the paper's 50 kHz, 100 Hz for the long
#: quasi-static relaxation hold (the built-in scene files document the same values).
DEFAULT_OUTPUT_RATE = {"drop-test": 50_000.0, "single-element": 50_000.0, "relaxation": 100.0}
MAX_ELEMENTS = 10_000_000  # a larger modelled mesh is almost surely a unit mistake


from .values import _choice, _num, _set, _text, parameter_value  # noqa: F401 (re-exported)
from .impactor_section import SYMMETRIES


# ----------------------------------------------------------------------------- sections
@dataclass(frozen=True)
class SceneSettings:
    """[scene]: type ("drop-test" | "single-element" | "relaxation"); name (text, default: the type);
    end_time (s, upper bound; None: automatic, see :attr:`Scene.end_time`);
    output_rate (Hz, histories are recorded at least this often; default by type,
    :data:`DEFAULT_OUTPUT_RATE`: 50 kHz as the paper, 100 Hz for relaxation; a history of more
    than :data:`cfm_core.scene.builder.MAX_HISTORY_ROWS` rows is refused when the model is built).

    Run checks (:mod:`cfm_core.simulation.checks`): penetration_tolerance (m, allowed penetration
    behind a rigid surface or across a symmetry plane; None: 5 % of the smallest element edge);
    hourglass_limit (-, hourglass / internal energy above which the run stops; None: only a
    warning above 0.10); energy_limit (-, energy-balance error above which the run stops; None:
    only a warning above 0.01)."""

    type: str
    name: str | None = None
    end_time: float | None = None
    output_rate: float | None = None
    penetration_tolerance: float | None = None
    hourglass_limit: float | None = None
    energy_limit: float | None = None

    def __post_init__(self):
        _choice("scene", "type", self.type, SCENE_TYPES)
        _set(self, name=self.type if self.name is None else _text("scene", "name", self.name))
        if self.end_time is not None:
            _set(self, end_time=_num("scene", "end_time", self.end_time, "s", 0, 1e4, lo_open=True))
        rate = DEFAULT_OUTPUT_RATE[self.type] if self.output_rate is None else self.output_rate
        _set(self, output_rate=_num("scene", "output_rate", rate, "Hz", 0, 1e9, lo_open=True))
        if self.penetration_tolerance is not None:
            _set(self, penetration_tolerance=_num("scene", "penetration_tolerance", self.penetration_tolerance,
                                                  "m", 0, 0.1, lo_open=True,
                                                  note="0 would stop every run on round-off (7e-18 m)"))
        for key in ("hourglass_limit", "energy_limit"):
            if getattr(self, key) is not None:
                _set(self, **{key: _num("scene", key, getattr(self, key), "-", 0, 1e6, lo_open=True)})

    def checks(self) -> dict:
        """The run-check limits as a dict (model.meta["checks"]); None values mean the defaults."""
        return {"penetration_tolerance": self.penetration_tolerance, "hourglass_limit": self.hourglass_limit,
                "energy_limit": self.energy_limit}


@functools.lru_cache(maxsize=16)
def _read_mesh_cached(path: str, mtime_ns: int, size: int, merge: bool = False):

    nodes, hexes = read_hex_mesh(path, merge=merge)
    nodes.setflags(write=False)
    hexes.setflags(write=False)
    return nodes, hexes, mean_edge_length(nodes, hexes)


def read_specimen_mesh(path, merge: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
    """(nodes (m), hexes, mean edge length (m)) of a user mesh, read once per file version.

    merge: merge coincident nodes (else a mesh that is not one body is refused, see
    :func:`cfm_core.scene.mesh.check_one_body`). The arrays are read-only and shared; copy them
    before changing them.
    """
    p = Path(path)
    st = p.stat() if p.is_file() else None
    if st is None:
        raise InputError(f"[specimen] mesh = '{path}': the file does not exist. Give the path of a "
                         f"hexahedral mesh file (Abaqus .inp, or a format meshio reads: .vtu, .msh, ...; relative "
                         f"paths are taken from the scene file's folder).")
    return _read_mesh_cached(str(p), st.st_mtime_ns, st.st_size, bool(merge))


@functools.lru_cache(maxsize=16)
def _read_sets_cached(path: str, mtime_ns: int, size: int) -> dict:
    sets = read_cell_sets(path)
    for a in sets.values():
        a.setflags(write=False)
    return sets


def read_specimen_cell_sets(path) -> dict:
    """Named hexahedron sets of a user mesh ({name: indices}), read once per file version
    (:func:`cfm_core.scene.mesh.read_cell_sets`; read-only arrays)."""
    st = Path(path).stat()
    return _read_sets_cached(str(path), st.st_mtime_ns, st.st_size)


@dataclass(frozen=True)
class Specimen:
    """[specimen] of a drop test: a square block on the plate, bottom at z = 0, centred at x=y=0.

    width (m, full in-plane size, default 0.05, at most 1); thickness (m, default 0.008, allowed
    1e-4..0.1; with layers their sum); element_size (m, default 0.001, at most the thickness; the
    in-plane size, and the size through the thickness of layers that give none); density
    (kg/m^3, default 950, an assumption: not in the paper); symmetry ("auto": the most reduced
    model the impact allows | "quarter": only x, y >= 0 is modelled | "half": only y >= 0 |
    "none"; resolved by :func:`cfm_core.scene.impactor_section.resolve_symmetry` when the
    scene is built, and :attr:`requested_symmetry` keeps what was asked). layers: optional
    ``[[specimen.layers]]`` from the plate upwards (:class:`cfm_core.scene.layers.Layer`), a
    conforming layered block. mesh: optional path of a user hexahedral mesh (coordinates in m);
    then width (x extent of the full specimen), thickness (max z) and element_size (mean edge
    length) are taken from the mesh, and values given for them must agree with it. The mesh's
    bottom must be at z = 0; its shape sets the symmetry (:attr:`mesh_symmetry`): the x, y >= 0
    quarter (min x = min y = 0) is "quarter", y >= 0 centred in x is "half", a mesh centred at
    x = y = 0 is "none". merge_nodes: merge coincident nodes of the mesh that its elements do
    not share (default None = false: such a mesh, which is not one body, is refused with a count).
    """

    width: float | None = None
    thickness: float | None = None
    element_size: float | None = None
    density: float = 950.0
    symmetry: str = "auto"
    mesh: str | None = None
    merge_nodes: bool | None = None
    layers: tuple = ()

    def __post_init__(self):
        s = "specimen"
        _choice(s, "symmetry", self.symmetry, SYMMETRIES)
        object.__setattr__(self, "requested_symmetry", self.symmetry)
        object.__setattr__(self, "mesh_symmetry", None)
        if self.merge_nodes is not None and not isinstance(self.merge_nodes, bool):
            raise InputError(f"[specimen] merge_nodes = {self.merge_nodes!r} must be true or false.")
        _set(self, density=_num(s, "density", self.density, "kg/m^3", 1, 1e5,
                                note="The default 950 kg/m^3 is an assumption (not in the paper)."))
        _set(self, layers=make_layers(self.layers) if self.layers else ())
        if self.mesh is not None:
            if self.layers:
                raise InputError(f"[specimen] mesh = {self.mesh!r} and [[specimen.layers]] cannot be used together: "
                                 f"layers cut the built-in block; give the regions of a mesh as cell sets with "
                                 f"[parts.NAME] material = ... instead.")
            self._geometry_from_mesh()
        else:
            self._layered_thickness()
            for key, default in (("width", 0.05), ("thickness", 0.008), ("element_size", 0.001)):
                if getattr(self, key) is None:
                    _set(self, **{key: default})
        src = f" (Taken from the mesh '{self.mesh}'.)" if self.mesh is not None else ""
        fix = "Scale the mesh's coordinates to m" if self.mesh is not None else None
        _set(self, width=_num(s, "width", self.width, "m", 1e-4, 1.0, note=src.strip(), fix=fix))  # wider: mm as m
        _set(self, thickness=_num(s, "thickness", self.thickness, "m", 1e-4, 0.1, fix=fix,
                                  note="The paper's specimens are 4.8e-3 to 8.3e-3 m thick." + src))
        if self.mesh is None:
            _set(self, element_size=_num(s, "element_size", self.element_size, "m", 0,
                                         self.thickness, lo_open=True, note="The upper bound is the "
                                         "thickness, so that there is at least one layer of "
                                         "elements; use a smaller element_size."))
            n = self.n_elements
            if n > MAX_ELEMENTS:
                raise InputError(f"[specimen] element_size = {self.element_size!r} m gives {n} "
                                 f"elements for the modelled part (at most {MAX_ELEMENTS} allowed); "
                                 f"use a larger element_size (m).")

    def _layered_thickness(self):
        """thickness = the sum of the layers' (a given thickness must agree)."""
        if not self.layers:
            return
        total = 0.0
        for lay in self.layers:
            total = total + lay.thickness
        if self.thickness is not None:
            g = _num("specimen", "thickness", self.thickness, "m", 1e-4, 0.1)
            if not math.isclose(g, total, rel_tol=1e-9, abs_tol=0.0):
                raise InputError(f"[specimen] thickness = {self.thickness!r} m disagrees with the sum of the "
                                 f"[[specimen.layers]] thicknesses, {total!r} m; remove thickness (it is their "
                                 f"sum) or fix the layers.")
        _set(self, thickness=total)

    def _geometry_from_mesh(self):
        if not isinstance(self.mesh, (str, Path)) or not str(self.mesh).strip():
            raise InputError(f"[specimen] mesh = {self.mesh!r} must be a file path (string).")
        path = str(Path(self.mesh).expanduser().resolve())
        nodes, _, edge = read_specimen_mesh(path, bool(self.merge_nodes))
        lo, hi = nodes.min(axis=0), nodes.max(axis=0)
        tol = 1e-6 * float(np.max(hi - lo))
        if abs(lo[2]) > tol:
            raise InputError(f"[specimen] mesh '{path}': its bottom is at z = {lo[2]:g} m, but it "
                             f"must be at z = 0 (the plate). Translate the mesh.")
        kind = self.symmetry
        if kind == "auto":
            at0 = [abs(lo[k]) <= tol for k in (0, 1)]
            kind = "quarter" if all(at0) else "half" if at0[1] else "none"
        object.__setattr__(self, "mesh_symmetry", kind)
        if kind == "half":
            cx = 0.5 * (lo[0] + hi[0])
            if abs(lo[1]) > tol or abs(cx) > tol:
                raise InputError(f"[specimen] mesh '{path}' with symmetry = 'half' must be the y >= 0 half "
                                 f"(min y = 0 m) centred at x = 0, but min y = {lo[1]:g} m and its x centre is "
                                 f"{cx:g} m. Translate the mesh, or give a full mesh with symmetry = 'none'.")
            width = float(hi[0] - lo[0])
        elif kind == "quarter":
            if abs(lo[0]) > tol or abs(lo[1]) > tol:
                raise InputError(f"[specimen] mesh '{path}' with symmetry = 'quarter' must be the "
                                 f"x >= 0, y >= 0 quarter (min x = min y = 0 m), but min x = "
                                 f"{lo[0]:g} m, min y = {lo[1]:g} m. Give a quarter mesh or set "
                                 f"symmetry = 'none' for a full mesh centred at x = y = 0.")
            width = 2.0 * float(hi[0])
        else:
            cx, cy = 0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])
            if abs(cx) > tol or abs(cy) > tol:
                raise InputError(f"[specimen] mesh '{path}' with symmetry = 'none' must be centred "
                                 f"at x = y = 0, but its centre is at x = {cx:g} m, y = {cy:g} m. "
                                 f"Translate the mesh.")
            width = float(hi[0] - lo[0])
        derived = {"width": width, "thickness": float(hi[2]), "element_size": edge}
        for key, val in derived.items():
            given = getattr(self, key)
            if given is not None:
                g = _num("specimen", key, given, "m", 0, math.inf, lo_open=True)
                if not math.isclose(g, val, rel_tol=1e-9, abs_tol=0.0):
                    raise InputError(f"[specimen] {key} = {given!r} m disagrees with the mesh "
                                     f"'{path}', which gives {val!r} m; remove {key} (it is taken "
                                     f"from the mesh) or fix the mesh.")
        _set(self, mesh=path, **derived)

    @property
    def grid(self) -> tuple[int, int, int]:
        """(nx, ny, nz) of the structured mesh of the modelled part (quarter or full).

        Quarter (and "auto" before it is resolved): nx = ny = nq = round(width / 2 /
        element_size); half: nx = 2 nq, ny = nq; full: 2 nq each (the mirrored quarter, so the
        models have exactly the same elements); nz = round(thickness / element_size), or with
        layers the sum of :func:`cfm_core.scene.layers.layer_cells`; each at least 1, halves
        rounded up.
        """
        nq = max(1, math.floor(self.width / 2.0 / self.element_size + 0.5))
        if self.layers:
            nz = sum(layer_cells(self.layers, self.element_size))
        else:
            nz = max(1, math.floor(self.thickness / self.element_size + 0.5))
        nx = nq if self.symmetry in ("quarter", "auto") else 2 * nq
        ny = 2 * nq if self.symmetry == "none" else nq
        return nx, ny, nz

    @property
    def n_elements(self) -> int:
        """Number of elements of the modelled part (structured mesh or user mesh)."""
        if self.mesh is not None:
            return int(read_specimen_mesh(self.mesh, bool(self.merge_nodes))[1].shape[0])
        nx, ny, nz = self.grid
        return nx * ny * nz


from .impactor_section import Impactor  # noqa: E402,F401 (the [impactor] section lives there)


@dataclass(frozen=True)
class Contact:
    """[contact]: friction (-, Coulomb coefficient on both sphere and plate, default 0, 0..1)."""

    friction: float = 0.0

    def __post_init__(self):
        _set(self, friction=_num("contact", "friction", self.friction, "-", 0.0, 1.0))


@dataclass(frozen=True)
class MaterialSettings:
    """[material]: name (registered material, default "cfm"); moduli ("instantaneous" |
    "long-term", default "long-term", docs/conventions.md section 2); elastic (bool: drop the Prony series);
    parameters: overrides by name in SI units (stored as sorted (name, value) pairs; values are
    range-checked later by the material itself)."""

    name: str = "cfm"
    moduli: str = "long-term"
    elastic: bool = False
    parameters: tuple = ()

    def __post_init__(self):
        _text("material", "name", self.name)
        _choice("material", "moduli", self.moduli, ("instantaneous", "long-term"))
        if not isinstance(self.elastic, (bool, np.bool_)):
            raise InputError(f"[material] elastic = {self.elastic!r} must be true or false.")
        _set(self, elastic=bool(self.elastic))
        p = self.parameters
        items = p.items() if isinstance(p, Mapping) else p
        try:
            items = [(k, v) for k, v in items]
        except (TypeError, ValueError):
            raise InputError(f"[material.parameters] = {p!r} must be a table of name = number "
                             f"(SI units).") from None
        out = {}
        for k, v in items:
            _text("material.parameters", "name", k)
            out[k] = parameter_value("material.parameters", k, v)
        _set(self, parameters=tuple(sorted(out.items())))

    @property
    def parameter_dict(self) -> dict[str, float]:
        """The parameter overrides as a new dict {name: value (SI)}."""
        return dict(self.parameters)


@dataclass(frozen=True)
class ElementTest:
    """[element] of a single-element scene: one cube, top face moved along z.

    size (m, edge, default 0.001); stretch (-, final stretch of the top face, 0.05..3, != 1,
    default 0.5 = 50 % compression); rate (1/s, engineering strain rate, default 100, about the
    drop-test rate); hold (s, hold after reaching the stretch, default 0); density (kg/m^3, 950,
    assumed). Load time t_load = |stretch - 1| / rate (s).
    """

    size: float = 0.001
    stretch: float = 0.5
    rate: float = 100.0
    hold: float = 0.0
    density: float = 950.0

    def __post_init__(self):
        e = "element"
        _set(self, size=_num(e, "size", self.size, "m", 1e-5, 1.0))
        _set(self, stretch=_num(e, "stretch", self.stretch, "-", 0.05, 3.0))
        if self.stretch == 1.0:
            raise InputError("[element] stretch = 1.0 (-) means no deformation; give a stretch != 1 "
                             "in 0.05 <= stretch <= 3 (e.g. 0.5 for 50 % compression).")
        _set(self, rate=_num(e, "rate", self.rate, "1/s", 0, 1e6, lo_open=True))
        _set(self, hold=_num(e, "hold", self.hold, "s", 0, 1e4))
        _set(self, density=_num(e, "density", self.density, "kg/m^3", 1, 1e5))

    @property
    def load_time(self) -> float:
        """Time (s) to reach the stretch: |stretch - 1| / rate."""
        return abs(self.stretch - 1.0) / self.rate


@dataclass(frozen=True)
class RelaxationTest:
    """[relaxation] of a quasi-static relaxation scene: one cube compressed, then held.

    size (m, edge, default 0.001); stretch (-, held stretch of the top face, 0.05..3, != 1,
    default 0.7 = 30 % compression); load_time (s, ramp time to the stretch, default 1e-3);
    hold (s, hold time, default 30: three times the longest Prony time of the paper, 10 s);
    lateral ("free": lateral faces traction free, uniaxial stress | "confined": lateral faces
    held in their planes, uniaxial strain). No inertia: the scene is quasi-static (there is no
    density); an explicit solver would need millions of steps for the hold.
    """

    size: float = 0.001
    stretch: float = 0.7
    load_time: float = 1e-3
    hold: float = 30.0
    lateral: str = "free"

    def __post_init__(self):
        r = "relaxation"
        _set(self, size=_num(r, "size", self.size, "m", 1e-5, 1.0))
        _set(self, stretch=_num(r, "stretch", self.stretch, "-", 0.05, 3.0))
        if self.stretch == 1.0:
            raise InputError("[relaxation] stretch = 1.0 (-) means no deformation; give a stretch != 1 "
                             "in 0.05 <= stretch <= 3 (e.g. 0.7 for 30 % compression).")
        _set(self, load_time=_num(r, "load_time", self.load_time, "s", 0, 1e4, lo_open=True))
        _set(self, hold=_num(r, "hold", self.hold, "s", 0, 1e5, lo_open=True))
        _choice(r, "lateral", self.lateral, ("free", "confined"))
