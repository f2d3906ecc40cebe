"""Eigen-decomposition of a batch of symmetric 3x3 matrices in plain torch ops (no LAPACK).

The algorithm is the numba backend's (``cfm_backends/numba_explicit/kernels/eigen.py``),
written over a batch with masks instead of branches; nothing is differentiated through it
(stresses come from the material's generated gradient in the principal basis):

``eig3`` (hybrid): the most isolated eigenvalue m of the deviator (largest if r >= 0, else
smallest) from the trigonometric solution's polynomial fit plus one Halley step; its eigenvector
as the longest cross product of two rows of A - m I (first longest on ties); the remaining pair
from one exact Jacobi rotation in the orthogonal plane (exact for repeated eigenvalues); eigenvalues
as Rayleigh quotients. The starting basis of that plane is built branch-free (Duff et al. 2017)
instead of numba's cross product with the least aligned axis: the same eigenpairs to round-off.
Matrices isotropic to round-off with zero off-diagonals give Q = I; the others the hybrid cannot
handle (isotropic with non-zero off-diagonals, a non-finite or zero cross
product) are flagged and solved by ``eig3_jacobi`` (cyclic Jacobi, the numba fallback).

``torch.linalg.eigh`` would also do, but on the CPU it loops LAPACK over the batch (about 1-2 us
per matrix: ~10 ms for 5000 elements, more than a whole numba step), and through autograd it gives
NaN at repeated eigenvalues. Layout: A is (3, 3, N), eigenvalues (3, N), Q (3, 3, N) with
Q[:, a, e] the eigenvector of eigenvalue a, so A = Q diag(m) Q^T per element. The scalar part
(eigenvalue, cross products) is written on (N,) component rows; the basis products A [v u w], the
Rayleigh quotients and the outputs on stacked (3, 3, N) / (3, N) tensors (about 240 dispatched
ops with views, was 316; ~1 ms for 5000 elements eager on one core, 0.2 ms through
``torch.compile``). Stacking everything (the cross products from a rolled copy of the rows, the
selection by ``torch.max``) was not faster at 5000 elements: the copies and the slow
reductions along a leading dimension cost what the fewer dispatches save.
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


_CONSTANTS: dict = {}


def constant(values, dtype, device) -> torch.Tensor:
    """A cached constant tensor (index or float table) on ``device`` (one per dtype and device)."""
    key = (values, dtype, device)
    t = _CONSTANTS.get(key)
    if t is None:
        t = torch.tensor(values, dtype=dtype, device=device)
        if not torch.compiler.is_compiling():
            _CONSTANTS[key] = t
    return t


def eig3(A: torch.Tensor):
    """(m (3, N), Q (3, 3, N), fallback (N,) bool) of symmetric A (3, 3, N); see the module docstring.

    Entries flagged in ``fallback`` are not valid: solve them with :func:`eig3_jacobi`.
    The scalar parts (eigenvalue, cross products) are written on (N,) component rows as numba's
    scalar code; the products with the basis [v u w] (A V, the Rayleigh quotients) and the
    outputs are single ops on stacked (3, 3, N) / (3, N) tensors. About 150 tensor ops.
    """
    dt, dev = A.dtype, A.device
    rel = precision_scale(dt)
    N = A.shape[-1]
    a00, a01, a02 = A[0].unbind(0)
    a11, a12 = A[1, 1], A[1, 2]
    a22 = A[2, 2]
    diag = A.reshape(9, N)[0::4]                                # (3, N) view: a00, a11, a22
    q = diag.sum(0) / 3.0
    b00 = a00 - q
    b11 = a11 - q
    b22 = a22 - q
    p2 = (b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (a01 * a01 + a02 * a02 + a12 * a12)) / 6.0
    scale = a00.abs() + a11.abs() + a22.abs() + a01.abs() + a02.abs() + a12.abs()
    iso = p2 <= (1e-17 * rel * scale) ** 2                      # includes A = 0
    offzero = (a01 == 0.0) & (a02 == 0.0) & (a12 == 0.0)
    p = torch.sqrt(p2)
    det = b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02)
    r = (det / (2.0 * p2 * p)).clamp(-1.0, 1.0)
    s = r.abs()
    beta = BETA_FIT[6] * s + BETA_FIT[5]
    for c in BETA_FIT[4::-1]:
        beta.mul_(s).add_(c)
    b2 = beta * beta
    g = beta * (b2 - 3.0) - 2.0 * s
    gp = 3.0 * (b2 - 1.0)
    beta = beta - 2.0 * g * gp / (2.0 * gp * gp - 6.0 * g * beta)
    pb = p * beta
    m = q + torch.where(r >= 0.0, pb, -pb)
    # eigenvector of m: the longest cross product of two rows of A - m I (first longest on ties)
    c00 = a00 - m
    c11 = a11 - m
    c22 = a22 - m
    x0 = a01 * a12 - a02 * c11                                 # row0 x row1
    x1 = a02 * a01 - c00 * a12
    x2 = c00 * c11 - a01 * a01
    n0 = x0 * x0 + x1 * x1 + x2 * x2
    y0 = a01 * c22 - a02 * a12                                 # row0 x row2
    y1 = a02 * a02 - c00 * c22
    y2 = c00 * a12 - a01 * a02
    n1 = y0 * y0 + y1 * y1 + y2 * y2
    z0 = c11 * c22 - a12 * a12                                 # row1 x row2
    z1 = a12 * a02 - a01 * c22
    z2 = a01 * a12 - c11 * a02
    n2 = z0 * z0 + z1 * z1 + z2 * z2
    take_y = (n1 > n0) & (n1 >= n2)
    take_z = ~take_y & (n2 > n0)
    X = torch.stack([x0, x1, x2, n0, y0, y1, y2, n1, z0, z1, z2, n2]).view(3, 4, N)
    x = torch.where(take_z, X[2], torch.where(take_y, X[1], X[0]))          # (4, N): the vector, its norm^2
    bad = ~((x[3] > 0.0) & (x[3] < torch.inf))
    v = x[0:3] * torch.rsqrt(x[3])
    v0, v1, v2 = v.unbind(0)
    # (u, w): an orthonormal basis of the plane normal to v, branch-free (Duff et al. 2017,
    # "Building an orthonormal basis, revisited"); the Jacobi rotation below makes the pair unique
    sg = torch.where(v2 >= 0.0, 1.0, -1.0)
    a = -1.0 / (sg + v2)
    b = v0 * v1 * a
    sv0 = sg * v0
    V = torch.stack([v0, sv0 * v0 * a + 1.0, b, v1, sg * b, sg + v1 * v1 * a, v2, -sv0, -v1]).view(3, 3, N)
    # isotropic A: the basis is I, so that (with zero off-diagonals) the rotation below is t = 0 and
    # the outputs are exactly Q = I, m = diag A (a row times 1 plus zeros times finite entries)
    V = torch.where(iso, constant((1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), dt, dev).view(3, 3, 1), V)
    # A [v u w], the Rayleigh quotients v.Av, u.Au, w.Aw and u.Aw
    A0, A1, A2 = A[:, :, None].unbind(1)
    V0, V1, V2 = V[None].unbind(1)
    AV = (A0 * V0).addcmul_(A1, V1).addcmul_(A2, V2)
    mv, buu, bww = (V * AV).sum(0).unbind(0)
    buw = (V[:, 1] * AV[:, 2]).sum(0)
    # Jacobi rotation of the (u, w) block: t = sign(theta) / (|theta| + sqrt(theta^2 + 1))
    dd = bww - buu
    den = dd.abs() + torch.sqrt(dd * dd + 4.0 * buw * buw)
    t = 2.0 * buw / torch.copysign(den, dd)
    # buw = 0, or dd = 0 with 4 buw^2 below the smallest float (den = 0: t was inf, the eigenvalues +-inf in
    # float32 at an off-diagonal of 1e-24): no rotation, as numba's kernel (its error is below the last bit)
    t = torch.where((buw != 0.0) & (den > 0.0), t, 0.0)
    c = 1.0 / torch.sqrt(t * t + 1.0)
    sn = t * c
    tb = t * buw
    u, w = V[:, 1], V[:, 2]
    m = torch.stack([mv, buu - tb, bww + tb])
    Q = torch.stack([V[:, 0], c * u - sn * w, sn * u + c * w], dim=1)
    fallback = torch.where(iso, ~offzero, bad)
    return m, Q, fallback


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


def eig3_jacobi(A: torch.Tensor, max_sweeps: int = 16, check: bool = True):
    """Cyclic Jacobi (numba's ``eig3_jacobi``) on A (3, 3, K): (m (3, K), Q (3, 3, K)).

    Slow (about 100 tensor ops per sweep) and used only for the few matrices :func:`eig3` flags.
    Each matrix stops rotating once its off-diagonal sum is below 1e-18 of its diagonal sum (scaled
    by the dtype's precision); the loop ends when all have (one host check per sweep), or, with
    ``check=False``, after ``max_sweeps`` sweeps without any host check (a converged matrix is
    left unchanged by further sweeps, so the result is the same).
    """
    rel = precision_scale(A.dtype)
    a = {(i, j): A[i, j].clone() for i in range(3) for j in range(i, 3)}
    Q = torch.eye(3, dtype=A.dtype, device=A.device)[:, :, None].repeat(1, 1, A.shape[-1])
    Q = [[Q[i, j].clone() for j in range(3)] for i in range(3)]
    for _sweep in range(max_sweeps):
        off = a[0, 1].abs() + a[0, 2].abs() + a[1, 2].abs()
        active = ~(off <= 1e-18 * rel * (a[0, 0].abs() + a[1, 1].abs() + a[2, 2].abs()))
        if check and not bool(active.any()):
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


def patch_fallback_isotropic(A, m, Q, fallback, rel: float | None = None):
    """:func:`patch_fallback` without host synchronisation, for matrices isotropic to round-off.

    The hybrid flags (nearly) only matrices whose deviator is at round-off level, where any
    orthonormal basis is an eigenbasis to that level: the flagged entries get m = diag(A) and
    Q = I (the stress error is of the order of the round-off off-diagonals that caused the flag,
    relative to an element stress that is itself near zero). Returns (m, Q, unsafe), ``unsafe``
    (0-d bool tensor) saying that a flagged matrix has off-diagonals above ``rel`` times its
    trace, where this is not exact: the caller reports it later (nothing here waits for the device).
    """
    if rel is None:   # 1e-8 in float64, 2.3e-4 in float32 (whose hybrid flags less isotropic matrices)
        rel = 1e-8 * precision_scale(A.dtype) ** 0.5
    diag = torch.stack([A[0, 0], A[1, 1], A[2, 2]])
    off = A[0, 1].abs() + A[0, 2].abs() + A[1, 2].abs()
    unsafe = (fallback & ~(off <= rel * diag.abs().sum(0))).any()
    eye = torch.eye(3, dtype=A.dtype, device=A.device)[:, :, None]
    return torch.where(fallback, diag, m), torch.where(fallback, eye, Q), unsafe
