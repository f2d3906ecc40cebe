"""Kinematic contact with a rigid impactor of any shape that may move in x, y and z (B runs).

The hemisphere contact's method (:mod:`.contact`, numba's kernels/contact.py) for every shape of
:mod:`.impactor` and for an impactor with several free translations (``RigidSphere.moves``):

- a node I inside the impactor (trial positions, g_I < 0) is pushed along its push direction
  D_I, the impactor's outward normal n_I at the nearest surface point with the node's fixed
  dofs removed, normalised (w_I = |free_I n_I|); normal impulse q_I = m_I s_I / w_I;
- the impactor's move d (3,) over its free directions f solves the momentum balance
  r(d) = d + sum_I q_I(d) (f n_I) / M = 0, where s_I(d) >= 0 is the exact push that lands node I
  on the impactor moved by d (:func:`.impactor.land`; 0 for a node the moved impactor no longer
  reaches). Newton's method with the Jacobian I + sum_I (m_I / w_I / M) (f n_I) (x) (f ds_I/dd),
  a 3x3 solve by Cramer's rule per run (no host synchronisation), from d = 0 (its first step is the
  linearised estimate). The residual is piecewise smooth and nearly linear over one step (the push
  is a few micrometres, the radius millimetres), so Newton converges in a few iterations;
- nodes land exactly on the moved surface (gap closed to round-off), the impactor takes
  -sum q_I f n_I / M: momentum is conserved along every free direction of the impactor;
- Coulomb friction per contacting node as for the hemisphere, relative to the impactor's full
  velocity, its reaction on all free directions of the impactor.

The iteration runs until every run has converged, with a host check every ``block`` iterations,
or (``block = 0``) ``ITERATIONS`` iterations without a check, flagging runs still unconverged.
Layout as :mod:`.batch_contact`: node k of run b at [b, k]; u, v, dvc (3, B n).
"""

from __future__ import annotations

import torch

from .batch_contact import BatchSphere, _gather, coulomb
from .impactor import gap, land

ITERATIONS = 16        # Newton iterations of the sync-free step
LIMIT = 100            # with host checks
STALL = 1e-9           # relative residual below which a stalled Newton iteration counts as converged


def _solve3(J, r):
    """x (3, B) with J x = r per run; J (3, 3, B), r (3, B) (Cramer's rule, elementwise ops)."""
    def det(a):
        return (a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
                + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]))

    rows = [[J[i, j] for j in range(3)] for i in range(3)]
    dj = det(rows)
    out = []
    for c in range(3):
        m = [[r[i] if j == c else rows[i][j] for j in range(3)] for i in range(3)]
        out.append(det(m) / dj)
    return torch.stack(out)


class _Cand:
    """Candidates of B runs at the trial positions (all sphere nodes, masked)."""

    def __init__(self, xs, sp: BatchSphere, shape, R, r, C, M, fmask):
        self.shape, self.R, self.r = shape, R, r
        self.P = xs - C[:, :, None]
        g, n = gap(shape, R, r, self.P)
        un = n * sp.free
        w = torch.sqrt((un * un).sum(0))
        self.inside = (g < 0.0) & ~(w < 1e-12)
        ws = torch.where(self.inside, w, 1.0)
        self.D = torch.where(self.inside, un / ws, 0.0)
        self.qc = torch.where(self.inside, sp.mass / ws, 0.0)
        self.nf = torch.where(self.inside, n, 0.0) * fmask[:, :, None]     # n on the impactor's free axes
        self.coef = self.qc * self.nf / M[None, :, None]
        self.fmask = fmask

    def push(self, d):
        """(s (B, s), ds/dd (3, B, s) on the free axes) for the impactor moved by d (3, B)."""
        s, ds = land(self.shape, self.R, self.r, self.P - d[:, :, None], self.D)
        return torch.where(self.inside, s, 0.0), torch.where(self.inside, ds, 0.0) * self.fmask[:, :, None]

    def residual(self, d):
        """(r (3, B), Jacobian (3, 3, B)) of the momentum balance at d."""
        s, ds = self.push(d)
        res = d + (self.coef * s).sum(2)
        J = torch.einsum("ibk,jbk->ijb", self.coef, ds)
        J = J + torch.eye(3, dtype=J.dtype, device=J.device)[:, :, None]
        return res, J


def _newton(c: _Cand, alive, tol: float, block: int):
    """d (3, B) solving r(d) = 0 per run; (d, host checks, unconverged (B,) bool)."""
    B = alive.shape[0]
    d = torch.zeros((3, B), dtype=c.P.dtype, device=c.P.device)
    active = alive & c.inside.any(1)
    checks = 0
    iterations = 0
    limit = LIMIT if block > 0 else ITERATIONS
    prev = torch.full((B,), torch.inf, dtype=d.dtype, device=d.device)
    while iterations < limit:
        if block > 0 and iterations % block == 0:
            checks += 1
            if not bool(active.any()):
                break
        res, J = c.residual(d)
        scale = d.abs().amax(0)
        rn = res.abs().amax(0)
        # converged: residual at the tolerance, or at its round-off floor (Newton stopped gaining; the
        # sums carry round-off of the coordinates, ~1e-13 of a micrometre move), close to the root
        done = (rn <= 16.0 * tol * scale) | ((rn >= 0.5 * prev) & (rn <= STALL * scale))
        prev = rn
        step = _solve3(J, res)
        active = active & ~done
        d = torch.where(active, d - step, d)
        iterations += 1
    return d, checks, active


def contact(u, v, dvc, sp: BatchSphere, shape: str, R: float, r: float, fmask, C, V, M, mu: float, dt, alive,
            tol: float, block: int):
    """Close the gaps of B runs between their contact nodes and their impactors.

    Parameters
    ----------
    u, v, dvc : Tensor (3, B n)
        Trial displacements (m), velocities (m/s) and velocity corrections, modified in place.
    sp : BatchSphere
        The nodes that may touch the impactor.
    shape, R, r : str, float, float
        Impactor shape, radius and rim radius (m).
    fmask : Tensor (3, 1)
        1 on the impactor's free translations.
    C, V : Tensor (3, B)
        Trial reference point (m) and velocity (m/s) of each run's impactor.
    M, dt, alive : Tensor (B,)
        Impactor mass (kg), step (s), live runs.
    mu, tol, block : float, float, int
        Coulomb coefficient; relative Newton tolerance; host check interval (0: none).

    Returns
    -------
    tuple
        (dC (3, B), dV (3, B), penetration (B,) (m), host checks, unconverged (B,) bool).
    """
    c = _Cand(_gather(u, sp), sp, shape, R, r, C, M, fmask)
    d, checks, unconverged = _newton(c, alive, tol, block)
    s, _ = c.push(d)
    q = c.qc * s
    moved = s > 0.0
    dx = torch.where(moved, s, 0.0) * c.D
    dvx = dx / dt[:, None]
    u.index_add_(1, sp.nodes, dx.reshape(3, -1))
    v.index_add_(1, sp.nodes, dvx.reshape(3, -1))
    dvc.index_add_(1, sp.nodes, dvx.reshape(3, -1))
    dC = -torch.where(moved, q * c.nf, 0.0).sum(2) / M
    dV = dC / dt
    if mu > 0.0:
        dC, dV = _friction(u, v, dvc, sp, c, q, C, V, dC, dV, M, mu, dt)
    g, _ = gap(shape, R, r, _gather(u, sp) - (C + dC)[:, :, None])
    pen = torch.where(torch.isfinite(g), -g, 0.0).amax(1).clamp_min(0.0)
    return dC, dV, pen, checks, unconverged


def _friction(u, v, dvc, sp, c: _Cand, q, C, V, dC, dV, M, mu, dt):
    """Coulomb stick / slip of the touching nodes relative to each run's impactor; (dC, dV) (3, B)."""
    B, s = sp.mass.shape
    _, n = gap(c.shape, c.R, c.r, _gather(u, sp) - (C + dC)[:, :, None])
    vs = v.index_select(1, sp.nodes).view(3, B, s)
    rel = vs - (V + dV)[:, :, None]
    dvt = coulomb(u, v, dvc, sp, c.inside, q, rel, n, mu, dt)
    mt = (sp.mass * dvt).sum(2) * c.fmask
    return dC + mt * dt / M, dV + mt / M
