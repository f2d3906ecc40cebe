"""Eigen-decomposition of a batch of symmetric 3x3 matrices in plain torch ops (no LAPACK).

The algorithm is the numba backend's (``cfm_backends/numba_explicit/kernels/eigen.py``),
written over a batch with masks instead of branches; nothing is differentiated through it
(stresses come from the material's generated gradient in the principal basis):

``eig3`` (hybrid): the most isolated eigenvalue m of the deviator (largest if r >= 0, else
smallest) from the trigonometric solution's polynomial fit plus one Halley step; its eigenvector
as the longest cross product of two rows of A - m I (first longest on ties); the remaining pair
from one exact Jacobi rotation in the orthogonal plane (exact for repeated eigenvalues); eigenvalues
as Rayleigh quotients. Matrices isotropic to round-off with zero off-diagonals give Q = I; the
others the hybrid cannot handle (isotropic with non-zero off-diagonals, a non-finite or zero cross
product) are flagged and solved by ``eig3_jacobi`` (cyclic Jacobi, the numba fallback).

``torch.linalg.eigh`` would also do, but on the CPU it loops LAPACK over the batch (about 1-2 us
per matrix: ~10 ms for 5000 elements, more than a whole numba step), and through autograd it gives
NaN at repeated eigenvalues. Layout: A is (3, 3, N), eigenvalues (3, N), Q (3, 3, N) with
Q[:, a, e] the eigenvector of eigenvalue a, so A = Q diag(m) Q^T per element.
"""

from __future__ import annotations

import torch

# degree-6 fit of beta(s) = 2 cos(acos(s) / 3) on [0, 1] (error 3.7e-7), refined by one Halley step
BETA_FIT = (1.7320511824314178, 0.3333112449980408, -0.09590537847225317, 0.047417862652197044,
            -0.024856608917710094, 0.010008930582931824, -0.002027510931468306)
OFF = ((0, 1), (0, 2), (1, 2))


def precision_scale(dtype) -> float:
    """Machine epsilon of dtype relative to float64's (1 for float64): scales round-off thresholds."""
    return torch.finfo(dtype).eps / torch.finfo(torch.float64).eps


def eig3(A: torch.Tensor):
    """(m (3, N), Q (3, 3, N), fallback (N,) bool) of symmetric A (3, 3, N); see the module docstring.

    Entries flagged in ``fallback`` are not valid: solve them with :func:`eig3_jacobi`.
    """
    rel = precision_scale(A.dtype)
    eye = torch.eye(3, dtype=A.dtype, device=A.device)
    diag = torch.diagonal(A, dim1=0, dim2=1).T                 # (3, N) view
    off = torch.stack([A[0, 1], A[0, 2], A[1, 2]])             # a01, a02, a12
    q = (diag[0] + diag[1] + diag[2]) / 3.0
    b = diag - q
    p2 = ((b * b).sum(0) + 2.0 * (off * off).sum(0)) / 6.0
    scale = diag.abs().sum(0) + off.abs().sum(0)
    iso = p2 <= (1e-17 * rel * scale) ** 2                      # includes A = 0
    offzero = (off == 0.0).all(0)
    p = torch.sqrt(p2)
    b00, b11, b22 = b[0], b[1], b[2]
    a01, a02, a12 = off[0], off[1], off[2]
    det = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02))
    r = (det / (2.0 * p2 * p)).clamp(-1.0, 1.0)
    s = r.abs()
    beta = BETA_FIT[6] * s + BETA_FIT[5]
    for c in BETA_FIT[4::-1]:
        beta = beta * s + c
    b2 = beta * beta
    g = beta * (b2 - 3.0) - 2.0 * s
    gp = 3.0 * (b2 - 1.0)
    beta = beta - 2.0 * g * gp / (2.0 * gp * gp - 6.0 * g * beta)
    pb = p * beta
    m = torch.where(r >= 0.0, q + pb, q - pb)
    # eigenvector of m: the longest cross product of two rows of A - m I (first longest on ties)
    R = A - eye[:, :, None] * m
    X = torch.linalg.cross(R[[0, 0, 1]], R[[1, 2, 2]], dim=1)  # rows (0x1, 0x2, 1x2), (3, 3, N)
    n3 = (X * X).sum(1)
    k = torch.argmax(n3, dim=0, keepdim=True)
    x = X.gather(0, k[:, None, :].expand(1, 3, -1))[0]
    n0 = n3.gather(0, k)[0]
    bad = ~(n0 > 0.0) | ~torch.isfinite(n0)
    v = x * torch.rsqrt(n0)
    # u = x cross e_j / |.| with e_j the axis least aligned with x (first on ties); w = v x u
    j = torch.argmin(x.abs(), dim=0)
    ur = torch.linalg.cross(x, eye.index_select(1, j), dim=0)
    u = ur * torch.rsqrt((ur * ur).sum(0))
    w = torch.linalg.cross(v, u, dim=0)
    V = torch.stack([v, u, w])                                 # (vector, component, N)
    AV = (A[None] * V[:, None]).sum(2)                         # A v, A u, A w
    ray = (V * AV).sum(1)
    mv, buu, bww = ray[0], ray[1], ray[2]
    buw = (u * AV[2]).sum(0)
    # Jacobi rotation of the (u, w) block: t = sign(theta) / (|theta| + sqrt(theta^2 + 1))
    dd = bww - buu
    t = 2.0 * buw / (dd.abs() + torch.sqrt(dd * dd + 4.0 * buw * buw))
    t = torch.where(dd < 0.0, -t, t)
    t = torch.where(buw != 0.0, t, 0.0)
    c = 1.0 / torch.sqrt(t * t + 1.0)
    sn = t * c
    tb = t * buw
    u2 = c * u - sn * w
    w2 = sn * u + c * w
    m_all = torch.stack([mv, buu - tb, bww + tb])
    Q = torch.stack([v, u2, w2], dim=1)
    m_all = torch.where(iso, diag, m_all)
    Q = torch.where(iso, eye[:, :, None], Q)
    fallback = (iso & ~offzero) | (~iso & bad)
    return m_all, Q, fallback


def _rotation(app, aqq, apq):
    """(c, s, t) of the rotation annihilating apq (Numerical Recipes, sec. 11.1), batched."""
    theta = (aqq - app) / (2.0 * apq)
    at = theta.abs()
    t = 1.0 / (at + torch.sqrt(theta * theta + 1.0))
    t = torch.where(theta < 0.0, -t, t)
    big = 1e150 if theta.dtype == torch.float64 else 1e15    # theta^2 + 1 would overflow
    t = torch.where(at > big, 0.5 / theta, t)
    c = 1.0 / torch.sqrt(t * t + 1.0)
    return c, t * c, t


def eig3_jacobi(A: torch.Tensor, max_sweeps: int = 16):
    """Cyclic Jacobi (numba's ``eig3_jacobi``) on A (3, 3, K): (m (3, K), Q (3, 3, K)).

    Slow (about 100 tensor ops per sweep) and used only for the few matrices :func:`eig3` flags.
    Each matrix stops rotating once its off-diagonal sum is below 1e-18 of its diagonal sum (scaled
    by the dtype's precision); the loop ends when all have (one host check per sweep).
    """
    rel = precision_scale(A.dtype)
    a = {(i, j): A[i, j].clone() for i in range(3) for j in range(i, 3)}
    Q = torch.eye(3, dtype=A.dtype, device=A.device)[:, :, None].repeat(1, 1, A.shape[-1])
    Q = [[Q[i, j].clone() for j in range(3)] for i in range(3)]
    for _sweep in range(max_sweeps):
        off = a[0, 1].abs() + a[0, 2].abs() + a[1, 2].abs()
        active = ~(off <= 1e-18 * rel * (a[0, 0].abs() + a[1, 1].abs() + a[2, 2].abs()))
        if not bool(active.any()):
            break
        for p, qq in OFF:
            r = 3 - p - qq                                      # the third index
            apq = a[p, qq]
            do = active & (apq != 0.0)
            c, s, t = _rotation(a[p, p], a[qq, qq], apq)
            rp = (min(p, r), max(p, r))
            rq = (min(qq, r), max(qq, r))
            new = {(p, p): a[p, p] - t * apq, (qq, qq): a[qq, qq] + t * apq,
                   (p, qq): torch.zeros_like(apq),
                   rp: c * a[rp] - s * a[rq], rq: s * a[rp] + c * a[rq]}
            for key, val in new.items():
                a[key] = torch.where(do, val, a[key])
            for i in range(3):
                qp, qn = Q[i][p], Q[i][qq]
                Q[i][p] = torch.where(do, c * qp - s * qn, qp)
                Q[i][qq] = torch.where(do, s * qp + c * qn, qn)
    m = torch.stack([a[0, 0], a[1, 1], a[2, 2]])
    return m, torch.stack([torch.stack(row) for row in Q])


def eig3_full(A: torch.Tensor):
    """(m, Q) of all matrices: :func:`eig3`, then :func:`eig3_jacobi` on the flagged ones (host check)."""
    m, Q, fallback = eig3(A)
    if bool(fallback.any()):
        m, Q = patch_fallback(A, m, Q, fallback)
    return m, Q


def patch_fallback(A, m, Q, fallback):
    """m, Q with the entries flagged in ``fallback`` replaced by the Jacobi solution."""
    idx = torch.nonzero(fallback).reshape(-1)
    mj, Qj = eig3_jacobi(A.index_select(2, idx))
    m = m.index_copy(1, idx, mj)
    Q = Q.index_copy(2, idx, Qj)
    return m, Q
