"""Eigen-decomposition of a symmetric 3x3 matrix (numba, scalars only, no allocation).

``eig3`` (used by the solver) is a hybrid, about 3x faster than cyclic Jacobi:

1. the *most isolated* eigenvalue (largest if r >= 0, else smallest) of the deviator
   B = A - tr(A)/3 I, as in the trigonometric solution (Smith 1961) m = tr/3 + p beta(r), but
   with beta from a polynomial fit refined by one Halley step on the normalised
   characteristic polynomial (no acos / cos; the root is simple, so this is exact to
   round-off); if the deviator vanishes (all eigenvalues equal, e.g. the undeformed state)
   Q = I exactly;
2. its eigenvector as the
   longest cross product of two rows of A - m I; its error is O(eps |A| / spread), so the
   reconstruction and any isotropic function of A (the stress) stay accurate to round-off even
   when the spread is tiny: eigenvector errors only mix directions whose eigenvalues are close;
3. the remaining pair from one exact Jacobi rotation of A projected on the orthogonal plane,
   which is exact for repeated eigenvalues (uniaxial states: diag(a, b, b)).

Eigenvalues are then the Rayleigh quotients of the final orthonormal vectors. ``eig3_jacobi``
(cyclic Jacobi, quadratic convergence to 1e-18 relative off-diagonal) is the slow, simple
reference and the fallback when the hybrid meets a non-finite value.
"""

# >>> standalone (removed when the kernels are concatenated into a generated module)
import math

from numba import njit
from cfm_backends.numba_cache import key_on_folder

from .layout import FASTMATH
from .vmath import vsqrt

key_on_folder(__file__)  # numba's cache of these kernels is keyed on every file of the folder
# <<< standalone


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def rotate(c, s, a, b):
    """The plane rotation (c a - s b, s a + c b)."""
    return c * a - s * b, s * a + c * b


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def jacobi_rotation(app, aqq, apq):
    """(c, s, t) of the rotation annihilating apq (Numerical Recipes, sec. 11.1)."""
    theta = (aqq - app) / (2.0 * apq)
    at = abs(theta)
    if at > 1e150:
        t = 0.5 / theta
    else:
        t = 1.0 / (at + math.sqrt(theta * theta + 1.0))
        if theta < 0.0:
            t = -t
    c = 1.0 / math.sqrt(t * t + 1.0)
    return c, t * c, t


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def eig3_jacobi(a00, a01, a02, a11, a12, a22):
    """Cyclic Jacobi: eigenvalues and eigenvectors of the symmetric matrix [[a00,a01,a02],[.,a11,a12],[.,.,a22]].

    Returns (m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22): eigenvalue m_k belongs to
    column k of Q = [[q00,q01,q02],[q10,q11,q12],[q20,q21,q22]], so A = Q diag(m) Q^T.
    Eigenvalues are not sorted.
    """
    q00 = 1.0
    q01 = 0.0
    q02 = 0.0
    q10 = 0.0
    q11 = 1.0
    q12 = 0.0
    q20 = 0.0
    q21 = 0.0
    q22 = 1.0
    for _sweep in range(16):
        off = abs(a01) + abs(a02) + abs(a12)
        if off <= 1e-18 * (abs(a00) + abs(a11) + abs(a22)):
            break
        # pair (0, 1): the third index is 2
        if a01 != 0.0:
            c, s, t = jacobi_rotation(a00, a11, a01)
            a00 -= t * a01
            a11 += t * a01
            a01 = 0.0
            a02, a12 = rotate(c, s, a02, a12)
            q00, q01 = rotate(c, s, q00, q01)
            q10, q11 = rotate(c, s, q10, q11)
            q20, q21 = rotate(c, s, q20, q21)
        # pair (0, 2): the third index is 1
        if a02 != 0.0:
            c, s, t = jacobi_rotation(a00, a22, a02)
            a00 -= t * a02
            a22 += t * a02
            a02 = 0.0
            a01, a12 = rotate(c, s, a01, a12)
            q00, q02 = rotate(c, s, q00, q02)
            q10, q12 = rotate(c, s, q10, q12)
            q20, q22 = rotate(c, s, q20, q22)
        # pair (1, 2): the third index is 0
        if a12 != 0.0:
            c, s, t = jacobi_rotation(a11, a22, a12)
            a11 -= t * a12
            a22 += t * a12
            a12 = 0.0
            a01, a02 = rotate(c, s, a01, a02)
            q01, q02 = rotate(c, s, q01, q02)
            q11, q12 = rotate(c, s, q11, q12)
            q21, q22 = rotate(c, s, q21, q22)
    return a00, a11, a22, q00, q01, q02, q10, q11, q12, q20, q21, q22


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def eig3(a00, a01, a02, a11, a12, a22):
    """Eigenvalues and eigenvectors of a symmetric 3x3 matrix, same output as :func:`eig3_jacobi`."""
    (ok, m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22) = eig3_hybrid(a00, a01, a02, a11, a12, a22)
    if ok:
        return m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22
    return eig3_jacobi(a00, a01, a02, a11, a12, a22)


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def eig3_hybrid(a00, a01, a02, a11, a12, a22):
    """The hybrid method without branches (so that a loop over elements vectorises).

    Returns (ok, m0, m1, m2, q00, ..., q22) as :func:`eig3_jacobi` does. Where the method does
    not apply (A isotropic to round-off, p2 <= (1e-17 |A|)^2, or a non-finite value on the way)
    but A is exactly diagonal (the undeformed state C = I, and any diagonal A the method skips),
    the result is that diagonal with Q = I, selected without a branch: an undeformed element
    stays on the vectorised path (on a large mesh most of the far field is undeformed for much of
    a run). Otherwise ok is False, the other values are meaningless and the caller falls back to
    :func:`eig3` (scalar cyclic Jacobi).
    """
    q = (a00 + a11 + a22) / 3.0
    b00 = a00 - q
    b11 = a11 - q
    b22 = a22 - q
    p2 = (b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (a01 * a01 + a02 * a02 + a12 * a12)) / 6.0
    scale = abs(a00) + abs(a11) + abs(a22) + abs(a01) + abs(a02) + abs(a12)
    tol = 1e-17 * scale
    p = vsqrt(p2)
    # r = det(B / p) / 2 with B = A - q I, clamped to [-1, 1]
    det = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02)
           + a02 * (a01 * a12 - b11 * a02))
    r = det / (2.0 * p2 * p)
    r = 1.0 if r > 1.0 else r
    r = -1.0 if r < -1.0 else r
    # isolated root beta = 2 cos(acos(|r|) / 3) in [sqrt 3, 2] of g = beta^3 - 3 beta - 2 |r|
    # (largest eigenvalue if r >= 0, else smallest): degree-6 fit (error 3.7e-7) and one Halley
    # step (error ~ 1e-19; the root is simple, g' >= 6), no acos / cos
    s = abs(r)
    beta = 1.7320511824314178 + s * (0.3333112449980408 + s * (-0.09590537847225317 + s * (
        0.047417862652197044 + s * (-0.024856608917710094 + s * (0.010008930582931824
                                                                 - 0.002027510931468306 * s)))))
    b2 = beta * beta
    g = beta * (b2 - 3.0) - 2.0 * s
    gp = 3.0 * (b2 - 1.0)
    beta -= 2.0 * g * gp / (2.0 * gp * gp - 6.0 * g * beta)
    m = q + p * beta if r >= 0.0 else q - p * beta
    # eigenvector of m: longest cross product of two rows of A - m I
    c00 = a00 - m
    c11 = a11 - m
    c22 = a22 - m
    x0 = a01 * a12 - a02 * c11      # row0 x row1
    x1 = a02 * a01 - c00 * a12
    x2 = c00 * c11 - a01 * a01
    n0 = x0 * x0 + x1 * x1 + x2 * x2
    y0 = a01 * c22 - a02 * a12      # row0 x row2
    y1 = a02 * a02 - c00 * c22
    y2 = c00 * a12 - a01 * a02
    n1 = y0 * y0 + y1 * y1 + y2 * y2
    z0 = c11 * c22 - a12 * a12      # row1 x row2
    z1 = a12 * a02 - a01 * c22
    z2 = a01 * a12 - c11 * a02
    n2 = z0 * z0 + z1 * z1 + z2 * z2
    take_y = (n1 > n0) & (n1 >= n2)           # & and |: no short-circuit branches
    take_z = (n2 > n0) & ((n1 <= n0) | (n1 < n2))
    x0 = y0 if take_y else (z0 if take_z else x0)
    x1 = y1 if take_y else (z1 if take_z else x1)
    x2 = y2 if take_y else (z2 if take_z else x2)
    n0 = n1 if take_y else (n2 if take_z else n0)
    ok = (p2 > tol * tol) & (n0 > 0.0) & (n0 - n0 == 0.0)      # n0 - n0 is NaN for inf and NaN
    # v = x / |x|; u = (x x e_k) / |x x e_k| with e_k the axis least aligned with x (both
    # normalisations are independent: shorter dependency chain); w = v x u
    inv = 1.0 / vsqrt(n0)
    ax0 = abs(x0)
    ax1 = abs(x1)
    ax2 = abs(x2)
    k0 = (ax0 <= ax1) & (ax0 <= ax2)                  # u ~ x x e0
    k1 = ((ax0 > ax1) | (ax0 > ax2)) & (ax1 <= ax2)   # u ~ x x e1, else x x e2
    u0 = 0.0 if k0 else (-x2 if k1 else x1)
    u1 = x2 if k0 else (0.0 if k1 else -x0)
    u2 = -x1 if k0 else (x0 if k1 else 0.0)
    invu = 1.0 / vsqrt(x1 * x1 + x2 * x2 if k0 else (x0 * x0 + x2 * x2 if k1 else x0 * x0 + x1 * x1))
    v0 = x0 * inv
    v1 = x1 * inv
    v2 = x2 * inv
    u0 *= invu
    u1 *= invu
    u2 *= invu
    w0 = v1 * u2 - v2 * u1
    w1 = v2 * u0 - v0 * u2
    w2 = v0 * u1 - v1 * u0
    # A v, A u, A w and the projections
    av0 = a00 * v0 + a01 * v1 + a02 * v2
    av1 = a01 * v0 + a11 * v1 + a12 * v2
    av2 = a02 * v0 + a12 * v1 + a22 * v2
    au0 = a00 * u0 + a01 * u1 + a02 * u2
    au1 = a01 * u0 + a11 * u1 + a12 * u2
    au2 = a02 * u0 + a12 * u1 + a22 * u2
    aw0 = a00 * w0 + a01 * w1 + a02 * w2
    aw1 = a01 * w0 + a11 * w1 + a12 * w2
    aw2 = a02 * w0 + a12 * w1 + a22 * w2
    mv = v0 * av0 + v1 * av1 + v2 * av2
    buu = u0 * au0 + u1 * au1 + u2 * au2
    bww = w0 * aw0 + w1 * aw1 + w2 * aw2
    buw = u0 * aw0 + u1 * aw1 + u2 * aw2
    # Jacobi rotation: t = sign(theta) / (|theta| + sqrt(theta^2 + 1)), theta = (bww-buu)/(2 buw);
    # buw = 0 gives t = 0, the identity
    dd = bww - buu
    den = abs(dd) + vsqrt(dd * dd + 4.0 * buw * buw)
    t = 2.0 * buw / den if den > 0.0 else 0.0
    t = -t if dd < 0.0 else t
    c = 1.0 / vsqrt(t * t + 1.0)
    s = t * c
    buu -= t * buw
    bww += t * buw
    u0, w0 = rotate(c, s, u0, w0)
    u1, w1 = rotate(c, s, u1, w1)
    u2, w2 = rotate(c, s, u2, w2)
    # exactly diagonal where the method does not apply: that diagonal, Q = I (selects, no branch)
    dg = (a01 == 0.0) & (a02 == 0.0) & (a12 == 0.0) & (not ok)
    return (ok | dg, a00 if dg else mv, a11 if dg else buu, a22 if dg else bww,
            1.0 if dg else v0, 0.0 if dg else u0, 0.0 if dg else w0,
            0.0 if dg else v1, 1.0 if dg else u1, 0.0 if dg else w1,
            0.0 if dg else v2, 0.0 if dg else u2, 1.0 if dg else w2)
