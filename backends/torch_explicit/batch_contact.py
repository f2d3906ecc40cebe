"""Kinematic sphere contact for a batch of runs, with masks instead of node selection.

The algorithm of :mod:`.contact` (numba's kernels/contact.py: exact roots s_I of
|x_I + s d_I - c - dZ e_z| = R, the monotone scalar equation h(dZ) = 0 solved by safeguarded
Newton in [0, -h(0)], Coulomb stick / slip), on B runs at once: the sphere nodes of every run are
all kept (shape (B, s)), the nodes outside the lower half of the sphere weigh zero, and each run has
its own sphere (height Z, velocity V, mass M: (B,) tensors), its own bracket and its own step dt.
No ``nonzero``: the shapes never depend on the data, so that a step can run without host
synchronisation. The Newton iteration runs until every run has converged, with a host check every
``block`` iterations, or (``block = 0``) a fixed ``FIXED_ITERATIONS`` without any check, flagging
runs still unconverged (reported by the solver after the chunk). An iteration after convergence
changes nothing (the run is frozen), so the result does not depend on ``block``.
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from .contact import newton_block

FIXED_ITERATIONS = 24


class BatchSphere(NamedTuple):
    """Sphere-node data of B runs (device tensors); node k of run b at [b, k]."""

    nodes: torch.Tensor    # (B * s,) global node indices (run b's nodes offset by b n)
    X: torch.Tensor        # (3, B, s) reference coordinates (m)
    mass: torch.Tensor     # (B, s) nodal masses (kg)
    free: torch.Tensor     # (3, B, s) 1 on free dofs


class _Cand(NamedTuple):
    P: torch.Tensor        # (3, B, s) node - sphere centre (m)
    D: torch.Tensor        # (3, B, s) push direction (0 outside)
    qc: torch.Tensor       # (B, s) impulse per unit push (kg), 0 outside
    nz: torch.Tensor       # (B, s)
    coef: torch.Tensor     # (B, s) qc nz / M, 0 outside
    c0: torch.Tensor
    b0: torch.Tensor
    dd: torch.Tensor
    inside: torch.Tensor   # (B, s) bool: candidate


def _gather(u, sp: BatchSphere):
    B, s = sp.mass.shape
    return sp.X + u.index_select(1, sp.nodes).view(3, B, s)


def _candidates(xs, sp: BatchSphere, cx: float, cy: float, Z, R: float, M) -> _Cand:
    P = torch.stack([xs[0] - cx, xs[1] - cy, xs[2] - Z[:, None]])
    d2 = (P * P).sum(0)
    d = torch.sqrt(d2)
    un = P / d * sp.free
    w = torch.sqrt((un * un).sum(0))
    inside = (d2 < R * R) & (P[2] < 0.0) & ~(w < 1e-12)
    wsafe = torch.where(inside, w, 1.0)
    D = torch.where(inside, un / wsafe, 0.0)
    qc = torch.where(inside, sp.mass / wsafe, 0.0)
    nz = torch.where(inside, P[2] / d, 0.0)
    return _Cand(P, D, qc, nz, qc * nz / M[:, None], P[0] * P[0] + P[1] * P[1] - R * R,
                 P[0] * D[0] + P[1] * D[1], D[0] * D[0] + D[1] * D[1], inside)


def _root(c: _Cand, dz):
    """(s, ds/d dz) (B, s) for the sphere moved by dz (B,)."""
    qz = c.P[2] - dz[:, None]
    cq = torch.addcmul(c.c0, qz, qz)
    b = torch.addcmul(c.b0, qz, c.D[2])
    disc = torch.sqrt(torch.clamp(b * b - cq, min=0.0))
    s = torch.where(b > 0.0, -cq / (b + disc), disc - b)
    ez = torch.addcmul(qz, s, c.D[2])
    den = torch.addcmul(c.b0, s, c.dd).addcmul_(ez, c.D[2])
    ds = torch.where(den <= 0.0, 0.0, ez / den)  # same arithmetic as the single run's contact._root
    ok = (cq < 0.0) & c.inside
    return torch.where(ok, s, 0.0), torch.where(ok, ds, 0.0)


def _h(c: _Cand, dz):
    s, ds = _root(c, dz)
    return (c.coef * s).sum(1), (c.coef * ds).sum(1)


def _newton(c: _Cand, alive, tol: float, block: int):
    """dz (B,) solving h(dz) = 0 per run; (dz, host checks, unconverged (B,) bool)."""
    h0, dh0 = _h(c, torch.zeros_like(c.P[2, :, 0]))
    lo = torch.zeros_like(h0)
    hi = -h0
    active = (hi > 0.0) & alive
    dz = torch.where(active, -h0 / (1.0 + dh0), 0.0)
    checks = 0
    iterations = 0
    limit = 100 if block > 0 else FIXED_ITERATIONS
    while iterations < limit:
        if block > 0:
            checks += 1
            if not bool(active.any()):
                break
        count = min(block if block > 0 else limit, limit - iterations)
        dz, lo, hi, active = newton_block(lambda z: _h(c, z), dz, lo, hi, active, tol, count)
        iterations += count
    return dz, checks, active


def sphere_contact(u, v, dvc, sp: BatchSphere, cx: float, cy: float, Z, V, R: float, M, mu: float, dt,
                   alive, tol: float, block: int):
    """Close the gaps of B runs; u, v, dvc (3, B n) modified in place.

    Z, V, M, dt, alive: (B,) trial sphere height (m), velocity (m/s), mass (kg), step (s), live runs.
    Returns (dZ, dV, penetration (m), host checks, unconverged): (B,) tensors but the count.
    """
    B, s = sp.mass.shape
    c = _candidates(_gather(u, sp), sp, cx, cy, Z, R, M)
    dz, checks, unconverged = _newton(c, alive, tol, block)
    sr, _ = _root(c, dz)
    q = c.qc * sr
    moved = sr > 0.0
    dx = (torch.where(moved, sr, 0.0) * c.D)
    dvx = dx / dt[:, None]
    u.index_add_(1, sp.nodes, dx.reshape(3, -1))
    v.index_add_(1, sp.nodes, dvx.reshape(3, -1))
    dvc.index_add_(1, sp.nodes, dvx.reshape(3, -1))
    dZ = -torch.where(moved, q * c.nz, 0.0).sum(1) / M
    dV = dZ / dt
    if mu > 0.0:
        dZ, dV = _friction(u, v, dvc, sp, c, q, cx, cy, Z, V, dZ, dV, M, mu, dt)
    xs = _gather(u, sp)
    pz = xs[2] - (Z + dZ)[:, None]
    gap = R - torch.sqrt((xs[0] - cx) ** 2 + (xs[1] - cy) ** 2 + pz * pz)
    pen = torch.where(pz < 0.0, gap, 0.0).amax(1).clamp_min(0.0)
    return dZ, dV, pen, checks, unconverged


def coulomb(u, v, dvc, sp, inside, q, rel, n, mu, dt):
    """Coulomb stick / slip of the touching nodes (the one formula of the batch contacts).

    The tangential part t of each node's velocity relative to the impactor ``rel`` (3, B, s)
    (m/s), with the components of fixed dofs removed, is removed (stick) when that takes an impulse
    of at most mu times the normal impulse ``q`` (B, s) (kg m), else reduced by it (slip); ``n``
    (3, B, s) is the impactor's outward normal, ``inside`` (B, s) the candidates. Corrects v, u
    (by dv dt) and dvc in place; returns the velocity change removed, dvt (3, B, s) (m/s).
    """
    rn = (rel * n).sum(0)
    t = (rel - rn * n) * sp.free
    tn = torch.sqrt((t * t).sum(0))
    ok = inside & (q > 0.0) & (tn != 0.0)
    fac = torch.clamp(mu * (q / dt[:, None]) / (sp.mass * torch.where(ok, tn, 1.0)), max=1.0)
    dvt = torch.where(ok, fac * t, 0.0)
    v.index_add_(1, sp.nodes, -dvt.reshape(3, -1))
    u.index_add_(1, sp.nodes, (-dvt * dt[:, None]).reshape(3, -1))
    dvc.index_add_(1, sp.nodes, -dvt.reshape(3, -1))
    return dvt


def _friction(u, v, dvc, sp, c: _Cand, q, cx, cy, Z, V, dZ, dV, M, mu, dt):
    """Coulomb stick / slip of the touching nodes relative to each run's sphere; (dZ, dV) (B,)."""
    B, s = sp.mass.shape
    xs = _gather(u, sp)
    vs = v.index_select(1, sp.nodes).view(3, B, s)
    P = torch.stack([xs[0] - cx, xs[1] - cy, xs[2] - (Z + dZ)[:, None]])
    n = P / torch.sqrt((P * P).sum(0))
    r = torch.stack([vs[0], vs[1], vs[2] - (V + dV)[:, None]])
    dvt = coulomb(u, v, dvc, sp, c.inside, q, r, n, mu, dt)
    mz = (sp.mass * dvt[2]).sum(1)
    return dZ + mz * dt / M, dV + mz / M
