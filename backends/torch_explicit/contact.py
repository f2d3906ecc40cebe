"""Kinematic (momentum-exchange) contact with a rigid sphere and a rigid plane, vectorised over nodes.

The numba backend's algorithm (kernels/contact.py; see its docstring for the derivation): after
the trial update, every penetrating node is moved back onto the rigid surface and its velocity
corrected by dx / dt. For the sphere (moving along z), node I is pushed along its outward normal
with the fixed dofs removed, d_I, by the exact root s_I of |x_I + s d_I - c - dZ e_z| = R, with
normal impulse q_I = m_I s_I / |P n_I|; the sphere's move dZ solves the monotone scalar equation
h(dZ) = dZ + sum_I q_I(dZ) n_Iz / M = 0, by the same safeguarded Newton iteration in the bracket
[0, -h(0)] and the same stopping rule. Here the sums run over all candidate nodes at once; the
iteration count is a host decision, checked every ``block`` iterations (an iteration after
convergence changes nothing, so the result does not depend on ``block``).

Friction (Coulomb): stick or slip per contacting node as in numba, except that every node sees the
sphere velocity after the normal correction (numba updates it node by node; the difference is of
the order of node mass / impactor mass, about 1e-5 relative, on the friction part only).

Positions are X + u (reference plus displacement); u, v, dvc (3, n) are modified in place.
"""

from __future__ import annotations

from typing import NamedTuple

import torch


class SphereNodes(NamedTuple):
    """Fixed data of the nodes that may touch the sphere (device tensors)."""

    nodes: torch.Tensor    # (s,) node indices
    X: torch.Tensor        # (3, s) reference coordinates (m)
    mass: torch.Tensor     # (s,) nodal masses (kg)
    free: torch.Tensor     # (3, s) 1 on free dofs, 0 on fixed ones


class PlaneNodes(NamedTuple):
    nodes: torch.Tensor    # (p,)
    Xz: torch.Tensor       # (p,) reference z (m)
    free: torch.Tensor     # (3, p)


class _Candidates(NamedTuple):
    """Nodes inside the lower half of the sphere, with the per-node constants of the root equation."""

    nodes: torch.Tensor    # (c,) positions in SphereNodes (not node numbers)
    P: torch.Tensor        # (3, c) node position - sphere centre (m)
    D: torch.Tensor        # (3, c) push direction (unit, fixed dofs removed)
    qc: torch.Tensor       # (c,) normal impulse per unit push, m / |P n| (kg)
    nz: torch.Tensor       # (c,) z component of the outward normal
    coef: torch.Tensor     # (c,) qc nz / M
    c0: torch.Tensor       # (c,) Px^2 + Py^2 - R^2 (m^2)
    b0: torch.Tensor       # (c,) Px Dx + Py Dy (m)
    dd: torch.Tensor       # (c,) Dx^2 + Dy^2


def _candidates(xs, sn: SphereNodes, cx: float, cy: float, Z: float, R: float, M: float):
    P = xs - torch.tensor([[cx], [cy], [Z]], dtype=xs.dtype).to(xs.device, non_blocking=True)
    d2 = (P * P).sum(0)
    d = torch.sqrt(d2)
    un = P / d * sn.free
    w = torch.sqrt((un * un).sum(0))
    cand = torch.nonzero((d2 < R * R) & (P[2] < 0.0) & ~(w < 1e-12)).reshape(-1)   # host sync
    if cand.numel() == 0:
        return None
    P, d, w = P.index_select(1, cand), d.index_select(0, cand), w.index_select(0, cand)
    D = un.index_select(1, cand) / w
    qc = sn.mass.index_select(0, cand) / w
    nz = P[2] / d
    Pxy, Dxy = P[0:2], D[0:2]
    return _Candidates(cand, P, D, qc, nz, qc * nz / M, (Pxy * Pxy).sum(0) - R * R, (Pxy * Dxy).sum(0),
                       (Dxy * Dxy).sum(0))


def _root(c: _Candidates, dz):
    """(2, c): s and ds/d dz per candidate, s >= 0 with |P - dz e_z + s D| = R (0 where outside)."""
    qz = c.P[2] - dz
    cq = torch.addcmul(c.c0, qz, qz)
    b = torch.addcmul(c.b0, qz, c.D[2])
    disc = torch.sqrt(b * b - cq)
    s = torch.where(b > 0.0, -cq / (b + disc), disc - b)
    ez = torch.addcmul(qz, s, c.D[2])
    den = torch.addcmul(c.b0, s, c.dd).addcmul_(ez, c.D[2])
    ds = torch.where(den <= 0.0, 0.0, ez / den)
    return torch.where(cq < 0.0, torch.stack([s, ds]), 0.0)


def _h(c: _Candidates, dz):
    """(h(dz) - dz, h'(dz) - 1) = (sum coef s, sum coef ds) as a (2,) tensor."""
    return (_root(c, dz) * c.coef).sum(1)


def _newton_host(c: _Candidates, tol: float):
    """Safeguarded Newton for h(dz) = 0 in [0, -h(0)] with host scalars (one sync per iteration)."""
    h0, dh0 = _h(c, 0.0).tolist()
    checks = 1
    lo, hi, dz = 0.0, -h0, 0.0
    if hi > 0.0:
        dz = -h0 / (1.0 + dh0)
        for _it in range(100):
            sh, sdh = _h(c, dz).tolist()
            checks += 1
            h, dh = dz + sh, 1.0 + sdh
            if h < 0.0:
                lo = dz
            else:
                hi = dz
            if abs(h) <= tol * abs(dz) or hi - lo <= 4.0 * tol * hi:
                break
            nxt = dz - h / dh
            if not (nxt > lo and nxt < hi):
                nxt = 0.5 * (lo + hi)
            dz = nxt
    return dz, checks


def newton_block(h, dz, lo, hi, active, tol: float, count: int):
    """``count`` safeguarded Newton steps on the device for the sphere gap equation dz + h(dz) = 0.

    Parameters
    ----------
    h : callable
        ``h(dz) -> (sh, sdh)``: the contact sum and its derivative at dz (tensors like dz).
    dz, lo, hi : Tensor
        Iterate and bracket (m), one entry per run (a scalar for a single run).
    active : Tensor of bool
        Runs still iterating; converged ones keep their dz.
    tol : float
        Relative tolerance on the residual and the bracket (-).
    count : int
        Number of steps (no host synchronisation inside).

    Returns
    -------
    tuple of Tensor
        (dz, lo, hi, active) after the steps; a Newton step outside the bracket is replaced by bisection.
    """
    for _ in range(count):
        sh, sdh = h(dz)
        res, dres = dz + sh, 1.0 + sdh
        neg = res < 0.0
        lo = torch.where(active & neg, dz, lo)
        hi = torch.where(active & ~neg, dz, hi)
        done = (res.abs() <= tol * dz.abs()) | (hi - lo <= 4.0 * tol * hi)
        nxt = dz - res / dres
        nxt = torch.where((nxt > lo) & (nxt < hi), nxt, 0.5 * (lo + hi))
        active = active & ~done
        dz = torch.where(active, nxt, dz)
    return dz, lo, hi, active


def _newton_device(c: _Candidates, tol: float, block: int):
    """The same iteration on the device; the host checks convergence every ``block`` iterations."""
    h0, dh0 = _h(c, 0.0).unbind()
    dh0 = 1.0 + dh0
    lo = torch.zeros_like(h0)
    hi = -h0
    active = hi > 0.0
    dz = torch.where(active, -h0 / dh0, 0.0)
    checks = 1
    iterations = 0
    if bool(active):
        while iterations < 100:
            count = min(block, 100 - iterations)
            dz, lo, hi, active = newton_block(lambda z: _h(c, z).unbind(), dz, lo, hi, active, tol, count)
            iterations += count
            checks += 1
            if not bool(active):
                break
    return dz, checks


def sphere_contact(u, v, dvc, sn: SphereNodes, cx: float, cy: float, Z: float, V: float, R: float,
                   M: float, mu: float, dt: float, block: int, tol: float = 1e-16):
    """Close the gaps between the nodes ``sn`` and the sphere (centre (cx, cy, Z), radius R).

    u, v: trial displacements and velocities (3, n), modified in place with dvc (velocity
    corrections); Z, V: trial sphere position and velocity (host floats); M (kg); dt (s); block:
    1 for host scalars in the Newton iteration (one sync per iteration), k > 1 for device scalars
    and a host check every k iterations (the results are the same); tol: relative convergence
    threshold (1e-16 in float64, scaled with the dtype's epsilon). Returns (dZ, dV, penetration
    (m)) as 0-d tensors or None (no node inside the sphere), and the number of host syncs.
    """
    xs = sn.X + u.index_select(1, sn.nodes)
    c = _candidates(xs, sn, cx, cy, Z, R, M)
    if c is None:
        return None, 1
    dz, checks = _newton_host(c, tol) if block == 1 else _newton_device(c, tol, block)
    checks += 1
    # apply: nodes land on the sphere moved by dz; the sphere moves by -sum q n_z / M
    s = _root(c, dz)[0]
    q = c.qc * s
    moved = s > 0.0
    dx = torch.where(moved, s, 0.0) * c.D
    nodes = sn.nodes.index_select(0, c.nodes)
    u.index_add_(1, nodes, dx)
    dvx = dx / dt
    v.index_add_(1, nodes, dvx)
    dvc.index_add_(1, nodes, dvx)
    dZ = -torch.where(moved, q * c.nz, 0.0).sum() / M
    dV = dZ / dt
    if mu > 0.0:
        dZ, dV = _sphere_friction(u, v, dvc, sn, c, q, cx, cy, Z, V, dZ, dV, M, mu, dt)
    # largest remaining penetration (m), for the record
    xs = sn.X + u.index_select(1, sn.nodes)
    pz = xs[2] - (Z + dZ)
    gap = R - torch.sqrt((xs[0] - cx) ** 2 + (xs[1] - cy) ** 2 + pz * pz)
    pen = torch.where(pz < 0.0, gap, 0.0).amax().clamp_min(0.0)
    return (dZ, dV, pen), checks


def _sphere_friction(u, v, dvc, sn, c: _Candidates, q, cx, cy, Z, V, dZ, dV, M, mu, dt):
    """Coulomb stick / slip of the touching candidates relative to the sphere; returns (dZ, dV)."""
    nodes = sn.nodes.index_select(0, c.nodes)
    xs = sn.X.index_select(1, c.nodes) + u.index_select(1, nodes)
    vs = v.index_select(1, nodes)
    P = torch.stack([xs[0] - cx, xs[1] - cy, xs[2] - (Z + dZ)])
    n = P / torch.sqrt((P * P).sum(0))
    r = torch.stack([vs[0], vs[1], vs[2] - (V + dV)])
    rn = (r * n).sum(0)
    t = (r - rn * n) * sn.free.index_select(1, c.nodes)
    tn = torch.sqrt((t * t).sum(0))
    ok = (q > 0.0) & (tn != 0.0)
    m = sn.mass.index_select(0, c.nodes)
    fac = torch.clamp(mu * (q / dt) / (m * tn), max=1.0)
    dvt = torch.where(ok, fac * t, 0.0)
    v.index_add_(1, nodes, -dvt)
    u.index_add_(1, nodes, -dvt * dt)
    dvc.index_add_(1, nodes, -dvt)
    mz = (m * dvt[2]).sum()
    return dZ + mz * dt / M, dV + mz / M


def plane_contact(u, v, dvc, pn: PlaneNodes, z0: float, mu: float, dt: float) -> None:
    """Nodes below the plane z = z0 are put back onto it; dv_z = dz / dt; optional friction."""
    uz = u[2].index_select(0, pn.nodes)
    z = pn.Xz + uz
    below = (pn.free[2] != 0.0) & (z < z0)
    dz = torch.where(below, z0 - z, 0.0)
    u[2].index_copy_(0, pn.nodes, torch.where(below, z0 - pn.Xz, uz))
    dvz = dz / dt
    v[2].index_add_(0, pn.nodes, dvz)
    dvc[2].index_add_(0, pn.nodes, dvz)
    if mu > 0.0:
        vt = v[0:2].index_select(1, pn.nodes) * pn.free[0:2]
        tn = torch.sqrt((vt * vt).sum(0))
        ok = below & (tn > 0.0)
        fac = torch.where(ok, torch.clamp(mu * dvz / tn, max=1.0), 0.0)
        dvt = torch.where(ok, fac * vt, 0.0)
        v[0:2].index_add_(1, pn.nodes, -dvt)
        u[0:2].index_add_(1, pn.nodes, -dvt * dt)
        dvc[0:2].index_add_(1, pn.nodes, -dvt)
