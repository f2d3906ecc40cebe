"""Kinematic (momentum-exchange) contact with a rigid sphere and a rigid plane (numba, serial).

After the trial update, penetrating nodes are moved back onto the rigid surface and the
velocities corrected consistently (dv = dx / dt), which is the same as adding a contact force
m dv / dtn to the central-difference update: the contact never limits the time step.

Sphere (moving along z only, hemispherical: only its lower half, n_z < 0, can touch; the
paper's impactor; other shapes and lateral motion: ``impactor.py``, the same scheme in general):
a node I inside the sphere is pushed along d_I, its outward normal n_I = (x_I - c)/|x_I - c|
with the components of fixed dofs removed (symmetry planes: the correction never moves a fixed
dof; on a symmetry plane n has no component along the fixed axis anyway), by s_I >= 0 so that
it lands exactly on the moved sphere. Normal impulse q_I = m_I s_I / |P n_I| (kg m) acts on the
node and -q_I n_I on the sphere, whose move is dZ = -sum_I q_I n_Iz / M. Since every s_I(dZ) is
the exact root of |x_I + s d_I - c - dZ e_z| = R, the one unknown dZ solves the monotone equation
h(dZ) = dZ + sum_I q_I(dZ) n_Iz / M = 0 (safeguarded Newton in the bracket [0, -h(0)]): gaps are
closed to round-off (no linearisation), momentum along z is conserved, and nodes that would be
pulled (q < 0) simply get s = 0 (the complementarity is exact).

Friction (Coulomb, mu): after the normal correction, the tangential relative velocity of each
contacting node is removed (stick) if that needs an impulse <= mu times its normal impulse,
else reduced by mu times the normal impulse (slip); the node's own mass is used (the impactor is
much heavier) and the z part of the reaction goes to the sphere.
"""

# >>> standalone (removed when the kernels are concatenated into a generated module)
import math

from numba import njit
from cfm_backends.numba_cache import key_on_folder

from .layout import FASTMATH

key_on_folder(__file__)  # numba's cache of these kernels is keyed on every file of the folder
# <<< standalone


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def _sphere_root(px, py, pz, d0, d1, d2, R, dz):
    """(s, ds/d dz): s >= 0 with |p - dz e_z + s d| = R for a unit d (0 when outside)."""
    qz = pz - dz
    pp = px * px + py * py + qz * qz
    cq = pp - R * R
    if cq >= 0.0:
        return 0.0, 0.0
    b = px * d0 + py * d1 + qz * d2
    disc = math.sqrt(b * b - cq)
    if b > 0.0:
        s = -cq / (b + disc)
    else:
        s = disc - b
    ex = px + s * d0
    ey = py + s * d1
    ez = qz + s * d2
    den = ex * d0 + ey * d1 + ez * d2
    if den <= 0.0:
        return s, 0.0
    return s, ez / den


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def sphere_contact(x, v, dvc, mass, free, snodes, scr, cx, cy, Z, V, R, M, mu, dt):
    """Close all gaps between nodes ``snodes`` and the sphere (centre (cx, cy, Z), radius R).

    x, v: trial positions x^{n+1} and velocities v^{n+1/2} (modified in place); dvc (n, 3)
    accumulates the velocity corrections; scr (len(snodes), 9) scratch; Z, V: trial sphere
    position and velocity; M its mass (kg); dt = dt_{n+1/2} (s). Returns (dZ, dV, penetration):
    the sphere's position and velocity corrections and the largest penetration left (m).
    """
    na = 0
    R2 = R * R
    for k in range(snodes.shape[0]):
        I = snodes[k]
        px = x[I, 0] - cx
        py = x[I, 1] - cy
        pz = x[I, 2] - Z
        d2 = px * px + py * py + pz * pz
        if d2 >= R2 or pz >= 0.0:
            continue
        d = math.sqrt(d2)
        u0 = px / d * free[I, 0]
        u1 = py / d * free[I, 1]
        u2 = pz / d * free[I, 2]
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
        scr[na, 8] = pz / d                # n_Iz
        na += 1
    if na == 0:
        return 0.0, 0.0, 0.0
    # h(dz) = dz + sum_I q_I(dz) n_Iz / M is increasing, h(0) <= 0, h(-h(0)) >= 0
    h0 = 0.0
    dh0 = 1.0
    for k in range(na):
        s, ds = _sphere_root(scr[k, 1], scr[k, 2], scr[k, 3], scr[k, 4], scr[k, 5], scr[k, 6], R, 0.0)
        c = scr[k, 7] * scr[k, 8] / M
        h0 += c * s
        dh0 += c * ds
    lo = 0.0
    hi = -h0
    dz = 0.0
    if hi > 0.0:
        dz = -h0 / dh0                      # linearised (Sherman-Morrison) estimate, in (0, hi]
        for _it in range(100):
            h = dz
            dh = 1.0
            for k in range(na):
                s, ds = _sphere_root(scr[k, 1], scr[k, 2], scr[k, 3], scr[k, 4], scr[k, 5],
                                     scr[k, 6], R, dz)
                c = scr[k, 7] * scr[k, 8] / M
                h += c * s
                dh += c * ds
            if h < 0.0:
                lo = dz
            else:
                hi = dz
            if abs(h) <= 1e-16 * abs(dz) or hi - lo <= 4e-16 * hi:
                break
            nxt = dz - h / dh
            if not (nxt > lo and nxt < hi):
                nxt = 0.5 * (lo + hi)
            dz = nxt
    # apply: nodes land on the sphere moved by dz; the sphere moves by -sum q n_z / M exactly
    sq = 0.0
    for k in range(na):
        s, _ = _sphere_root(scr[k, 1], scr[k, 2], scr[k, 3], scr[k, 4], scr[k, 5], scr[k, 6], R, dz)
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
        sq += q * scr[k, 8]
    dZ = -sq / M
    dV = dZ / dt
    if mu > 0.0:
        for k in range(na):
            q = scr[k, 7]
            if q <= 0.0:
                continue
            I = int(scr[k, 0])
            px = x[I, 0] - cx
            py = x[I, 1] - cy
            pz = x[I, 2] - (Z + dZ)
            d = math.sqrt(px * px + py * py + pz * pz)
            nx = px / d
            ny = py / d
            nz = pz / d
            r0 = v[I, 0]
            r1 = v[I, 1]
            r2 = v[I, 2] - (V + dV)
            rn = r0 * nx + r1 * ny + r2 * nz
            t0 = (r0 - rn * nx) * free[I, 0]
            t1 = (r1 - rn * ny) * free[I, 1]
            t2 = (r2 - rn * nz) * free[I, 2]
            tn = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
            if tn == 0.0:
                continue
            m = mass[I]
            fac = min(1.0, mu * (q / dt) / (m * tn))
            v[I, 0] -= fac * t0
            v[I, 1] -= fac * t1
            v[I, 2] -= fac * t2
            x[I, 0] -= fac * t0 * dt
            x[I, 1] -= fac * t1 * dt
            x[I, 2] -= fac * t2 * dt
            dvc[I, 0] -= fac * t0
            dvc[I, 1] -= fac * t1
            dvc[I, 2] -= fac * t2
            dV += m * fac * t2 / M
            dZ += m * fac * t2 * dt / M
    # largest remaining penetration (m), for the record
    pen = 0.0
    Zn = Z + dZ
    for k in range(snodes.shape[0]):
        I = snodes[k]
        px = x[I, 0] - cx
        py = x[I, 1] - cy
        pz = x[I, 2] - Zn
        if pz >= 0.0:
            continue
        g = R - math.sqrt(px * px + py * py + pz * pz)
        if g > pen:
            pen = g
    return dZ, dV, pen


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def plane_contact(x, v, dvc, mass, free, pnodes, z0, mu, dt):
    """Nodes ``pnodes`` below the plane z = z0 are put back onto it (kinematic constraint).

    dz = z0 - z, dv_z = dz / dt; with friction the in-plane velocity is removed (stick) or
    reduced by mu |dv_z| (slip). Modifies x, v, dvc in place.
    """
    for k in range(pnodes.shape[0]):
        I = pnodes[k]
        if free[I, 2] == 0.0 or x[I, 2] >= z0:
            continue
        dz = z0 - x[I, 2]
        x[I, 2] = z0
        dvz = dz / dt
        v[I, 2] += dvz
        dvc[I, 2] += dvz
        if mu > 0.0:
            t0 = v[I, 0] * free[I, 0]
            t1 = v[I, 1] * free[I, 1]
            tn = math.sqrt(t0 * t0 + t1 * t1)
            if tn > 0.0:
                fac = min(1.0, mu * dvz / tn)
                v[I, 0] -= fac * t0
                v[I, 1] -= fac * t1
                x[I, 0] -= fac * t0 * dt
                x[I, 1] -= fac * t1 * dt
                dvc[I, 0] -= fac * t0
                dvc[I, 1] -= fac * t1
