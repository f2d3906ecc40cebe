"""Contact with a rigid impactor of any shape moving in any of x, y, z (augmented Lagrangian).

The impactor translates without rotating; its unknowns are the displacements W_j (m) of its
reference point along its free axes (``RigidSphere.moves``), the last dofs of the system. Its
surface is the project's reference formula :func:`cfm_core.scene.impactor.impactor_gap`: the
signed gap g(x - c) (m, > 0 outside) of a point x to the impactor at reference point c = c0 + W,
and the impactor's outward normal n = dg/dx there. Per candidate node, with the penetration
pen = -g, the multiplier lambda and the augmentation stiffness k (N/m), as for the hemisphere
(:mod:`.contact`):

    p = max(0, lambda + k pen)                                   (N)
    f = p d pen/dy,      d pen/dy = a = (-n, +n_j)               (y = (x_node, W))
    K = dp/d pen a a^T + p d2pen,   d2pen = -B^T H_g B,  B = [I, -E]

with E (3, m) the unit columns of the free axes and H_g = d2g/dx2 the Hessian of the gap
(1/m), per shape (rho the distance from the axis, e_r, e_phi the radial and azimuthal unit
vectors, s the distance to the rim circle of a flat impactor):

* sphere, hemisphere: H_g = (I - n n^T) / |x - c|;
* plane, and the flat face of "flat": H_g = 0;
* cylindrical side of "flat": H_g = e_phi e_phi^T / rho;
* rounded rim of "flat" (distance s to the circle of radius R - r at height c_z + r):
  H_g = (e_r e_r^T + e_z e_z^T - n n^T) / s + (n . e_r / rho) e_phi e_phi^T.

On a symmetry plane (x = c_x or y = c_y when the impactor is held along that axis, the node's
dof along it fixed) a node belongs half to the modelled part (a quarter on the axis):
its contribution, plate included, is scaled by that share (:func:`symmetry_share`), so that the
quarter or half model is the exact restriction of the full one (a node's multiplier stays the
force on the whole node). This is the exact generalised Hessian (tests compare it with finite differences of the force).
The force on the impactor is -sum p n (N, modelled part); its z component is the contact force
of the Result (+ decelerating a downward-moving impactor). Frictionless (the solver rejects a
friction coefficient).
"""

from __future__ import annotations

import numpy as np

from cfm_core.errors import InputError
from cfm_core.scene.impactor import impactor_gap
from cfm_core.scene.model import IMPACTOR_SHAPES

from .contact import ContactState, plane_contact


def check(imp, model_name: str) -> list[str]:
    """InputError for an impactor the backend cannot run; returns warnings (text) for one it runs.

    Checks the shape, radius (m) > 0 (unused for "plane"), 0 <= edge_radius (m) < radius for
    "flat", mass (kg) > 0, that z is free and that no velocity component (m/s) is given along a
    held axis. A flat impactor with a sharp rim (edge_radius = 0) runs with a warning.
    """
    where = f"model '{model_name}': impactor"
    if imp.shape not in IMPACTOR_SHAPES:
        raise InputError(f"{where} shape = {imp.shape!r}; allowed: {', '.join(IMPACTOR_SHAPES)}.")
    if not (float(imp.mass) > 0.0 and np.isfinite(float(imp.mass))):
        raise InputError(f"{where} mass = {imp.mass!r} kg must be finite and > 0.")
    if imp.shape != "plane" and not (float(imp.radius) > 0.0 and np.isfinite(float(imp.radius))):
        raise InputError(f"{where} radius = {imp.radius!r} m must be finite and > 0 for shape '{imp.shape}'.")
    if imp.shape == "flat" and not (0.0 <= float(imp.edge_radius) < float(imp.radius)):
        raise InputError(f"{where} edge_radius = {imp.edge_radius!r} m must be in [0, radius = {imp.radius!r} m) "
                         f"for shape 'flat'.")
    moves = tuple(bool(m) for m in imp.moves)
    if len(moves) != 3 or not moves[2]:
        raise InputError(f"{where} moves = {imp.moves!r}: the skfem backend needs the impactor free along z "
                         f"(moves[2] = True); x and y may be free or held.")
    v = imp.velocity_vector
    for j, name in ((0, "x"), (1, "y")):
        if not moves[j] and v[j] != 0.0:
            raise InputError(f"{where} velocity along {name} = {v[j]!r} m/s but moves[{j}] = False (a symmetry "
                             f"plane holds it): use symmetry 'half' or 'none', or a zero {name} velocity.")
    if imp.shape == "flat" and float(imp.edge_radius) == 0.0:
        return [f"skfem backend: the flat impactor of model '{model_name}' has a sharp rim (edge_radius = 0 m): "
                f"the stress under the rim is singular, so stresses there grow without bound as the mesh is "
                f"refined (the contact force converges); give edge_radius > 0 m for stresses at the rim."]
    return []


def symmetry_share(model, nodes: np.ndarray) -> np.ndarray:
    """Fraction (-) of each of ``nodes`` (k,) in the modelled part: x 1/2 per symmetry plane it lies on.

    A symmetry plane is x = c_x (y = c_y) of the impactor's reference point c when the impactor is
    held along x (y); a node lies on it when its coordinate is within 1e-9 of the mesh extent and
    its dof along that axis is fixed.
    """
    nodes = np.asarray(nodes, dtype=np.int64)
    share = np.ones(nodes.size)
    imp = model.sphere
    if imp is None or nodes.size == 0:
        return share
    X = np.asarray(model.nodes, dtype=np.float64)
    tol = 1e-9 * float(np.ptp(X, axis=0).max())
    fixed = np.zeros((X.shape[0], 3), dtype=bool)
    f = np.asarray(model.fixed_dofs, dtype=np.int64).reshape(-1, 2)
    fixed[f[:, 0], f[:, 1]] = True
    for j in (0, 1):
        if not imp.moves[j]:
            on = (np.abs(X[nodes, j] - float(imp.center[j])) <= tol) & fixed[nodes, j]
            share[on] *= 0.5
    return share


def gap_hessian(imp, p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """H_g (k, 3, 3) (1/m): the Hessian of the gap at points p = x - c (k, 3) (m) with normals n (k, 3)."""
    k = p.shape[0]
    H = np.zeros((k, 3, 3))
    if imp.shape in ("sphere", "hemisphere"):
        d = np.sqrt(np.einsum("ki,ki->k", p, p))
        H = (np.eye(3)[None] - n[:, :, None] * n[:, None, :]) / d[:, None, None]
    elif imp.shape == "flat":
        r = float(imp.edge_radius)
        a = float(imp.radius) - r
        rho = np.hypot(p[:, 0], p[:, 1])
        safe = np.where(rho > 0.0, rho, 1.0)
        er = np.zeros((k, 3))
        er[:, 0] = np.where(rho > 0.0, p[:, 0] / safe, 1.0)
        er[:, 1] = np.where(rho > 0.0, p[:, 1] / safe, 0.0)
        ephi = np.stack([-er[:, 1], er[:, 0], np.zeros(k)], axis=1)
        q1, q2 = rho - a, r - p[:, 2]
        corner = (q1 > 0.0) & (q2 > 0.0)
        side = ~corner & (q1 > q2)
        pp = ephi[:, :, None] * ephi[:, None, :]
        H[side] = pp[side] / safe[side, None, None]
        if corner.any():
            s = np.hypot(q1[corner], q2[corner])
            ez = np.zeros((int(corner.sum()), 3))
            ez[:, 2] = 1.0
            e, nc = er[corner], n[corner]
            plane = e[:, :, None] * e[:, None, :] + ez[:, :, None] * ez[:, None, :] - nc[:, :, None] * nc[:, None, :]
            ring = np.einsum("ki,ki->k", nc, e) / safe[corner]
            H[corner] = plane / s[:, None, None] + ring[:, None, None] * pp[corner]
    return H


def evaluate(x: np.ndarray, W: np.ndarray, imp, imp_nodes: np.ndarray, plane, plane_nodes: np.ndarray,
             k: float, imp_dofs: np.ndarray, axes: np.ndarray, lam_imp: np.ndarray, lam_plane: np.ndarray,
             tangent: bool = True, share_imp: np.ndarray | None = None,
             share_plane: np.ndarray | None = None) -> ContactState:
    """Contact contributions at current positions x (n, 3) (m) and impactor displacement W (3,) (m).

    imp_dofs (m,): the system dofs of the impactor's free axes ``axes`` (m,) (0, 1, 2 for x, y, z);
    k: augmentation stiffness (N/m per node); lam_imp (ni,), lam_plane (np,): multipliers (N) of the
    candidate nodes ``imp_nodes`` / ``plane_nodes``; share_imp, share_plane: their
    :func:`symmetry_share` (None: 1). The plate is :func:`.contact.plane_contact`.
    """
    grad, hess = [], []
    force = np.zeros(3)
    pen_i, n_active = 0.0, 0
    p_i = np.zeros(len(imp_nodes))
    if imp is not None and len(imp_nodes):
        c = np.asarray(imp.center, dtype=np.float64) + W
        xs = x[imp_nodes]
        g, n = impactor_gap(imp, c, xs)
        pen = -g
        pen_i = max(0.0, float(pen.max()))
        with np.errstate(invalid="ignore"):
            trial = lam_imp + k * pen  # -inf where the shape cannot touch (above a hemisphere)
        act = trial > 0.0
        if act.any():
            p_i[act] = trial[act]
            nodes, p, n, rel = imp_nodes[act], trial[act], n[act], xs[act] - c
            if share_imp is not None:
                p = p * share_imp[act]  # the modelled part of each node's force
            m = nodes.size
            na = axes.size
            n_active += m
            a = np.concatenate([-n, n[:, axes]], axis=1)  # d pen / d(x_node, W), (m, 3 + na)
            dofs = np.concatenate([3 * nodes[:, None] + np.arange(3)[None, :],
                                   np.broadcast_to(imp_dofs[None, :], (m, na))], axis=1)
            grad.append((dofs.ravel(), (p[:, None] * a).ravel()))
            force = -np.einsum("m,mi->i", p, n)
            if tangent:
                Bm = np.zeros((3, 3 + na))
                Bm[:, :3] = np.eye(3)
                Bm[axes, 3 + np.arange(na)] = -1.0
                d2pen = -np.einsum("ji,mjk,kl->mil", Bm, gap_hessian(imp, rel, n), Bm)
                kw = k if share_imp is None else k * share_imp[act][:, None, None]
                H = kw * a[:, :, None] * a[:, None, :] + p[:, None, None] * d2pen
                rows = np.broadcast_to(dofs[:, :, None], H.shape)
                cols = np.broadcast_to(dofs[:, None, :], H.shape)
                hess.append((rows.ravel(), cols.ravel(), H.ravel()))
    p_p, pen_p, n_plane = plane_contact(x, plane, plane_nodes, k, lam_plane, tangent, grad, hess, share_plane)
    return ContactState(p_i, p_p, float(force[2]), pen_i, pen_p, grad, hess, n_active + n_plane,
                        force_vector=force)
