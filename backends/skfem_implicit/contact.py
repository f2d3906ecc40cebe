"""Nodal penalty contact with a rigid sphere (one dof: its z displacement w) and a rigid plane.

Penetrations (m, positive when inside): sphere g = R - |d|, d = x - c(w), c(w) = c0 + w e_z;
plane g = z_p - x_z. Penalty force p(g) (N) with stiffness k (N/m per node), made C^1 over a
small gap g0 (m) so that Newton keeps converging when nodes enter or leave contact:

    p = 0 (g <= 0),   k g^2 / (2 g0) (0 < g < g0),   k (g - g0/2) (g >= g0)
    phi = int_0^g p = k g^3 / (6 g0)  or  k (g^2/2 - g0 g/2 + g0^2/6)     (energy, J)

With y = (x, w) and d = B y - c0, B = [I, -e_z]:

    dPhi/dy   = p dg/dy,               dg/dy = -B^T n,   n = d / |d|
    d2Phi/dy2 = p' dg dg^T + p d2g,    d2g   = -B^T (I - n n^T) B / |d|

the exact Hessian (symmetric). The contact force on the impactor (N, +z, modelled part) is
-dPhi/dw = -sum k g n_z, positive when the specimen decelerates a downward-moving impactor.
Frictionless: a friction coefficient other than 0 is rejected by the solver.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ContactState:
    """Active nodes and their contributions (modelled part).

    energy (J); force_on_impactor (N, +z); max_pen_sphere / max_pen_plane (m);
    grad: list of (dofs (m,), values (m,)); hess: list of (rows, cols, values) COO triplets.
    """

    energy: float
    force_on_impactor: float
    max_pen_sphere: float
    max_pen_plane: float
    grad: list
    hess: list
    n_active: int


def penalty_law(g: np.ndarray, k: float, g0: float):
    """(p, dp/dg, phi) of the C^1 penalty law for penetrations g > 0 (m): N, N/m, J."""
    lo = g < g0
    p = np.where(lo, 0.5 * k * g * g / g0, k * (g - 0.5 * g0))
    dp = np.where(lo, k * g / g0, k)
    phi = np.where(lo, k * g ** 3 / (6.0 * g0), k * (0.5 * g * g - 0.5 * g0 * g + g0 * g0 / 6.0))
    return p, dp, phi


def evaluate(x: np.ndarray, w: float, sphere, sphere_nodes: np.ndarray, plane, plane_nodes: np.ndarray,
             k: float, w_dof: int, tangent: bool = True, g0: float = 0.0) -> ContactState:
    """Contact contributions at current positions x (n, 3) (m) and impactor displacement w (m).

    g0 (m): smoothing gap of the penalty law (0: the plain k/2 <g>^2).
    """
    g0 = max(float(g0), 1e-300)
    energy, fz, pen_s, pen_p, n_active = 0.0, 0.0, 0.0, 0.0, 0
    grad, hess = [], []
    if sphere is not None and len(sphere_nodes):
        c = np.array(sphere.center, dtype=np.float64)
        c[2] += w
        d = x[sphere_nodes] - c
        r = np.sqrt(np.einsum("ni,ni->n", d, d))
        g = sphere.radius - r
        act = g > 0.0
        if act.any():
            nodes, g, r, d = sphere_nodes[act], g[act], r[act], d[act]
            n = d / r[:, None]
            m = nodes.size
            n_active += m
            p, dp, phi = penalty_law(g, k, g0)
            energy += float(np.sum(phi))
            pen_s = float(g.max())
            # gradient over (x_node (3), w): a = [-n, n_z]
            a = np.concatenate([-n, n[:, 2:3]], axis=1)  # (m, 4)
            dofs = np.concatenate([3 * nodes[:, None] + np.arange(3)[None, :],
                                   np.full((m, 1), w_dof)], axis=1)  # (m, 4)
            grad.append((dofs.ravel(), (p[:, None] * a).ravel()))
            fz = -float(np.sum(p * n[:, 2]))
            if tangent:
                P = np.eye(3)[None] - n[:, :, None] * n[:, None, :]  # (m, 3, 3)
                Bm = np.zeros((m, 3, 4))
                Bm[:, :, :3] = np.eye(3)
                Bm[:, 2, 3] = -1.0
                d2g = -np.einsum("mij,mjk,mkl->mil", Bm.transpose(0, 2, 1), P, Bm) / r[:, None, None]
                H = dp[:, None, None] * a[:, :, None] * a[:, None, :] + p[:, None, None] * d2g  # (m, 4, 4)
                rows = np.broadcast_to(dofs[:, :, None], H.shape)
                cols = np.broadcast_to(dofs[:, None, :], H.shape)
                hess.append((rows.ravel(), cols.ravel(), H.ravel()))
    if plane is not None and len(plane_nodes):
        g = plane.z - x[plane_nodes, 2]
        act = g > 0.0
        if act.any():
            nodes, g = plane_nodes[act], g[act]
            n_active += nodes.size
            p, dp, phi = penalty_law(g, k, g0)
            energy += float(np.sum(phi))
            pen_p = float(g.max())
            dofs = 3 * nodes + 2
            grad.append((dofs, -p))
            if tangent:
                hess.append((dofs, dofs, dp))
    return ContactState(energy, fz, pen_s, pen_p, grad, hess, n_active)
