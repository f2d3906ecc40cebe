"""Reference-configuration geometry of hex8 elements for the explicit solvers (numpy, SI units).

Per element (Flanagan & Belytschko 1981, "uniform strain" hexahedron):

- V0 (m^3): exact volume, int det J over the 2x2x2 Gauss points (det J of a trilinear map has
  degree <= 2 per variable, so this is exact);
- B (8, 3) (1/m): mean shape-function gradient (1/V0) int dN_I/dX dV, exact with 2x2x2 Gauss
  (the integrand cof(J)^T grad_xi N has degree <= 3 per variable). It satisfies
  sum_I X_I (x) B_I = I and sum_I B_I = 0 for any hexahedron, so a linear displacement field
  gives the same F in every element (patch test) and interior nodes of a homogeneous state carry
  no residual force;
- G (8, 4): hourglass vectors (node, mode) gamma_alpha = h_alpha - (h_alpha . X_j) B_j with the base vectors
  h = (xi eta, eta zeta, zeta xi, xi eta zeta) at the nodes (entries +-1); G annihilates
  linear fields;
- L (m): characteristic length of the stable step dt = L / c, from the Flanagan-Belytschko
  bound on the largest eigenfrequency of the one-point element with lumped mass,
  omega_max^2 <= 8 c^2 sum_I |B_I|^2, i.e. L = 1 / sqrt(2 sum_I |B_I|^2): L = a / sqrt(3) for a
  cube of edge a. The one-dimensional estimate V0 / (largest face area) = a is too large by
  sqrt(3) when the bulk modulus dominates (the dilatational mode of an element at a free corner
  has omega = 2 sqrt(3) c / a): with kappa 100 times Table 1 it let the energy grow 20-fold;
- lumped nodal mass rho V0 / 8 (kg) and the node -> (element, local node) incidence in CSR form.

Node order: meshio/VTK hexahedron (bottom face counter-clockwise seen from +z, then top face).
"""

from __future__ import annotations

import itertools

import numpy as np

from cfm_core.errors import InputError

XI = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
               [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=np.float64)
HG_BASE = np.stack([XI[:, 0] * XI[:, 1], XI[:, 1] * XI[:, 2], XI[:, 2] * XI[:, 0],
                    XI[:, 0] * XI[:, 1] * XI[:, 2]])


def _dN_dxi(point: np.ndarray) -> np.ndarray:
    """Trilinear shape-function derivatives (8, 3) at a natural point (3,)."""
    lin = 1.0 + XI * point[None, :]
    out = np.empty((8, 3))
    for k in range(3):
        others = [j for j in range(3) if j != k]
        out[:, k] = XI[:, k] * lin[:, others[0]] * lin[:, others[1]] / 8.0
    return out


def hex_geometry(nodes: np.ndarray, hexes: np.ndarray):
    """(V0 (e,), B (e, 8, 3), G (e, 8, 4), L (e,)) of the elements; see the module docstring.

    Raises InputError naming the first element whose Jacobian is not positive at a Gauss point
    (inverted or badly distorted element, or connectivity not in VTK order).
    """
    X = np.asarray(nodes, dtype=np.float64)[np.asarray(hexes)]
    ne = X.shape[0]
    V0 = np.zeros(ne)
    Bsum = np.zeros((ne, 8, 3))
    g = 1.0 / np.sqrt(3.0)
    for point in itertools.product((-g, g), repeat=3):
        dN = _dN_dxi(np.array(point))
        Jm = np.einsum("eai,ak->eik", X, dN)          # dX_i / dxi_k
        det = np.linalg.det(Jm)
        bad = ~(det > 0.0)
        if bad.any():
            e = int(np.argmax(bad))
            raise InputError(
                f"element {e} has a non-positive Jacobian ({det[e]:.3g} m^3) at a Gauss point: it is "
                f"inverted, badly distorted, or its nodes are not in VTK hexahedron order (bottom face "
                f"counter-clockwise seen from above, then the top face); nodes {hexes[e].tolist()}.")
        inv = np.linalg.inv(Jm)                       # dxi_k / dX_j
        Bsum += det[:, None, None] * np.einsum("ak,ekj->eaj", dN, inv)
        V0 += det
    B = Bsum / V0[:, None, None]
    hx = np.einsum("sa,eaj->esj", HG_BASE, X)
    G = HG_BASE.T[None, :, :] - np.einsum("esj,eaj->eas", hx, B)
    L = 1.0 / np.sqrt(2.0 * np.einsum("eaj,eaj->e", B, B))
    return V0, B, G, L


def incidence(hexes: np.ndarray, n_nodes: int):
    """CSR node -> element incidence: (ptr (n+1,), rows (8e,)), int64; row = 8 element + local node."""
    flat = np.asarray(hexes, dtype=np.int64).ravel()
    order = np.argsort(flat, kind="stable")
    counts = np.bincount(flat, minlength=n_nodes)
    ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return ptr, order.astype(np.int64)


def lumped_mass(hexes: np.ndarray, V0: np.ndarray, rho, n_nodes: int) -> np.ndarray:
    """Nodal masses (kg): rho V0 / 8 from every element a node belongs to (rho: kg/m^3, a number
    or one per element, shape (e,))."""
    return np.bincount(np.asarray(hexes).ravel(), weights=np.repeat(rho * V0 / 8.0, 8),
                       minlength=n_nodes)


def constraints(model, nodes: np.ndarray, hexes: np.ndarray, V0: np.ndarray):
    """Lumped masses and the free / prescribed dof masks of a model.

    Parameters
    ----------
    model : cfm_core.scene.model.Model
        The model (density kg/m^3, per part when it has parts; fixed dofs, prescribed motion).
    nodes : (n, 3) ndarray
        Reference coordinates (m).
    hexes : (e, 8) ndarray of int
        Connectivity (VTK order).
    V0 : (e,) ndarray
        Element volumes (m^3) from :func:`hex_geometry`.

    Returns
    -------
    mass : (n,) ndarray
        Lumped nodal masses (kg); 1 on massless nodes (which are held fixed).
    free : (n, 3) ndarray
        1 on free dofs, 0 on fixed, massless and prescribed ones.
    pmask : (n, 3) ndarray
        1 on prescribed dofs.
    pnodes : (p,) ndarray of int64
        The prescribed nodes (empty when none).
    """
    n = nodes.shape[0]
    rho = float(model.density) if not model.parts else model.element_density()
    mass = lumped_mass(hexes, V0, rho, n)
    free = np.ones((n, 3))
    free[mass <= 0.0] = 0.0
    mass = np.where(mass > 0.0, mass, 1.0)
    fixed = np.asarray(model.fixed_dofs, dtype=np.int64).reshape(-1, 2)
    free[fixed[:, 0], fixed[:, 1]] = 0.0
    pmask = np.zeros((n, 3))
    pnodes = np.zeros(0, dtype=np.int64)
    pr = model.prescribed
    if pr is not None:
        pnodes = np.ascontiguousarray(pr.nodes, dtype=np.int64)
        free[pnodes, pr.dof] = 0.0
        pmask[pnodes, pr.dof] = 1.0
    return mass, free, pmask, pnodes
