"""Element and node loops of the explicit solver (numba, parallel over elements / nodes).

Total Lagrangian hex8 with one-point integration (Flanagan & Belytschko 1981):

    F = sum_I x_I (x) B_I,  B_I = (1/V0) int dN_I/dX dV0   (uniform gradient, reference config.)
    f_I^int = V0 P B_I,  P = F S                           (N)

Viscous hourglass control with the 4 hourglass vectors gamma_alpha (orthogonal to the linear
field in the reference configuration):

    q_alpha = sum_I v_I gamma_alpha,I  (m/s),   f_I^hg = -c_hg sum_alpha q_alpha gamma_alpha,I
    c_hg = Q_hg rho c V0^(2/3) / 4  (kg/s)

with c the current isochoric ("shear-type") wave speed sqrt(M_iso / rho) by default, or the
full longitudinal one. Element forces go to a per-element array (e, 8, 6) (internal, hourglass);
a node-parallel gather through the node -> element incidence (CSR) sums them without write
conflicts.
"""

# >>> standalone (removed when the kernels are concatenated into a generated module)
import math

import numpy as np
from numba import njit, prange

from .constitutive import ST_INVERTED, ST_NONFINITE, ST_OK, first_piola, principal_stress, psi_grad_hess_diag_v
from .eigen import eig3, eig3_hybrid
from .layout import FASTMATH
# <<< standalone


# Elements are processed in blocks of BLOCK: each stage of the element update is one loop over
# the block's columns of a work array, so that LLVM vectorises the eigen-decomposition and the
# material across elements (those stages have no calls and no branches). The work array is flat,
# wk[row * BLOCK + i] with the rows W_* below: row offsets are compile-time constants, so LLVM
# proves that a stage's stores never overlap its loads (with a 2-D array it would need a run-time
# overlap check per pair of rows, and gives up).
BLOCK = 32
W_F = 0         # F, 9 rows (row-major)
W_Q = 9         # hourglass modes q_alpha,i, 12 rows (alpha-major)
W_C = 21        # C = F^T F, 6 rows (11, 22, 33, 12, 23, 13)
W_J = 27        # det F
W_M = 28        # eigenvalues of C, 3 rows
W_V = 31        # eigenvectors of C (columns of Q, row-major), 9 rows
W_OK = 40       # 1 where the branch-free eigen-decomposition applied
W_R = 41        # psi_grad_hess_diag, 12 rows
W_N = 53


@njit(parallel=True, cache=True, fastmath=FASTMATH, error_model="numpy")
def element_pass(x, v, conn, B, G, V0, L, hgfac, p, decay, gain, ginf, H, S0old, Sold, Eold,
                 fe, dte, status, errv, rho, hg, hgwave):
    """Stresses, nodal forces, stable steps and the stress work of all elements at one state.

    x, v: (n, 3) positions x^n and velocities v^{n-1/2}; decay, gain: Prony factors of the step
    since the previous call (see ``prony_step``); hg: Q_hg; hgwave: 0 isochoric, 1 full modulus.
    Writes fe (e, 8, 6): internal (0:3) and hourglass (3:6) nodal forces (N), dte (e,) = L / c
    (s), status (e,), errv (e, 4) = (J, m0, m1, m2) at failures; updates the Prony state and
    Sold, Eold (e, 6). Returns (stress work increment (J), number of failures).
    """
    ne = conn.shape[0]
    nblk = (ne + BLOCK - 1) // BLOCK
    work = 0.0
    nbad = 0
    for blk in prange(nblk):
        wb, nb = element_block(blk * BLOCK, min(BLOCK, ne - blk * BLOCK), x, v, conn, B, G, V0, L,
                               hgfac, p, decay, gain, ginf, H, S0old, Sold, Eold, fe, dte, status,
                               errv, rho, hg, hgwave)
        work += wb
        nbad += nb
    return work, nbad


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def element_block(e0, n, x, v, conn, B, G, V0, L, hgfac, p, decay, gain, ginf, H, S0old, Sold,
                  Eold, fe, dte, status, errv, rho, hg, hgwave):
    """:func:`element_pass` for the n elements from e0 (one block); returns (work (J), failures)."""
    wk = np.empty(W_N * BLOCK)
    # 1. one sweep over the nodes: F = sum x_a (x) B_a and the hourglass modes q = sum v_a G_a
    for i in range(n):
        e = e0 + i
        f00 = 0.0
        f01 = 0.0
        f02 = 0.0
        f10 = 0.0
        f11 = 0.0
        f12 = 0.0
        f20 = 0.0
        f21 = 0.0
        f22 = 0.0
        q00 = 0.0
        q01 = 0.0
        q02 = 0.0
        q10 = 0.0
        q11 = 0.0
        q12 = 0.0
        q20 = 0.0
        q21 = 0.0
        q22 = 0.0
        q30 = 0.0
        q31 = 0.0
        q32 = 0.0
        for a in range(8):
            nd = conn[e, a]
            x0 = x[nd, 0]
            x1 = x[nd, 1]
            x2 = x[nd, 2]
            b0 = B[e, a, 0]
            b1 = B[e, a, 1]
            b2 = B[e, a, 2]
            f00 += x0 * b0
            f01 += x0 * b1
            f02 += x0 * b2
            f10 += x1 * b0
            f11 += x1 * b1
            f12 += x1 * b2
            f20 += x2 * b0
            f21 += x2 * b1
            f22 += x2 * b2
            v0 = v[nd, 0]
            v1 = v[nd, 1]
            v2 = v[nd, 2]
            g0 = G[e, a, 0]
            g1 = G[e, a, 1]
            g2 = G[e, a, 2]
            g3 = G[e, a, 3]
            q00 += v0 * g0
            q01 += v1 * g0
            q02 += v2 * g0
            q10 += v0 * g1
            q11 += v1 * g1
            q12 += v2 * g1
            q20 += v0 * g2
            q21 += v1 * g2
            q22 += v2 * g2
            q30 += v0 * g3
            q31 += v1 * g3
            q32 += v2 * g3
        wk[W_F * BLOCK + i] = f00
        wk[(W_F + 1) * BLOCK + i] = f01
        wk[(W_F + 2) * BLOCK + i] = f02
        wk[(W_F + 3) * BLOCK + i] = f10
        wk[(W_F + 4) * BLOCK + i] = f11
        wk[(W_F + 5) * BLOCK + i] = f12
        wk[(W_F + 6) * BLOCK + i] = f20
        wk[(W_F + 7) * BLOCK + i] = f21
        wk[(W_F + 8) * BLOCK + i] = f22
        wk[W_Q * BLOCK + i] = q00
        wk[(W_Q + 1) * BLOCK + i] = q01
        wk[(W_Q + 2) * BLOCK + i] = q02
        wk[(W_Q + 3) * BLOCK + i] = q10
        wk[(W_Q + 4) * BLOCK + i] = q11
        wk[(W_Q + 5) * BLOCK + i] = q12
        wk[(W_Q + 6) * BLOCK + i] = q20
        wk[(W_Q + 7) * BLOCK + i] = q21
        wk[(W_Q + 8) * BLOCK + i] = q22
        wk[(W_Q + 9) * BLOCK + i] = q30
        wk[(W_Q + 10) * BLOCK + i] = q31
        wk[(W_Q + 11) * BLOCK + i] = q32
    # 2. J, C and its eigen-decomposition (vectorised; the rare rest below, one by one)
    eigen_block(wk, n)
    for i in range(n):
        if wk[W_OK * BLOCK + i] == 0.0 or not (wk[W_J * BLOCK + i] > 0.0):
            # isotropic states (the undeformed one) and non-finite values: the scalar path;
            # an inverted element keeps finite placeholders for the material stage
            m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22 = eig3(
                wk[W_C * BLOCK + i], wk[(W_C + 3) * BLOCK + i], wk[(W_C + 5) * BLOCK + i], wk[(W_C + 1) * BLOCK + i], wk[(W_C + 4) * BLOCK + i], wk[(W_C + 2) * BLOCK + i])
            if not (wk[W_J * BLOCK + i] > 0.0) or not math.isfinite(wk[W_J * BLOCK + i]):
                m0 = 1.0
                m1 = 1.0
                m2 = 1.0
            wk[W_M * BLOCK + i] = m0
            wk[(W_M + 1) * BLOCK + i] = m1
            wk[(W_M + 2) * BLOCK + i] = m2
            wk[W_V * BLOCK + i] = q00
            wk[(W_V + 1) * BLOCK + i] = q01
            wk[(W_V + 2) * BLOCK + i] = q02
            wk[(W_V + 3) * BLOCK + i] = q10
            wk[(W_V + 4) * BLOCK + i] = q11
            wk[(W_V + 5) * BLOCK + i] = q12
            wk[(W_V + 6) * BLOCK + i] = q20
            wk[(W_V + 7) * BLOCK + i] = q21
            wk[(W_V + 8) * BLOCK + i] = q22
    # 3. the material's derivatives (vectorised)
    material_block(wk, p, n)
    # 4. stress, Prony, forces and stress work, element by element
    wb = 0.0
    nb = 0
    for i in range(n):
        e = e0 + i
        J = wk[W_J * BLOCK + i]
        m0 = wk[W_M * BLOCK + i]
        m1 = wk[(W_M + 1) * BLOCK + i]
        m2 = wk[(W_M + 2) * BLOCK + i]
        st = ST_OK
        s00 = s11 = s22 = s01 = s12 = s02 = mt = mi = 0.0
        if not (J > 0.0) or not math.isfinite(J):
            st = ST_INVERTED
            m0 = 0.0
            m1 = 0.0
            m2 = 0.0
        else:
            (st, s00, s11, s22, s01, s12, s02, mt, mi) = principal_stress(
                m0, m1, m2, wk[W_V * BLOCK + i], wk[(W_V + 1) * BLOCK + i], wk[(W_V + 2) * BLOCK + i], wk[(W_V + 3) * BLOCK + i],
                wk[(W_V + 4) * BLOCK + i], wk[(W_V + 5) * BLOCK + i], wk[(W_V + 6) * BLOCK + i], wk[(W_V + 7) * BLOCK + i], wk[(W_V + 8) * BLOCK + i],
                wk[W_R * BLOCK + i], wk[(W_R + 1) * BLOCK + i], wk[(W_R + 2) * BLOCK + i], wk[(W_R + 3) * BLOCK + i], wk[(W_R + 4) * BLOCK + i],
                wk[(W_R + 5) * BLOCK + i], wk[(W_R + 6) * BLOCK + i], wk[(W_R + 7) * BLOCK + i], wk[(W_R + 8) * BLOCK + i], wk[(W_R + 9) * BLOCK + i],
                wk[(W_R + 10) * BLOCK + i], wk[(W_R + 11) * BLOCK + i], decay, gain, ginf, H[e], S0old[e])
            if st == ST_OK and not math.isfinite(s00 + s11 + s22 + s01 + s12 + s02 + mt):
                st = ST_NONFINITE
        if st != ST_OK:
            status[e] = st
            errv[e, 0] = J
            errv[e, 1] = m0
            errv[e, 2] = m1
            errv[e, 3] = m2
            dte[e] = np.inf
            for a in range(8):
                for c in range(6):
                    fe[e, a, c] = 0.0
            nb += 1
            continue
        # stable step L / c with c the longitudinal wave speed (reference density)
        dte[e] = L[e] / math.sqrt(mt / rho) if mt > 0.0 else np.inf
        # hourglass damping coefficient c_hg = Q_hg rho c V0^(2/3) / 4 (hgfac = rho V0^(2/3) / 4)
        chg = 0.0
        if hg > 0.0:
            mod = mi if hgwave == 0 else mt
            if mod > 0.0:
                chg = -hg * hgfac[e] * math.sqrt(mod / rho)
        # first Piola-Kirchhoff P = F S; nodal forces V0 P B_a and -c_hg sum_alpha q_alpha G_a,alpha
        f00 = wk[W_F * BLOCK + i]
        f01 = wk[(W_F + 1) * BLOCK + i]
        f02 = wk[(W_F + 2) * BLOCK + i]
        f10 = wk[(W_F + 3) * BLOCK + i]
        f11 = wk[(W_F + 4) * BLOCK + i]
        f12 = wk[(W_F + 5) * BLOCK + i]
        f20 = wk[(W_F + 6) * BLOCK + i]
        f21 = wk[(W_F + 7) * BLOCK + i]
        f22 = wk[(W_F + 8) * BLOCK + i]
        p00, p01, p02, p10, p11, p12, p20, p21, p22 = first_piola(f00, f01, f02, f10, f11, f12, f20, f21, f22,
                                                                  s00, s11, s22, s01, s12, s02)
        q00 = wk[W_Q * BLOCK + i]
        q01 = wk[(W_Q + 1) * BLOCK + i]
        q02 = wk[(W_Q + 2) * BLOCK + i]
        q10 = wk[(W_Q + 3) * BLOCK + i]
        q11 = wk[(W_Q + 4) * BLOCK + i]
        q12 = wk[(W_Q + 5) * BLOCK + i]
        q20 = wk[(W_Q + 6) * BLOCK + i]
        q21 = wk[(W_Q + 7) * BLOCK + i]
        q22 = wk[(W_Q + 8) * BLOCK + i]
        q30 = wk[(W_Q + 9) * BLOCK + i]
        q31 = wk[(W_Q + 10) * BLOCK + i]
        q32 = wk[(W_Q + 11) * BLOCK + i]
        vol = V0[e]
        for a in range(8):
            b0 = B[e, a, 0] * vol
            b1 = B[e, a, 1] * vol
            b2 = B[e, a, 2] * vol
            fe[e, a, 0] = p00 * b0 + p01 * b1 + p02 * b2
            fe[e, a, 1] = p10 * b0 + p11 * b1 + p12 * b2
            fe[e, a, 2] = p20 * b0 + p21 * b1 + p22 * b2
            g0 = G[e, a, 0] * chg
            g1 = G[e, a, 1] * chg
            g2 = G[e, a, 2] * chg
            g3 = G[e, a, 3] * chg
            fe[e, a, 3] = q00 * g0 + q10 * g1 + q20 * g2 + q30 * g3
            fe[e, a, 4] = q01 * g0 + q11 * g1 + q21 * g2 + q31 * g3
            fe[e, a, 5] = q02 * g0 + q12 * g1 + q22 * g2 + q32 * g3
        # stress work, trapezoid in time: V0 (S_old + S) / 2 : (E - E_old), E = (C - I) / 2
        e00 = 0.5 * (wk[W_C * BLOCK + i] - 1.0)
        e11 = 0.5 * (wk[(W_C + 1) * BLOCK + i] - 1.0)
        e22 = 0.5 * (wk[(W_C + 2) * BLOCK + i] - 1.0)
        e01 = 0.5 * wk[(W_C + 3) * BLOCK + i]
        e12 = 0.5 * wk[(W_C + 4) * BLOCK + i]
        e02 = 0.5 * wk[(W_C + 5) * BLOCK + i]
        so = Sold[e]
        eo = Eold[e]
        w = ((so[0] + s00) * (e00 - eo[0]) + (so[1] + s11) * (e11 - eo[1])
             + (so[2] + s22) * (e22 - eo[2])
             + 2.0 * ((so[3] + s01) * (e01 - eo[3]) + (so[4] + s12) * (e12 - eo[4])
                      + (so[5] + s02) * (e02 - eo[5])))
        wb += 0.5 * vol * w
        so[0] = s00
        so[1] = s11
        so[2] = s22
        so[3] = s01
        so[4] = s12
        so[5] = s02
        eo[0] = e00
        eo[1] = e11
        eo[2] = e22
        eo[3] = e01
        eo[4] = e12
        eo[5] = e02
    return wb, nb


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def eigen_block(wk, n):
    """J = det F, C = F^T F and the branch-free eigen-decomposition of C for the first n columns
    of a block's work array (rows W_F in; W_C, W_J, W_M, W_V, W_OK out). A function of its own:
    LLVM vectorises this loop alone, not inside the larger element_block."""
    for i in range(n):
        f00 = wk[W_F * BLOCK + i]
        f01 = wk[(W_F + 1) * BLOCK + i]
        f02 = wk[(W_F + 2) * BLOCK + i]
        f10 = wk[(W_F + 3) * BLOCK + i]
        f11 = wk[(W_F + 4) * BLOCK + i]
        f12 = wk[(W_F + 5) * BLOCK + i]
        f20 = wk[(W_F + 6) * BLOCK + i]
        f21 = wk[(W_F + 7) * BLOCK + i]
        f22 = wk[(W_F + 8) * BLOCK + i]
        J = (f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20)
             + f02 * (f10 * f21 - f11 * f20))
        c00 = f00 * f00 + f10 * f10 + f20 * f20
        c11 = f01 * f01 + f11 * f11 + f21 * f21
        c22 = f02 * f02 + f12 * f12 + f22 * f22
        c01 = f00 * f01 + f10 * f11 + f20 * f21
        c12 = f01 * f02 + f11 * f12 + f21 * f22
        c02 = f00 * f02 + f10 * f12 + f20 * f22
        (ok, m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22) = eig3_hybrid(
            c00, c01, c02, c11, c12, c22)
        wk[W_C * BLOCK + i] = c00
        wk[(W_C + 1) * BLOCK + i] = c11
        wk[(W_C + 2) * BLOCK + i] = c22
        wk[(W_C + 3) * BLOCK + i] = c01
        wk[(W_C + 4) * BLOCK + i] = c12
        wk[(W_C + 5) * BLOCK + i] = c02
        wk[W_J * BLOCK + i] = J
        wk[W_M * BLOCK + i] = m0
        wk[(W_M + 1) * BLOCK + i] = m1
        wk[(W_M + 2) * BLOCK + i] = m2
        wk[W_V * BLOCK + i] = q00
        wk[(W_V + 1) * BLOCK + i] = q01
        wk[(W_V + 2) * BLOCK + i] = q02
        wk[(W_V + 3) * BLOCK + i] = q10
        wk[(W_V + 4) * BLOCK + i] = q11
        wk[(W_V + 5) * BLOCK + i] = q12
        wk[(W_V + 6) * BLOCK + i] = q20
        wk[(W_V + 7) * BLOCK + i] = q21
        wk[(W_V + 8) * BLOCK + i] = q22
        wk[W_OK * BLOCK + i] = 1.0 if ok else 0.0


@njit(cache=True, error_model="numpy")
def material_block(wk, p, n):
    """The material's derivatives for the first n columns of a block's work array: rows W_M..
    W_M+2 hold the eigenvalues m of C, rows W_R..W_R+11 receive psi_grad_hess_diag's 12 values.
    IEEE maths, no fast-math flags (as the scalar material functions: zero stress at the
    reference state to the bit); one loop with the vectorisable variant of the generated code
    (``codegen.vector_source``)."""
    for i in range(n):
        r = psi_grad_hess_diag_v(wk[W_M * BLOCK + i], wk[(W_M + 1) * BLOCK + i], wk[(W_M + 2) * BLOCK + i], p)
        wk[W_R * BLOCK + i] = r[0]
        wk[(W_R + 1) * BLOCK + i] = r[1]
        wk[(W_R + 2) * BLOCK + i] = r[2]
        wk[(W_R + 3) * BLOCK + i] = r[3]
        wk[(W_R + 4) * BLOCK + i] = r[4]
        wk[(W_R + 5) * BLOCK + i] = r[5]
        wk[(W_R + 6) * BLOCK + i] = r[6]
        wk[(W_R + 7) * BLOCK + i] = r[7]
        wk[(W_R + 8) * BLOCK + i] = r[8]
        wk[(W_R + 9) * BLOCK + i] = r[9]
        wk[(W_R + 10) * BLOCK + i] = r[10]
        wk[(W_R + 11) * BLOCK + i] = r[11]


@njit(parallel=True, cache=True, fastmath=FASTMATH, error_model="numpy")
def gather_update(ef, ptr, inc, mass, free, fint, fhg, x, v, vold, dtn, dt):
    """Sum element forces per node, then central differences on the free dofs.

    ef (8e, 6): the element forces fe viewed as rows e * 8 + a; ptr, inc: CSR incidence of
    node -> rows. fint, fhg (n, 3) receive the nodal internal and hourglass forces (N); vold the
    velocities v^{n-1/2}; v becomes v^{n+1/2} = v^{n-1/2} + dtn (f^hg - f^int) / m on free dofs
    (0 on fixed and prescribed ones); x becomes the trial x^{n+1} = x^n + dt v^{n+1/2}.
    """
    nn = x.shape[0]
    for n in prange(nn):
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        h0 = 0.0
        h1 = 0.0
        h2 = 0.0
        for k in range(ptr[n], ptr[n + 1]):
            r = inc[k]
            s0 += ef[r, 0]
            s1 += ef[r, 1]
            s2 += ef[r, 2]
            h0 += ef[r, 3]
            h1 += ef[r, 4]
            h2 += ef[r, 5]
        fint[n, 0] = s0
        fint[n, 1] = s1
        fint[n, 2] = s2
        fhg[n, 0] = h0
        fhg[n, 1] = h1
        fhg[n, 2] = h2
        c = dtn / mass[n]
        for i in range(3):
            vo = v[n, i]
            vold[n, i] = vo
            vn = (vo + c * (fhg[n, i] - fint[n, i])) * free[n, i]
            v[n, i] = vn
            x[n, i] += dt * vn


@njit(parallel=True, cache=True, fastmath=FASTMATH, error_model="numpy")
def energy_pass(mass, v, vold, fint, fhg, dvc, pmask, dtn):
    """Kinetic energy at t^n and the work of each force family around t^n (J, modelled part).

    Kinetic energy: the leapfrog's own, T^n = 1/2 sum m v^{n-1/2} . v^{n+1/2} (from the two
    mid-step velocities around t^n). Work of a force f^n: A = dtn/2 f^n . v^{n-1/2} (the part
    belonging to the interval before t^n) and B = dtn/2 f^n . v^{n+1/2} (after). Since
    m (v^{n+1/2} - v^{n-1/2}) = dtn f^n, T^n - T^{n-1} = A^n + B^{n-1} summed over all forces,
    exactly: the force works balance the kinetic energy to round-off, so the energy balance
    checks the internal energy (trapezoid stress work, independent of the nodal forces). For
    constant dt, B^{n-1} + A^n is the trapezoid rule 1/2 (f^{n-1} + f^n) . (x^n - x^{n-1}), and
    for a linear elastic model the balance is exact (the leapfrog conserves this energy).
    Forces: internal -fint, hourglass fhg, contact m dvc / dtn, and on prescribed dofs (pmask)
    the reaction imposing the motion (external).
    Returns (T, A_int, B_int, A_hg, B_hg, A_c, B_c, A_ext, B_ext, momentum_z at n+1/2).
    """
    nn = v.shape[0]
    h = 0.5 * dtn
    ke = 0.0
    ai = 0.0
    bi = 0.0
    ah = 0.0
    bh = 0.0
    ac = 0.0
    bc = 0.0
    ax = 0.0
    bx = 0.0
    pz = 0.0
    for n in prange(nn):
        m = mass[n]
        kn = 0.0
        ain = 0.0
        bin_ = 0.0
        ahn = 0.0
        bhn = 0.0
        acn = 0.0
        bcn = 0.0
        axn = 0.0
        bxn = 0.0
        for i in range(3):
            vo = vold[n, i]
            vh = v[n, i]
            kn += vo * vh
            fi = -h * fint[n, i]
            fhh = h * fhg[n, i]
            fc = 0.5 * m * dvc[n, i]
            ain += fi * vo
            bin_ += fi * vh
            ahn += fhh * vo
            bhn += fhh * vh
            acn += fc * vo
            bcn += fc * vh
            if pmask[n, i] != 0.0:
                fx = 0.5 * m * (vh - vo) - (fi + fhh + fc)
                axn += fx * vo
                bxn += fx * vh
        ke += 0.5 * m * kn
        ai += ain
        bi += bin_
        ah += ahn
        bh += bhn
        ac += acn
        bc += bcn
        ax += axn
        bx += bxn
        pz += m * v[n, 2]
    return ke, ai, bi, ah, bh, ac, bc, ax, bx, pz
