"""One pass over a state for the physics checks: the extremes the monitor needs (numpy reference).

The run monitor (:class:`cfm_core.simulation.checks.Monitor`) decides from a handful of numbers
per check; a *scan* computes them from the nodal positions x (n, 3) (m) and the impactor's
current reference point, as extremes with the index that attains them (:class:`Extremes`):

* the first node with a non-finite coordinate (-1 if none); when there is one the scan stops
  there and the other fields are left empty;
* the deepest node behind the rigid plate: depth ``plate_z - x_z`` (m) and node;
* per symmetry plane (axis d, coordinate c, side s) the deepest crossing ``-(x_d - c) s`` (m) and
  node;
* the deepest node inside the impactor: depth ``-g`` (m, g = :func:`cfm_core.scene.impactor.gap`)
  over the nodes in the impactor's box (:func:`cfm_core.scene.impactor.bounds` widened by the
  tolerance; outside it g >= 0, so only those need the gap), or none when no node is in the box;
* the smallest corner-Jacobian ratio to the reference, the triple product of the three edges
  leaving a corner over its reference value (:func:`corner_volumes`), with element and local
  corner (0-7, VTK order).

Ties go to the smallest index (node; element, then corner), as numpy's argmax / argmin give
them; a NaN ratio (a degenerate reference corner, 0 / 0) counts as the smallest, as argmin has
it. :class:`Scan` is the reference (numpy, the user's numbering), used by the torch and skfem
backends; the numba backend's parallel one (``cfm_backends.numba_explicit.scan``) reads its own
numbering and returns the same extremes in the user's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene.impactor import bounds, impactor_gap
from ..scene.mesh import HEX_REFERENCE


@dataclass(frozen=True)
class Extremes:
    """What a scan found (user numbering; SI units).

    Attributes
    ----------
    nonfinite : int
        First node with a non-finite coordinate, -1 if none (then nothing else is filled in).
    plate : tuple (float, int) or None
        (depth behind the rigid plate in m, node) of the deepest node; None without a plate.
    impactor : tuple (float, int) or None
        (depth inside the impactor in m, node) of the deepest node of its box; None without an
        impactor position or when no node is in the box.
    symmetry : tuple of tuple (float, int)
        (depth across the plane in m, node) of the deepest node, per symmetry plane.
    corner : tuple (float, int, int) or None
        (ratio of the corner triple product to its reference value (-), element, local corner)
        of the smallest ratio; None without elements.
    """

    nonfinite: int = -1
    plate: tuple | None = None
    impactor: tuple | None = None
    symmetry: tuple = ()
    corner: tuple | None = None


def _corner_neighbours() -> np.ndarray:
    """(3, 8): for each corner a of the VTK hexahedron, its neighbour along xi, eta and zeta."""
    out = np.zeros((3, 8), dtype=np.int64)
    for a in range(8):
        for k in range(3):
            target = HEX_REFERENCE[a].copy()
            target[k] = -target[k]
            out[k, a] = int(np.flatnonzero((HEX_REFERENCE == target).all(axis=1))[0])
    return out


NEIGHBOURS = _corner_neighbours()


def corner_volumes(x: np.ndarray, hexes: np.ndarray) -> np.ndarray:
    """Triple products of the three edges leaving each element corner (xi, eta, zeta order).

    The Jacobian of the trilinear map at corner a is this product times -(s1 s2 s3) / 8 (s = the
    corner's natural coordinates), so its ratio to the reference value is the Jacobian's ratio.

    Parameters
    ----------
    x : ndarray, shape (n, 3)
        Nodal positions (m).
    hexes : ndarray, shape (e, 8)
        Connectivity, VTK hexahedron order.

    Returns
    -------
    ndarray, shape (e, 8)
        Triple products (m^3); <= 0 where the element is folded at that corner.
    """
    X = np.asarray(x, dtype=np.float64)[np.asarray(hexes)]          # (e, 8, 3)
    e1 = X[:, NEIGHBOURS[0]] - X
    e2 = X[:, NEIGHBOURS[1]] - X
    e3 = X[:, NEIGHBOURS[2]] - X
    # e1 . (e2 x e3), summed as (x + z) + y: the order of the einsum this replaced (its two SIMD
    # lanes), so the ratios the monitor reports are unchanged; written out, it is the same on
    # every machine, and the compiled scan (cfm_backends.numba_explicit.scan) sums in this order
    out = e1[..., 0] * (e2[..., 1] * e3[..., 2] - e2[..., 2] * e3[..., 1])
    out += e1[..., 2] * (e2[..., 0] * e3[..., 1] - e2[..., 1] * e3[..., 0])
    out += e1[..., 1] * (e2[..., 2] * e3[..., 0] - e2[..., 0] * e3[..., 2])
    return out


class Scan:
    """The numpy scan of a model's states (module docstring); the monitor's default.

    Parameters
    ----------
    model : cfm_core.scene.Model
        Reference nodes (n, 3) in m, hexes (e, 8), plane, sphere (the impactor).
    tol : float
        Penetration tolerance (m): the impactor's box is widened by it.
    planes : list of tuple
        Symmetry planes (axis 0-2, coordinate in m, side +1.0 or -1.0),
        :func:`cfm_core.simulation.checks.symmetry_planes`.
    """

    def __init__(self, model, tol: float, planes):
        self.tol = float(tol)
        self.planes = list(planes)
        self.plate = None if model.plane is None else float(model.plane.z)
        self.impactor = model.sphere
        self.hexes = np.asarray(model.hexes, dtype=np.int64)
        self.ref = corner_volumes(model.nodes, self.hexes)
        self._ratio = np.empty_like(self.ref)

    def __call__(self, x: np.ndarray, centre=None) -> Extremes:
        """The extremes of one state.

        Parameters
        ----------
        x : ndarray, shape (n, 3)
            Nodal positions (m).
        centre : ndarray, shape (3,), optional
            The impactor's current reference point (m); None: no impactor check.

        Returns
        -------
        Extremes
            As the module docstring lists them.
        """
        x = np.asarray(x, dtype=np.float64)
        bad = ~np.isfinite(x).all(axis=1)
        if bad.any():
            return Extremes(nonfinite=int(np.argmax(bad)))
        plate = impactor = corner = None
        if self.plate is not None:
            depth = self.plate - x[:, 2]
            i = int(np.argmax(depth))
            plate = (float(depth[i]), i)
        if self.impactor is not None and centre is not None:
            lo, hi = bounds(self.impactor.shape, self.impactor.radius, centre)
            near = np.flatnonzero(((x > lo - self.tol) & (x < hi + self.tol)).all(axis=1))  # the rest: g >= 0
            if near.size:
                depth = -impactor_gap(self.impactor, centre, x[near])[0]
                k = int(np.argmax(depth))
                impactor = (float(depth[k]), int(near[k]))
        symmetry = []
        for axis, c, side in self.planes:
            depth = -(x[:, axis] - c) * side
            i = int(np.argmax(depth))
            symmetry.append((float(depth[i]), i))
        if self.hexes.size:
            ratio = np.divide(corner_volumes(x, self.hexes), self.ref, out=self._ratio)
            e, a = divmod(int(np.argmin(ratio)), 8)
            corner = (float(ratio[e, a]), e, a)
        return Extremes(-1, plate, impactor, tuple(symmetry), corner)

    def position(self, x: np.ndarray, node: int) -> np.ndarray:
        """(3,) position (m) of the user's node ``node`` in the state ``x`` this scan reads."""
        return np.asarray(x, dtype=np.float64)[int(node)]
