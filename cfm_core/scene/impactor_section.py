"""The [impactor] section of a drop test and the choice of symmetry (SI units, angles in degrees).

The impactor is rigid and translates without rotating (a guided drop-tower carriage). Its shape
is one of :data:`cfm_core.scene.model.IMPACTOR_SHAPES`; its velocity is a speed (m/s, moving
down) optionally tilted by ``angle`` and ``azimuth``, or a vector; ``offset`` moves the impact
point away from the specimen centre. :func:`resolve_symmetry` chooses the symmetry of the model
from the specimen and these values ([specimen] symmetry, docs/user/scenes.md).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..tables import as_float, shown
from .model import IMPACTOR_SHAPES
from .values import _choice, _num, _set

__all__ = ["Impactor", "SYMMETRIES", "resolve_symmetry"]

#: [specimen] symmetry values: "auto" chooses the most reduced model the scene allows.
SYMMETRIES = ("auto", "quarter", "half", "none")
#: Default rim radius of a "flat" impactor (m) when none is given (at most half its radius).
DEFAULT_EDGE_RADIUS = 1e-3
#: Velocity components below this fraction of the speed are set to 0: cos(90 deg) is 6e-17 in
#: floating point, which would otherwise break a symmetry the user asked for.
ZERO_COMPONENT = 1e-12


def _vector(section, key, value, n, unit):
    """``value`` as a tuple of ``n`` finite floats, else InputError."""
    ok = isinstance(value, (list, tuple)) and len(value) == n and all(
        isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(as_float(v)) for v in value)
    if not ok:
        shown_list = f"[{', '.join(map(shown, value))}]" if isinstance(value, (list, tuple)) else shown(value)
        raise InputError(f"[{section}] {key} = {shown_list} must be a list of {n} finite numbers ({unit}).")
    return tuple(float(v) for v in value)


@dataclass(frozen=True)
class Impactor:
    """[impactor]: rigid impactor translating without rotation (SI units, angles in degrees).

    radius (m, 0.055, 1e-4..1: sphere radius, or the cylinder radius of "flat"; "plane" has none,
    and another value with it is an InputError); mass (kg, 0.220, the full impactor); velocity (m/s: a speed, positive, moving down,
    default 1.0; or a vector [vx, vy, vz] with vz < 0, speed at most 1e3); shape ("hemisphere":
    the paper's, only its lower half touches | "sphere" | "flat": a cylinder with axis z, its
    flat bottom face down, the rim rounded with edge_radius | "plane": an infinite rigid plane);
    edge_radius (m, "flat" only, 0 <= edge_radius < radius; default min(1e-3, radius / 2); 0 is
    a sharp rim whose stress is singular, which the explicit backends may refuse); angle (deg
    from the plate normal, 0..89, only with a speed); azimuth (deg in the plane from +x, -360..360,
    default 0, only with an angle); offset ([x, y] in m: the impact point relative to the
    specimen centre, default [0, 0]). Values that are surely a unit slip (mass above 100 kg, speed
    above 100 m/s) are refused before running by :func:`cfm_core.scene.plausible.check_plausible`.
    """

    radius: float = 0.055
    mass: float = 0.220
    velocity: float | tuple = 1.0
    shape: str = "hemisphere"
    edge_radius: float | None = None
    angle: float | None = None
    azimuth: float | None = None
    offset: tuple | None = None

    def __post_init__(self):
        s = "impactor"
        _choice(s, "shape", self.shape, IMPACTOR_SHAPES)
        _set(self, radius=_num(s, "radius", self.radius, "m", 1e-4, 1.0))  # larger: mm typed as m
        if self.shape == "plane" and self.radius != Impactor.radius:
            raise InputError(f"[impactor] radius = {self.radius!r} m has no effect for shape = 'plane' (an infinite "
                             f"rigid plane: no radius); remove it, or give shape = 'hemisphere', 'sphere' or 'flat' "
                             f"for an impactor of that radius. (A study of the radius would give the same run for "
                             f"every value.)")
        _set(self, mass=_num(s, "mass", self.mass, "kg", 0, 1e4, lo_open=True))
        self._check_velocity()
        if self.edge_radius is not None:
            if self.shape != "flat":
                raise InputError(f"[impactor] edge_radius = {self.edge_radius!r} m is only for shape = 'flat' (the "
                                 f"rounded rim of a flat cylindrical impactor), but shape = {self.shape!r}; remove it.")
            _set(self, edge_radius=_num(s, "edge_radius", self.edge_radius, "m", 0.0, self.radius, hi_open=True,
                                        note=f"It is the rim radius of the flat face; it must be below the impactor "
                                             f"radius {self.radius:g} m. 0 is a sharp rim (singular stress; the "
                                             f"explicit backends may refuse it)."))
        if self.offset is not None:
            off = _vector(s, "offset", self.offset, 2, "m, the impact point [x, y] relative to the specimen centre")
            for k, v in zip("xy", off):
                _num(s, f"offset {k}", v, "m", -1.0, 1.0, note="The impact point must lie on the specimen.")
            _set(self, offset=off)

    def _check_velocity(self):
        s, v = "impactor", self.velocity
        if isinstance(v, (list, tuple)):
            vec = _vector(s, "velocity", v, 3, "m/s, [vx, vy, vz] with vz < 0 (moving down)")
            if not vec[2] < 0.0:
                raise InputError(f"[impactor] velocity = {list(v)!r} m/s has vz = {vec[2]!r} m/s; the vector form "
                                 f"needs vz < 0 (the impactor moves down onto the specimen). Give e.g. "
                                 f"[0.0, 0.0, -1.0] or a speed (a positive number).")
            speed = math.hypot(*vec)  # no overflow or underflow of the squares (1e300 is not inf, 1e-300 not 0)
            _num(s, "velocity (magnitude)", speed, "m/s", 0, 1e3, lo_open=True)
            for key in ("angle", "azimuth"):
                if getattr(self, key) is not None:
                    raise InputError(f"[impactor] {key} = {getattr(self, key)!r} deg is only for a velocity given as "
                                     f"a speed; velocity = {list(v)!r} m/s is a vector that already has a direction. "
                                     f"Remove {key} or give the speed (m/s).")
            _set(self, velocity=vec)
            return
        _set(self, velocity=_num(s, "velocity", v, "m/s", 0, 1e3, lo_open=True,
                                 note="It is the impact speed (the direction is down, tilted by angle and azimuth "
                                      "if given), or a vector [vx, vy, vz] in m/s."))
        if self.angle is not None:
            _set(self, angle=_num(s, "angle", self.angle, "deg", 0.0, 89.0,
                                  note="It is the angle between the velocity and the plate normal (-z)."))
        if self.azimuth is not None:
            if self.angle is None:
                raise InputError(f"[impactor] azimuth = {self.azimuth!r} deg turns the in-plane part of an oblique "
                                 f"velocity, but no angle (deg from the plate normal, 0..89) is given; give angle "
                                 f"or remove azimuth.")
            _set(self, azimuth=_num(s, "azimuth", self.azimuth, "deg", -360.0, 360.0,
                                    note="It is measured in the plate plane from +x towards +y."))

    @property
    def vector(self) -> np.ndarray:
        """(3,) initial velocity (m/s); components below :data:`ZERO_COMPONENT` x speed are 0."""
        if isinstance(self.velocity, tuple):
            return np.array(self.velocity, dtype=np.float64)
        s = float(self.velocity)
        if not self.angle:
            return np.array([0.0, 0.0, -s])
        a, b = math.radians(self.angle), math.radians(self.azimuth or 0.0)
        v = np.array([s * math.sin(a) * math.cos(b), s * math.sin(a) * math.sin(b), -s * math.cos(a)])
        v[np.abs(v) < ZERO_COMPONENT * s] = 0.0
        return v

    @property
    def speed(self) -> float:
        """Impact speed |v| (m/s)."""
        return float(self.velocity) if not isinstance(self.velocity, tuple) else math.hypot(*self.velocity)

    @property
    def normal_speed(self) -> float:
        """Speed towards the plate, -v_z (m/s, > 0)."""
        return float(self.velocity) if not isinstance(self.velocity, tuple) and not self.angle else float(-self.vector[2])

    @property
    def edge(self) -> float:
        """Rim radius of a flat impactor (m): edge_radius, default min(1e-3, radius / 2); 0 for other shapes."""
        if self.shape != "flat":
            return 0.0
        return float(self.edge_radius) if self.edge_radius is not None else min(DEFAULT_EDGE_RADIUS, 0.5 * self.radius)

    @property
    def point(self) -> tuple[float, float]:
        """Impact point (x, y) relative to the specimen centre (m)."""
        return (0.0, 0.0) if self.offset is None else (float(self.offset[0]), float(self.offset[1]))

    @property
    def bottom(self) -> float:
        """Height of the reference point above the lowest point (m): radius for spheres, 0 for flat and plane."""
        return float(self.radius) if self.shape in ("sphere", "hemisphere") else 0.0


def resolve_symmetry(specimen, impactor: Impactor, requested: str) -> tuple[str, str]:
    """The symmetry of the model and why (the run reports both).

    Parameters
    ----------
    specimen : Specimen
        The [specimen] section; a user mesh fixes the symmetry by its shape
        (``specimen.mesh_symmetry``: "quarter" for the x, y >= 0 quarter, "half" for y >= 0
        centred in x, "none" for a mesh centred at x = y = 0).
    impactor : Impactor
        The [impactor] section (impact point and velocity).
    requested : str
        [specimen] symmetry: "auto", "quarter", "half" or "none".

    Returns
    -------
    symmetry : str
        "quarter" (x, y >= 0 modelled; needs offset 0 and no in-plane velocity), "half" (the
        plane y = 0, y >= 0 modelled; needs offset y = 0 and vy = 0) or "none".
    reason : str
        One sentence saying why.

    Raises
    ------
    InputError
        A requested (or mesh-given) symmetry that the impact point or velocity breaks, or that
        the mesh's shape does not allow; the message names the offending value and unit.
    """
    (ox, oy), v = impactor.point, impactor.vector
    breaks = {"quarter": [], "half": []}
    if ox != 0.0:
        breaks["quarter"].append(f"[impactor] offset x = {ox:g} m is not 0")
    if v[0] != 0.0:
        breaks["quarter"].append(f"the velocity has vx = {v[0]:g} m/s")
    if oy != 0.0:
        breaks["half"].append(f"[impactor] offset y = {oy:g} m is not 0")
    if v[1] != 0.0:
        breaks["half"].append(f"the velocity has vy = {v[1]:g} m/s")
    breaks["quarter"] += breaks["half"]
    mesh_sym = getattr(specimen, "mesh_symmetry", None) if specimen.mesh is not None else None
    if mesh_sym is not None and requested in ("auto", mesh_sym):
        if mesh_sym != "none" and breaks[mesh_sym]:
            raise InputError(f"[specimen] mesh '{specimen.mesh}' is a {mesh_sym} model (its shape), but "
                             f"{' and '.join(breaks[mesh_sym])}, so the impact is not symmetric about its symmetry "
                             f"plane(s). Give a full mesh centred at x = y = 0 with symmetry = 'none', or a centred, "
                             f"vertical impact.")
        kind = "a whole-specimen (no symmetry)" if mesh_sym == "none" else f"a {mesh_sym}"
        return mesh_sym, f"the mesh '{_file_name(specimen.mesh)}' is {kind} model"
    if requested in ("quarter", "half"):
        if breaks[requested]:
            plane = "planes x = 0 and y = 0" if requested == "quarter" else "plane y = 0"
            allowed = "'half' or 'none'" if requested == "quarter" and not breaks["half"] else "'none'"
            raise InputError(f"[specimen] symmetry = {requested!r} needs an impact symmetric about the {plane}, but "
                             f"{' and '.join(breaks[requested])}. Use symmetry = 'auto' (chooses the symmetry the "
                             f"impact allows) or {allowed}.")
        return requested, f"symmetry = {requested!r} was asked for and the impact allows it"
    if requested == "none":
        return "none", "symmetry = 'none' was asked for"
    if not breaks["quarter"]:
        return "quarter", "auto: centred impact along the plate normal on a symmetric specimen"
    if not breaks["half"]:
        return "half", f"auto: {' and '.join(breaks['quarter'])} (the plane y = 0 still holds)"
    return "none", f"auto: {' and '.join(breaks['quarter'])}"


def _file_name(path) -> str:
    """The file name of a path (for the reason sentence)."""
    return Path(str(path)).name
