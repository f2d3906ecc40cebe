"""Kinematic (momentum-exchange) contact with a rigid impactor of any shape and motion (numba, serial).

The general form of ``contact.sphere_contact`` (which stays the path of the paper's hemisphere
moving along z): shapes ``hemisphere``, ``sphere``, ``flat`` (cylinder with a rounded rim),
``plane``, with the gap and normal of :func:`cfm_core.scene.impactor.gap` (:func:`shape_gap`,
the same formulas, tested against it), and an impactor that translates along any of its free
directions (``moves``).

After the trial update, each node I inside the impactor (at its trial position C) is pushed along
d_I = P n_I / |P n_I| (n_I the impactor's outward normal at the nearest surface point, P removes
the node's fixed dofs) by s_I >= 0 so that it lands exactly on the impactor moved by dX
(:func:`landing`: closed form for the sphere and the plane, a safeguarded Newton iteration on the
scalar root for the flat impactor, whose rim is a torus). The normal impulse q_I = m_I s_I /
|P n_I| (kg m) acts on the node and -q_I n_I on the impactor, so the impactor's move over its
free directions solves

    h(dX) = dX + sum_I q_I(dX) n_I / M = 0     (free components; held ones stay 0),

exactly (no linearisation): momentum is conserved in every free direction. One free direction
(z): the bracketed safeguarded Newton iteration of ``sphere_contact``; several: Newton on the
small system (Jacobian I + sum_I (m_I / (|P n_I| M)) n_I (grad g_I)^T / (grad g_I . d_I)) with
a halving line search, falling back to the bracketed 1-D solve in z if it does not converge.

Friction (Coulomb, mu): as in ``sphere_contact``, the tangential relative velocity of each
contacting node is removed (stick) or reduced by mu times its normal impulse (slip), the normal
taken on the moved impactor; the reaction goes to the impactor in all its free directions
(after the normal closure, as in ``sphere_contact``: with friction a gap of the order of
mu m_I |v_t| dt / M may be left, nanometres in the drop test, reported as the penetration).
"""

# >>> standalone (removed when the kernels are concatenated into a generated module)
import math

import numpy as np
from numba import njit
from cfm_backends.numba_cache import key_on_folder

from .layout import FASTMATH, SH_FLAT, SH_HEMISPHERE, SH_PLANE, SH_SPHERE

key_on_folder(__file__)  # numba's cache of these kernels is keyed on every file of the folder
# <<< standalone


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def shape_gap(shape, R, r, px, py, pz):
    """(g, nx, ny, nz): signed gap (m, +inf where a hemisphere cannot touch) of the point p
    (relative to the impactor's reference point, m) and the impactor's outward unit normal at the
    nearest surface point; :func:`cfm_core.scene.impactor.gap` (shape SH_*, radius R, rim r)."""
    if shape == SH_PLANE:
        return -pz, 0.0, 0.0, -1.0
    if shape == SH_FLAT:
        a = R - r
        rho = math.hypot(px, py)
        ex = 1.0
        ey = 0.0
        if rho > 0.0:
            ex = px / rho
            ey = py / rho
        q1 = rho - a
        q2 = r - pz
        o1 = max(q1, 0.0)
        o2 = max(q2, 0.0)
        dist = math.hypot(o1, o2)
        g = dist + min(max(q1, q2), 0.0) - r
        if q1 > 0.0 and q2 > 0.0:
            return g, o1 * ex / dist, o1 * ey / dist, -o2 / dist
        if q1 > q2:
            return g, ex, ey, 0.0
        return g, 0.0, 0.0, -1.0
    d = math.sqrt(px * px + py * py + pz * pz)
    g = d - R
    if shape == SH_HEMISPHERE and not pz < 0.0:
        g = math.inf
    if d > 0.0:
        return g, px / d, py / d, pz / d
    return g, 0.0, 0.0, -1.0


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def landing(shape, R, r, px, py, pz, d0, d1, d2):
    """(s, gx, gy, gz, den): the smallest s >= 0 with g(p + s d) = 0 for the unit push direction
    d (0 when g(p) >= 0; the hemisphere's root is the whole sphere's), the gap's gradient there
    (any length) and its product with d (ds/dX = grad g / den; 0 where den <= 0)."""
    if shape == SH_PLANE:
        if pz <= 0.0 or d2 >= 0.0:
            return 0.0, 0.0, 0.0, -1.0, 0.0
        return -pz / d2, 0.0, 0.0, -1.0, -d2
    if shape != SH_FLAT:
        pp = px * px + py * py + pz * pz
        cq = pp - R * R
        if cq >= 0.0:
            return 0.0, px, py, pz, 0.0
        b = px * d0 + py * d1 + pz * d2
        disc = math.sqrt(b * b - cq)
        s = -cq / (b + disc) if b > 0.0 else disc - b
        ex = px + s * d0
        ey = py + s * d1
        ez = pz + s * d2
        den = ex * d0 + ey * d1 + ez * d2
        return s, ex, ey, ez, max(den, 0.0)
    g0, n0, n1, n2 = shape_gap(shape, R, r, px, py, pz)
    if g0 >= 0.0:
        return 0.0, n0, n1, n2, 0.0
    lo = 0.0
    hi = -g0
    for _ in range(80):                         # bracket: g(p + hi d) >= 0 (g is 1-Lipschitz)
        g, n0, n1, n2 = shape_gap(shape, R, r, px + hi * d0, py + hi * d1, pz + hi * d2)
        if g >= 0.0:
            break
        lo = hi
        hi *= 2.0
    s = 0.5 * (lo + hi)
    den0 = n0 * d0 + n1 * d1 + n2 * d2
    if lo == 0.0 and den0 > 0.0:
        s = min(-g0 / den0, hi)                 # the linearised root (exact on the flat faces)
    tol = 4e-16 * (R + hi)
    for _ in range(100):                        # safeguarded Newton in [lo, hi]
        g, n0, n1, n2 = shape_gap(shape, R, r, px + s * d0, py + s * d1, pz + s * d2)
        if g < 0.0:
            lo = s
        else:
            hi = s
        if abs(g) <= tol or hi - lo <= 4e-16 * hi:
            break
        dg = n0 * d0 + n1 * d1 + n2 * d2
        nxt = s - g / dg if dg > 0.0 else -1.0
        if not (nxt > lo and nxt < hi):
            nxt = 0.5 * (lo + hi)
        s = nxt
    g, n0, n1, n2 = shape_gap(shape, R, r, px + s * d0, py + s * d1, pz + s * d2)
    den = n0 * d0 + n1 * d1 + n2 * d2
    return s, n0, n1, n2, max(den, 0.0)


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def _residual(scr, na, shape, R, r, M, mv, dX, h, J):
    """h(dX) (3,) (free components; held ones 0) and its Jacobian J (3, 3) (identity on held ones)."""
    for i in range(3):
        h[i] = dX[i] * mv[i]
        for j in range(3):
            J[i, j] = 1.0 if i == j else 0.0
    for k in range(na):
        s, g0, g1, g2, den = landing(shape, R, r, scr[k, 1] - dX[0], scr[k, 2] - dX[1], scr[k, 3] - dX[2],
                                     scr[k, 4], scr[k, 5], scr[k, 6])
        if s <= 0.0:
            continue
        c = scr[k, 7] / M
        for i in range(3):
            if mv[i] == 0.0:
                continue
            h[i] += c * s * scr[k, 9 + i]
            if den > 0.0:
                J[i, 0] += c * scr[k, 9 + i] * g0 / den * mv[0]
                J[i, 1] += c * scr[k, 9 + i] * g1 / den * mv[1]
                J[i, 2] += c * scr[k, 9 + i] * g2 / den * mv[2]


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def _solve3(J, h, out):
    """out = J^-1 h (Cramer's rule; False when J is singular)."""
    a, b, c = J[0, 0], J[0, 1], J[0, 2]
    d, e, f = J[1, 0], J[1, 1], J[1, 2]
    g, k, m = J[2, 0], J[2, 1], J[2, 2]
    A = e * m - f * k
    B = f * g - d * m
    C = d * k - e * g
    det = a * A + b * B + c * C
    if not (abs(det) > 0.0):
        return False
    out[0] = (A * h[0] + (c * k - b * m) * h[1] + (b * f - c * e) * h[2]) / det
    out[1] = (B * h[0] + (a * m - c * g) * h[1] + (c * d - a * f) * h[2]) / det
    out[2] = (C * h[0] + (b * g - a * k) * h[1] + (a * e - b * d) * h[2]) / det
    return True


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def _solve_z(scr, na, shape, R, r, M, dX):
    """The bracketed safeguarded Newton iteration on h_z(dz) (increasing), dX's x, y held."""
    mz = np.array([0.0, 0.0, 1.0])
    h = np.zeros(3)
    J = np.zeros((3, 3))
    dX[2] = 0.0
    _residual(scr, na, shape, R, r, M, mz, dX, h, J)
    h0 = h[2]
    if h0 == 0.0:
        return
    dz = -h0 / J[2, 2]                          # linearised estimate
    lo, hi = (0.0, -h0) if h0 < 0.0 else (-h0, 0.0)
    for _ in range(80):                         # widen until the bracket holds the root
        dX[2] = hi if h0 < 0.0 else lo
        _residual(scr, na, shape, R, r, M, mz, dX, h, J)
        if (h0 < 0.0 and h[2] >= 0.0) or (h0 > 0.0 and h[2] <= 0.0):
            break
        if h0 < 0.0:
            lo, hi = hi, 2.0 * hi
        else:
            lo, hi = 2.0 * lo, lo
    if not (dz > lo and dz < hi):
        dz = 0.5 * (lo + hi)
    for _ in range(100):
        dX[2] = dz
        _residual(scr, na, shape, R, r, M, mz, dX, h, J)
        if h[2] < 0.0:
            lo = dz
        else:
            hi = dz
        if abs(h[2]) <= 1e-16 * abs(dz) or hi - lo <= 4e-16 * max(abs(lo), abs(hi)):
            break
        nxt = dz - h[2] / J[2, 2]
        if not (nxt > lo and nxt < hi):
            nxt = 0.5 * (lo + hi)
        dz = nxt
    dX[2] = dz


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def solve_move(scr, na, shape, R, r, M, mv, dX):
    """The impactor's move dX (3,) (m) with h(dX) = 0 (module docstring); dX is overwritten."""
    h = np.zeros(3)
    J = np.zeros((3, 3))
    step = np.zeros(3)
    trial = np.zeros(3)
    ht = np.zeros(3)
    dX[:] = 0.0
    if mv[0] == 0.0 and mv[1] == 0.0:
        if mv[2] != 0.0:
            _solve_z(scr, na, shape, R, r, M, dX)
        return
    _residual(scr, na, shape, R, r, M, mv, dX, h, J)
    norm = math.sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2])
    for _it in range(100):
        size = math.sqrt(dX[0] * dX[0] + dX[1] * dX[1] + dX[2] * dX[2])
        if norm <= 1e-16 * size or norm == 0.0:
            return
        if not _solve3(J, h, step):
            break
        lam = 1.0
        nt = norm
        for _ls in range(40):                   # halving line search on |h|
            for i in range(3):
                trial[i] = (dX[i] - lam * step[i]) * mv[i]
            _residual(scr, na, shape, R, r, M, mv, trial, ht, J)
            nt = math.sqrt(ht[0] * ht[0] + ht[1] * ht[1] + ht[2] * ht[2])
            if nt < norm:
                break
            lam *= 0.5
        if not nt < norm:                       # no decrease left: round-off reached, or stuck
            if norm <= 1e-13 * size:
                return
            break
        dX[:] = trial
        h[:] = ht
        norm = nt
    _solve_z(scr, na, shape, R, r, M, dX)       # fallback: z alone, the lateral move held


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def impactor_contact(x, v, dvc, mass, free, snodes, scr, shape, R, r, C, V, mv, M, mu, dt, out):
    """Close all gaps between nodes ``snodes`` and the impactor (module docstring).

    x, v: trial positions x^{n+1} and velocities v^{n+1/2} (modified in place); dvc (n, 3)
    accumulates the velocity corrections; scr (len(snodes), 12) scratch; C, V (3,): the
    impactor's trial reference point (m) and velocity (m/s); mv (3,): 1 where it moves; M its mass
    (kg); dt = dt_{n+1/2} (s). Writes out (6,) = the impactor's move dX (m) and velocity change dV
    (m/s); returns the largest penetration left (m).
    """
    na = 0
    for k in range(snodes.shape[0]):
        I = snodes[k]
        px = x[I, 0] - C[0]
        py = x[I, 1] - C[1]
        pz = x[I, 2] - C[2]
        g, n0, n1, n2 = shape_gap(shape, R, r, px, py, pz)
        if not g < 0.0:
            continue
        u0 = n0 * free[I, 0]
        u1 = n1 * free[I, 1]
        u2 = n2 * free[I, 2]
        w = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        if w < 1e-12:
            continue
        scr[na, 0] = I
        scr[na, 1] = px
        scr[na, 2] = py
        scr[na, 3] = pz
        scr[na, 4] = u0 / w
        scr[na, 5] = u1 / w
        scr[na, 6] = u2 / w
        scr[na, 7] = mass[I] / w           # q_I = scr7 * s_I
        scr[na, 9] = n0
        scr[na, 10] = n1
        scr[na, 11] = n2
        na += 1
    dX = np.zeros(3)
    dV = np.zeros(3)
    if na > 0:
        solve_move(scr, na, shape, R, r, M, mv, dX)
    sq = np.zeros(3)
    for k in range(na):
        s, _, _, _, _ = landing(shape, R, r, scr[k, 1] - dX[0], scr[k, 2] - dX[1], scr[k, 3] - dX[2],
                                scr[k, 4], scr[k, 5], scr[k, 6])
        I = int(scr[k, 0])
        q = scr[k, 7] * s
        scr[k, 7] = q                       # from now on: the normal impulse q_I (kg m)
        if s <= 0.0:
            continue
        for i in range(3):
            dx = s * scr[k, 4 + i]
            x[I, i] += dx
            v[I, i] += dx / dt
            dvc[I, i] += dx / dt
            sq[i] += q * scr[k, 9 + i]
    for i in range(3):                      # the impactor moves by -sum q n / M exactly
        dX[i] = -sq[i] / M * mv[i]
        dV[i] = dX[i] / dt
    if mu > 0.0:
        for k in range(na):
            q = scr[k, 7]
            if q <= 0.0:
                continue
            I = int(scr[k, 0])
            _, nx, ny, nz = shape_gap(shape, R, r, x[I, 0] - C[0] - dX[0], x[I, 1] - C[1] - dX[1],
                                      x[I, 2] - C[2] - dX[2])
            r0 = v[I, 0] - (V[0] + dV[0])
            r1 = v[I, 1] - (V[1] + dV[1])
            r2 = v[I, 2] - (V[2] + dV[2])
            rn = r0 * nx + r1 * ny + r2 * nz
            t0 = (r0 - rn * nx) * free[I, 0]
            t1 = (r1 - rn * ny) * free[I, 1]
            t2 = (r2 - rn * nz) * free[I, 2]
            tn = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
            if tn == 0.0:
                continue
            m = mass[I]
            fac = min(1.0, mu * (q / dt) / (m * tn))
            t = (t0, t1, t2)
            for i in range(3):
                v[I, i] -= fac * t[i]
                x[I, i] -= fac * t[i] * dt
                dvc[I, i] -= fac * t[i]
                dV[i] += m * fac * t[i] / M * mv[i]
                dX[i] += m * fac * t[i] * dt / M * mv[i]
    pen = 0.0
    for k in range(snodes.shape[0]):
        I = snodes[k]
        g, _, _, _ = shape_gap(shape, R, r, x[I, 0] - C[0] - dX[0], x[I, 1] - C[1] - dX[1], x[I, 2] - C[2] - dX[2])
        if -g > pen:
            pen = -g
    for i in range(3):
        out[i] = dX[i]
        out[3 + i] = dV[i]
    return pen


@njit(cache=True, error_model="numpy")
def node_momentum(mass, v, axis):
    """sum_I m_I v_I,axis (kg m/s, modelled part)."""
    p = 0.0
    for n in range(v.shape[0]):
        p += mass[n] * v[n, axis]
    return p
