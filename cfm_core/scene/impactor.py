"""Surface of a rigid impactor: signed gap and outward normal of each shape (numpy reference).

One formula per shape, used by the run checks, the implicit contact and the tests; the explicit
kernels (numba, torch) compile the same formulas and are tested against these. SI units (m).

Shapes (the impactor translates without rotating; axis along z; ``c`` its reference point):

* ``"sphere"``: g = |x - c| - R, n = (x - c) / |x - c|.
* ``"hemisphere"``: the sphere's lower half (the paper's impactor); points at or above the
  centre plane (x_z >= c_z) never touch it (g = +inf).
* ``"flat"``: a cylinder of radius R, bottom face at z = c_z, its rim rounded with radius r
  (``edge_radius``): the set of points within r of the core cylinder of radius a = R - r whose
  bottom is at c_z + r, extending upwards. With rho the distance from the axis, q = (rho - a,
  c_z + r - z): g = |max(q, 0)| + min(max(q_1, q_2), 0) - r (the signed distance to a rounded
  semi-infinite cylinder; exact outside, the distance to the nearer face inside).
* ``"plane"``: the half-space above z = c_z: g = c_z - z, n = -e_z.
"""

from __future__ import annotations

import numpy as np


def gap(shape: str, radius: float, edge_radius: float, center, points) -> tuple[np.ndarray, np.ndarray]:
    """Signed gap of points to an impactor surface and the impactor's outward normal there.

    Parameters
    ----------
    shape : str
        ``"hemisphere"``, ``"sphere"``, ``"flat"`` or ``"plane"``.
    radius, edge_radius : float
        Radius and rim radius (m), see :class:`cfm_core.scene.model.RigidSphere`.
    center : array_like, shape (3,)
        Current reference point (m).
    points : array_like, shape (k, 3)
        Points (m).

    Returns
    -------
    g : ndarray, shape (k,)
        Signed gap (m): > 0 outside, < 0 inside (penetration -g); +inf where the shape cannot be
        touched (above a hemisphere's centre plane).
    n : ndarray, shape (k, 3)
        Unit outward normal of the impactor at the nearest surface point (the direction that
        pushes a penetrating point out).

    Raises
    ------
    ValueError
        Unknown shape.
    """
    x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    c = np.asarray(center, dtype=np.float64).reshape(3)
    p = x - c
    if shape in ("sphere", "hemisphere"):
        d = np.linalg.norm(p, axis=1)
        safe = np.where(d > 0.0, d, 1.0)
        n = np.where(d[:, None] > 0.0, p / safe[:, None], np.array([0.0, 0.0, -1.0]))
        g = d - float(radius)
        if shape == "hemisphere":
            g = np.where(p[:, 2] < 0.0, g, np.inf)
        return g, n
    if shape == "plane":
        n = np.zeros_like(p)
        n[:, 2] = -1.0
        return -p[:, 2], n
    if shape == "flat":
        r = float(edge_radius)
        a = float(radius) - r
        rho = np.hypot(p[:, 0], p[:, 1])
        er = np.zeros_like(p)
        er[:, 0] = 1.0
        nz = rho > 0.0
        er[nz, 0] = p[nz, 0] / rho[nz]
        er[nz, 1] = p[nz, 1] / rho[nz]
        q1, q2 = rho - a, r - p[:, 2]
        out1, out2 = np.maximum(q1, 0.0), np.maximum(q2, 0.0)
        dist_out = np.hypot(out1, out2)
        g = dist_out + np.minimum(np.maximum(q1, q2), 0.0) - r
        ez = np.array([0.0, 0.0, -1.0])
        corner = (q1 > 0.0) & (q2 > 0.0)
        side = ~corner & (q1 > q2)
        n = np.where(side[:, None], er, ez)
        safe = np.where(dist_out > 0.0, dist_out, 1.0)
        n_corner = (out1[:, None] * er + out2[:, None] * ez) / safe[:, None]
        n = np.where(corner[:, None], n_corner, n)
        return g, n
    raise ValueError(f"unknown impactor shape {shape!r}")


def bounds(shape: str, radius: float, center) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned box holding every point of an impactor where :func:`gap` can be negative.

    Parameters
    ----------
    shape : str
        ``"hemisphere"``, ``"sphere"``, ``"flat"`` or ``"plane"``.
    radius : float
        Radius (m); a flat impactor's rim lies inside it.
    center : array_like, shape (3,)
        Current reference point (m).

    Returns
    -------
    lo, hi : ndarray, shape (3,)
        Corners of the box (m); +-inf where the shape is unbounded (the flat punch and the plane
        upwards, the plane sideways). A point outside the box has g >= 0.

    Raises
    ------
    ValueError
        Unknown shape.
    """
    c = np.asarray(center, dtype=np.float64).reshape(3)
    r = float(radius)
    inf = np.inf
    if shape == "sphere":
        return c - r, c + r
    if shape == "hemisphere":
        return c - r, np.array([c[0] + r, c[1] + r, c[2]])
    if shape == "flat":
        return np.array([c[0] - r, c[1] - r, c[2]]), np.array([c[0] + r, c[1] + r, inf])
    if shape == "plane":
        return np.array([-inf, -inf, c[2]]), np.array([inf, inf, inf])
    raise ValueError(f"unknown impactor shape {shape!r}")


def impactor_gap(impactor, position, points) -> tuple[np.ndarray, np.ndarray]:
    """:func:`gap` of a :class:`cfm_core.scene.model.RigidSphere` at the current reference point
    ``position`` (m, shape (3,)); see :func:`gap` for the returns."""
    return gap(impactor.shape, impactor.radius, impactor.edge_radius, position, points)
