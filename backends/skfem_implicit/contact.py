"""Nodal penalty contact with a rigid sphere (one dof: its z displacement w) and a rigid plane.

Penetrations (m, positive when inside): sphere g = R - |d|, d = x - c(w), c(w) = c0 + w e_z;
plane g = z_p - x_z. Energy Phi = sum k/2 <g>^2 (J), k the penalty stiffness (N/m per node).
With y = (x, w) and d = B y - c0, B = [I, -e_z]:

    dPhi/dy   = k g dg/dy,            dg/dy = -B^T n,   n = d / |d|
    d2Phi/dy2 = k dg dg^T + k g d2g,  d2g   = -B^T (I - n n^T) B / |d|

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


def evaluate(x: np.ndarray, w: float, sphere, sphere_nodes: np.ndarray, plane, plane_nodes: np.ndarray,
             k: float, w_dof: int, tangent: bool = True) -> ContactState:
    """Contact contributions at current positions x (n, 3) (m) and impactor displacement w (m)."""
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
            energy += 0.5 * k * float(np.sum(g * g))
            pen_s = float(g.max())
            # gradient over (x_node (3), w): a = [-n, n_z]
            a = np.concatenate([-n, n[:, 2:3]], axis=1)  # (m, 4)
            dofs = np.concatenate([3 * nodes[:, None] + np.arange(3)[None, :],
                                   np.full((m, 1), w_dof)], axis=1)  # (m, 4)
            grad.append((dofs.ravel(), (k * g[:, None] * a).ravel()))
            fz = -float(np.sum(k * g * n[:, 2]))
            if tangent:
                P = np.eye(3)[None] - n[:, :, None] * n[:, None, :]  # (m, 3, 3)
                Bm = np.zeros((m, 3, 4))
                Bm[:, :, :3] = np.eye(3)
                Bm[:, 2, 3] = -1.0
                d2g = -np.einsum("mij,mjk,mkl->mil", Bm.transpose(0, 2, 1), P, Bm) / r[:, None, None]
                H = k * (a[:, :, None] * a[:, None, :] + g[:, None, None] * d2g)  # (m, 4, 4)
                rows = np.broadcast_to(dofs[:, :, None], H.shape)
                cols = np.broadcast_to(dofs[:, None, :], H.shape)
                hess.append((rows.ravel(), cols.ravel(), H.ravel()))
    if plane is not None and len(plane_nodes):
        g = plane.z - x[plane_nodes, 2]
        act = g > 0.0
        if act.any():
            nodes, g = plane_nodes[act], g[act]
            n_active += nodes.size
            energy += 0.5 * k * float(np.sum(g * g))
            pen_p = float(g.max())
            dofs = 3 * nodes + 2
            grad.append((dofs, -k * g))
            if tangent:
                hess.append((dofs, dofs, np.full(nodes.size, k)))
    return ContactState(energy, fz, pen_s, pen_p, grad, hess, n_active)
