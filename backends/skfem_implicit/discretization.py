"""Hexahedral discretisation with scikit-fem: shape-function gradients, quadrature, masses, dofs.

scikit-fem (``MeshHex1``, ``ElementHex1``, ``Basis``) maps the reference cube to each element and
gives, at the 2 x 2 x 2 Gauss points, dN_a/dX_J (reference configuration, 1/m) and the
integration weights w_q = weight x det(dX/dxi) (m^3). Everything later is numpy on (E, Q) arrays.

Node order: the model's hexes are in meshio/VTK order; scikit-fem numbers the corners of its
reference cube differently, ``VTK_TO_SKFEM`` reorders them (as ``skfem.io.meshio`` does).
Degrees of freedom: u of node n along axis i is dof 3 n + i; a rigid impactor, when present, is
the last dof (its z displacement).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cfm_core.errors import InputError

#: skfem local corner k is the VTK corner VTK_TO_SKFEM[k] (inverse of skfem.io.meshio.HEX_MAPPING[:8]).
VTK_TO_SKFEM = np.array([0, 4, 3, 1, 7, 5, 2, 6])


@dataclass
class Discretization:
    """Arrays of one hexahedral mesh (SI units).

    conn (E, 8): nodes of each element in skfem order; dN (E, Q, 8, 3): dN_a/dX_J (1/m);
    w (E, Q): integration weights (m^3); volume (E,): element volumes (m^3); mass (n,): lumped
    (row-sum) nodal masses for the density (kg); edofs (E, 24): dofs of each element, local
    index 3 a + i; size (m): mean element edge (cube root of the mean volume).
    """

    nodes: np.ndarray
    conn: np.ndarray
    dN: np.ndarray
    w: np.ndarray
    volume: np.ndarray
    mass: np.ndarray
    edofs: np.ndarray
    size: float

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.shape[0])

    @property
    def n_elements(self) -> int:
        return int(self.conn.shape[0])


def discretize(nodes: np.ndarray, hexes: np.ndarray, density, intorder: int = 3) -> Discretization:
    """Build the :class:`Discretization` of a hex mesh (nodes in m, hexes in VTK order).

    density: one mass density (kg/m^3) for every element, or an array (E,) of one per element
    (a model with parts).
    intorder 3 is the 2 x 2 x 2 Gauss rule (exact for the trilinear volume). Raises InputError
    for an element with a non-positive Jacobian at a Gauss point (inverted or wrongly ordered).
    """
    from skfem import Basis, ElementHex1, MeshHex1

    nodes = np.ascontiguousarray(nodes, dtype=np.float64)
    hexes = np.asarray(hexes, dtype=np.int64)
    if nodes.ndim != 2 or nodes.shape[1] != 3 or hexes.ndim != 2 or hexes.shape[1] != 8:
        raise InputError(f"mesh must have nodes (n, 3) and hexes (e, 8); got {nodes.shape} and {hexes.shape}.")
    if hexes.shape[0] == 0 or hexes.min() < 0 or hexes.max() >= nodes.shape[0]:
        raise InputError(f"hexes must index nodes 0..{nodes.shape[0] - 1} and there must be at least one.")
    conn = np.ascontiguousarray(hexes[:, VTK_TO_SKFEM])
    mesh = MeshHex1(np.ascontiguousarray(nodes.T), np.ascontiguousarray(conn.T), validate=False)
    basis = Basis(mesh, ElementHex1(), intorder=intorder)
    w = np.ascontiguousarray(basis.dx)  # (E, Q)
    if not (w > 0).all():
        e = int(np.argmax((w <= 0).any(axis=1)))
        raise InputError(f"element {e} has a non-positive Jacobian at a Gauss point: it is inverted, "
                         f"degenerate or its nodes are not in VTK hexahedron order.")
    dN = np.stack([basis.basis[a][0].grad.transpose(1, 2, 0) for a in range(8)], axis=2)
    N = np.stack([np.asarray(basis.basis[a][0]) for a in range(8)], axis=2)  # (E, Q, 8)
    volume = w.sum(axis=1)
    mass = np.zeros(nodes.shape[0])
    if np.ndim(density) == 0:
        np.add.at(mass, conn, float(density) * np.einsum("eq,eqa->ea", w, N))
    else:
        rho = np.asarray(density, dtype=np.float64).reshape(-1)
        if rho.shape[0] != conn.shape[0]:
            raise InputError(f"density: {rho.shape[0]} element densities for {conn.shape[0]} elements.")
        np.add.at(mass, conn, rho[:, None] * np.einsum("eq,eqa->ea", w, N))
    edofs = (3 * conn[:, :, None] + np.arange(3)[None, None, :]).reshape(-1, 24)
    return Discretization(nodes=nodes, conn=conn, dN=np.ascontiguousarray(dN), w=w, volume=volume,
                          mass=mass, edofs=edofs, size=float(np.cbrt(volume.mean())))
