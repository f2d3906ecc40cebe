"""Triangulated surfaces of the rigid impactor for the ParaView output, one per shape.

Every surface is given relative to the impactor's reference point (m) and lies on the surface of
:func:`cfm_core.scene.impactor.gap` (gap 0 to round-off): a triangulated surface of revolution
about the z axis for ``hemisphere`` (the lower half, as the paper's impactor), ``sphere`` and
``flat`` (bottom disc, rounded rim, cylinder wall up to one radius above the bottom face), and a
square patch for ``plane`` (the contact plane z = reference z, covering the specimen: the patch
is given in absolute x, y and only its height moves).

``sector`` clips the surfaces of revolution to a symmetric model: ``"quarter"`` x, y >= 0 of the
reference point, ``"half"`` y >= 0 (or y <= 0 with ``side = -1``), None the whole surface.
Azimuths 0, pi/2, pi and 3 pi/2 are always vertices, so a cut on y = 0 (``cfm fields``) meets a
meridian of vertices.
"""

from __future__ import annotations

import math

import numpy as np


def _profile(shape: str, radius: float, edge_radius: float, n: int) -> np.ndarray:
    """(p, 2) meridian (r, z) (m) from the lowest point on the axis upwards, r >= 0."""
    R = float(radius)
    if shape in ("hemisphere", "sphere"):
        theta = np.linspace(0.0, 0.5 * math.pi if shape == "hemisphere" else math.pi, n + 1)
        r, z = R * np.sin(theta), -R * np.cos(theta)
        r[0] = 0.0
        if shape == "sphere":
            r[-1] = 0.0
        else:  # the equator exactly at r = R (sin(pi/2) is 1 in floating point; keep it explicit)
            r[-1] = R
        return np.stack([r, z], axis=1)
    if shape == "flat":
        re = float(edge_radius)
        a = R - re
        disc = np.stack([np.linspace(0.0, a, max(2, n // 2) + 1), np.zeros(max(2, n // 2) + 1)], axis=1)
        pieces = [disc]
        if re > 0.0:
            phi = np.linspace(-0.5 * math.pi, 0.0, max(2, n // 2) + 1)[1:]
            arc = np.stack([a + re * np.cos(phi), re + re * np.sin(phi)], axis=1)
            arc[-1] = (R, re)
            pieces.append(arc)
        top = max(R, 2.0 * re)
        wall = np.stack([np.full(max(2, n // 4), R), np.linspace(re, top, max(2, n // 4) + 1)[1:]], axis=1)
        pieces.append(wall)
        return np.vstack(pieces)
    raise ValueError(f"no surface of revolution for impactor shape {shape!r}")


def revolve(profile: np.ndarray, start: float, stop: float, n_azimuth: int, closed: bool):
    """Triangulate the surface of revolution of a meridian about the z axis.

    Parameters
    ----------
    profile : ndarray, shape (p, 2)
        (r, z) (m) in order along the meridian; r = 0 points (poles) become one vertex.
    start, stop : float
        Azimuth range (rad).
    n_azimuth : int
        Divisions of the range.
    closed : bool
        The range is the whole circle (the last azimuth is the first).

    Returns
    -------
    points : ndarray, shape (q, 3)
    triangles : ndarray, shape (t, 3), int64
    """
    phi = np.linspace(start, stop, n_azimuth + 1)
    if closed:
        phi = phi[:-1]
    cols = len(phi)
    points, rows = [], []
    for r, z in profile:
        if r == 0.0:
            rows.append([len(points)] * cols)
            points.append((0.0, 0.0, z))
        else:
            rows.append(list(range(len(points), len(points) + cols)))
            points += [(r * math.cos(p), r * math.sin(p), z) for p in phi]
    tris = []
    span = cols if closed else cols - 1
    for i in range(len(rows) - 1):
        a, b = rows[i], rows[i + 1]
        for j in range(span):
            j1 = (j + 1) % cols
            for tri in ((a[j], b[j], b[j1]), (a[j], b[j1], a[j1])):
                if len(set(tri)) == 3:       # a pole row: one of the two triangles degenerates
                    tris.append(tri)
    return np.asarray(points, dtype=np.float64), np.asarray(tris, dtype=np.int64)


def impactor_surface(impactor, sector: str | None = None, side: int = 1, extent=None, n: int = 24):
    """The impactor's surface relative to its reference point, triangulated.

    Parameters
    ----------
    impactor : RigidSphere
        ``shape``, ``radius`` (m), ``edge_radius`` (m).
    sector : {"quarter", "half", None}
        Clip a surface of revolution to the modelled part of a symmetric model (module docstring).
    side : int
        +1: the half model lies at y >= 0; -1: at y <= 0.
    extent : tuple of float, optional
        ``(xmin, xmax, ymin, ymax)`` (m, absolute) of the plane's patch; needed for ``plane``.
    n : int
        Divisions of the meridian (a quarter circle gets n, a whole circle 4 n around).

    Returns
    -------
    points : ndarray, shape (q, 3)
        Vertices (m): relative to the reference point; for ``plane`` absolute x, y and z
        relative to the reference point (0).
    triangles : ndarray, shape (t, 3), int64

    Raises
    ------
    ValueError
        Unknown shape, or ``plane`` without ``extent``.
    """
    shape = impactor.shape
    if shape == "plane":
        if extent is None:
            raise ValueError("the plane impactor's patch needs the extent (xmin, xmax, ymin, ymax) it covers")
        xs, ys = np.linspace(extent[0], extent[1], n + 1), np.linspace(extent[2], extent[3], n + 1)
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        points = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
        idx = np.arange(X.size).reshape(X.shape)
        a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
        return points, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int64)
    profile = _profile(shape, impactor.radius, impactor.edge_radius, n)
    if sector == "quarter":
        return revolve(profile, 0.0, 0.5 * math.pi, n, closed=False)
    if sector == "half":
        return revolve(profile, 0.0, math.pi, 2 * n, closed=False) if side >= 0 else \
            revolve(profile, -math.pi, 0.0, 2 * n, closed=False)
    return revolve(profile, 0.0, 2.0 * math.pi, 4 * n, closed=True)


def impactor_positions(model, result, times) -> np.ndarray:
    """(f, 3) reference point of the impactor (m) at the frame times (s).

    z from ``Result.impactor_z``, x and y from ``Result.impactor_lateral`` when the impactor moves
    in-plane (linear interpolation in the history), else the initial ``center``.
    """
    sph = model.sphere
    times = np.asarray(times, dtype=np.float64)
    pos = np.tile(np.asarray(sph.center, dtype=np.float64), (len(times), 1))
    t = np.asarray(result.t, dtype=np.float64)
    if result.impactor_z is not None and len(t):
        pos[:, 2] = np.interp(times, t, result.impactor_z)
    lateral = getattr(result, "impactor_lateral", None)
    if lateral and len(t):
        for axis, key in ((0, "x"), (1, "y")):
            if key in lateral and lateral[key] is not None:
                pos[:, axis] = np.interp(times, t, lateral[key])
    return pos
