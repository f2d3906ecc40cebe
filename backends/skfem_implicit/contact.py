"""Frictionless node-to-rigid-surface contact: augmented Lagrangian, semi-smooth Newton (project code).

Penetrations (m, positive when inside): sphere g = R - |d|, d = x - c(w), c(w) = c0 + w e_z (w the
impactor's z displacement, its only dof); plane g = z_p - x_z. Each candidate node carries a
multiplier lambda (N, its contact force at the last converged step). Within a step lambda is fixed
and the nodal contact force is

    p = max(0, lambda + k g)                                     (N)

with k (N/m) the augmentation (penalty) stiffness. Newton sees the generalised derivative of
this semi-smooth law (dp/dg = k on active nodes, 0 otherwise), so once the active set settles it
converges quadratically; after each converged step lambda <- p (one augmentation per step,
"Uzawa per step"), so the penetration that remains is the change of the force over one step
divided by k, not the force divided by k: the force, and the peak, no longer depend on k (test
``test_skfem_contact``). ``contact="penalty"`` keeps lambda = 0 (the plain penalty law).

With y = (x, w) and d = B y - c0, B = [I, -e_z] (n = d / |d|):

    f = p dg/dy,                  dg/dy = -B^T n
    K = dp/dg dg dg^T + p d2g,    d2g   = -B^T (I - n n^T) B / |d|

the exact (generalised) Hessian, symmetric. The force on the impactor (N, +z, modelled part) is
-f_w = -sum p n_z, positive when the specimen decelerates a downward-moving impactor.
Frictionless: a friction coefficient other than 0 is rejected by the solver.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ContactState:
    """Contributions of the candidate nodes (modelled part).

    p_sphere (ns,), p_plane (np,): nodal contact forces (N) of the sphere and plane candidates, in
    the order of the candidate lists (the new multipliers once the step is accepted);
    force_on_impactor (N, +z); max_pen_sphere / max_pen_plane (m, largest penetration);
    grad: list of (dofs (m,), values (m,)) (N); hess: list of (rows, cols, values) COO triplets (N/m);
    n_active: active nodes; force_vector (3,): the force on the impactor (N, modelled part), set
    by the contact of any shape (:mod:`.impactor`), None for the hemisphere along z (z only).
    """

    p_sphere: np.ndarray
    p_plane: np.ndarray
    force_on_impactor: float
    max_pen_sphere: float
    max_pen_plane: float
    grad: list
    hess: list
    n_active: int
    force_vector: np.ndarray | None = None


def evaluate(x: np.ndarray, w: float, sphere, sphere_nodes: np.ndarray, plane, plane_nodes: np.ndarray,
             k: float, w_dof: int, lam_sphere: np.ndarray, lam_plane: np.ndarray,
             tangent: bool = True) -> ContactState:
    """Contact contributions at current positions x (n, 3) (m) and impactor displacement w (m).

    k: augmentation stiffness (N/m per node); lam_sphere (ns,), lam_plane (np,): multipliers (N) of
    the candidate nodes ``sphere_nodes`` / ``plane_nodes``.
    """
    fz, pen_s, n_active = 0.0, 0.0, 0
    grad, hess = [], []
    p_s = np.zeros(len(sphere_nodes))
    if sphere is not None and len(sphere_nodes):
        c = np.array(sphere.center, dtype=np.float64)
        c[2] += w
        d = x[sphere_nodes] - c
        r = np.sqrt(np.einsum("ni,ni->n", d, d))
        g = sphere.radius - r
        pen_s = max(0.0, float(g.max()))
        trial = lam_sphere + k * g
        act = trial > 0.0
        if act.any():
            p_s[act] = trial[act]
            nodes, r, d, p = sphere_nodes[act], r[act], d[act], trial[act]
            n = d / r[:, None]
            m = nodes.size
            n_active += m
            a = np.concatenate([-n, n[:, 2:3]], axis=1)  # dg/d(x_node, w), (m, 4)
            dofs = np.concatenate([3 * nodes[:, None] + np.arange(3)[None, :],
                                   np.full((m, 1), w_dof)], axis=1)  # (m, 4)
            grad.append((dofs.ravel(), (p[:, None] * a).ravel()))
            fz = -float(np.sum(p * n[:, 2]))
            if tangent:
                P = np.eye(3)[None] - n[:, :, None] * n[:, None, :]  # (m, 3, 3)
                Bm = np.zeros((m, 3, 4))
                Bm[:, :, :3] = np.eye(3)
                Bm[:, 2, 3] = -1.0
                d2g = -np.einsum("mji,mjk,mkl->mil", Bm, P, Bm) / r[:, None, None]
                H = k * a[:, :, None] * a[:, None, :] + p[:, None, None] * d2g  # (m, 4, 4)
                rows = np.broadcast_to(dofs[:, :, None], H.shape)
                cols = np.broadcast_to(dofs[:, None, :], H.shape)
                hess.append((rows.ravel(), cols.ravel(), H.ravel()))
    p_p, pen_p, n_plane = plane_contact(x, plane, plane_nodes, k, lam_plane, tangent, grad, hess)
    n_active += n_plane
    return ContactState(p_s, p_p, fz, pen_s, pen_p, grad, hess, n_active)


def plane_contact(x: np.ndarray, plane, plane_nodes: np.ndarray, k: float, lam_plane: np.ndarray,
                  tangent: bool, grad: list, hess: list, share: np.ndarray | None = None
                  ) -> tuple[np.ndarray, float, int]:
    """The rigid plate's contribution: penetration g = z_p - x_z (m) of the candidates ``plane_nodes``.

    Appends the gradient (N) and Hessian (N/m) entries to ``grad`` / ``hess``; returns the nodal
    forces (np,) (N, per whole node: the multipliers), the largest penetration (m) and the number
    of active nodes. ``share`` (np,): the fraction of each node in the modelled part (1/2 on a
    symmetry plane, see :func:`.impactor.symmetry_share`), which scales its contribution; None: 1.
    """
    p_p = np.zeros(len(plane_nodes))
    pen_p, n_active = 0.0, 0
    if plane is not None and len(plane_nodes):
        g = plane.z - x[plane_nodes, 2]
        pen_p = max(0.0, float(g.max()))
        trial = lam_plane + k * g
        act = trial > 0.0
        if act.any():
            p_p[act] = trial[act]
            nodes = plane_nodes[act]
            n_active += nodes.size
            dofs = 3 * nodes + 2
            if share is None:
                grad.append((dofs, -trial[act]))
                if tangent:
                    hess.append((dofs, dofs, np.full(nodes.size, k)))
            else:
                grad.append((dofs, -share[act] * trial[act]))
                if tangent:
                    hess.append((dofs, dofs, k * share[act]))
    return p_p, pen_p, n_active
