"""Compiled Gauss-point work of the implicit hex8 element (numba, the project's own code).

This file is concatenated after a material's generated scalar code (``psi_grad``, ``psi_hess``
from :meth:`cfm_core.material.Material.numba_source`) into one generated module by
:mod:`.compiled`; every function is ``njit(cache=True)``. It computes what the numpy reference
path (:mod:`.element` with :mod:`.constitutive`) computes, element by element, without temporary
arrays:

- F = I + sum_a u_a (x) dN_a, J = det F (J <= 0: status 1), C = F^T F = Q diag(m) Q^T (cyclic
  Jacobi, exact for diagonal and repeated eigenvalues);
- S0_iso = Q diag(2 psi_a) Q^T, Prony recurrence on it (DESIGN.md section 2), S (Pa);
- D = 2 dS/dC in Voigt form (Pa): D_IJ = f_eff [sum_ab 4 psi_ab Na_a(I) Na_b(J)
  + sum_(a<b) 2 theta_ab M_ab(I) M_ab(J)], Na_a(ij) = Q_ia Q_ja, M_ab(ij) = Q_ia Q_jb + Q_ib Q_ja,
  theta_ab = (psi_a - psi_b) / (m_a - m_b), or (psi_aa + psi_bb)/2 - psi_ab when the relative gap is
  below 1e-4 (the same rule as :func:`cfm_core.kinematics.tangent_from_principal`);
- f_e = sum_q w_q B^T S, K_e = sum_q w_q (B^T D B + geometric term), plus the mean-dilatation
  volumetric part (see :mod:`.element` for the equations).

Symmetric tensors are 6-vectors in the order 11, 22, 33, 12, 23, 13 (tensor components for
stresses; B gives engineering shear strains).
"""

# >>> standalone (removed when the kernels are concatenated into a generated module)
import math

import numpy as np
from numba import njit, prange


@njit(cache=True)
def psi_grad(m1, m2, m3, p):  # stub: generated modules define it from the material
    return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0


@njit(cache=True)
def psi_hess(m1, m2, m3, p):  # stub: generated modules define it from the material
    return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
# <<< standalone

ST_OK = 0
ST_INVERTED = 1
ST_NONFINITE = 2
THETA_TOL = 1e-4
VI = (0, 1, 2, 0, 1, 0)
VJ = (0, 1, 2, 1, 2, 2)


@njit(cache=True, error_model="numpy")
def eig_sym3(A, Q, m):
    """Eigen-decomposition of the symmetric 3 x 3 matrix A (overwritten): A = Q diag(m) Q^T.

    Cyclic Jacobi (Numerical Recipes 11.1) to a relative off-diagonal of 1e-18; a diagonal input
    (the reference state, uniaxial states along the axes) returns Q = I exactly.
    """
    for i in range(3):
        for j in range(3):
            Q[i, j] = 1.0 if i == j else 0.0
    for _sweep in range(20):
        off = abs(A[0, 1]) + abs(A[0, 2]) + abs(A[1, 2])
        if off <= 1e-18 * (abs(A[0, 0]) + abs(A[1, 1]) + abs(A[2, 2])):
            break
        for p in range(2):
            for q in range(p + 1, 3):
                apq = A[p, q]
                if apq == 0.0:
                    continue
                theta = (A[q, q] - A[p, p]) / (2.0 * apq)
                at = abs(theta)
                if at > 1e150:
                    t = 0.5 / theta
                else:
                    t = 1.0 / (at + math.sqrt(theta * theta + 1.0))
                    if theta < 0.0:
                        t = -t
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                A[p, p] -= t * apq
                A[q, q] += t * apq
                A[p, q] = 0.0
                A[q, p] = 0.0
                r = 3 - p - q
                arp = A[r, p]
                arq = A[r, q]
                A[r, p] = c * arp - s * arq
                A[p, r] = A[r, p]
                A[r, q] = s * arp + c * arq
                A[q, r] = A[r, q]
                for k in range(3):
                    qkp = Q[k, p]
                    qkq = Q[k, q]
                    Q[k, p] = c * qkp - s * qkq
                    Q[k, q] = s * qkp + c * qkq
    for i in range(3):
        m[i] = A[i, i]


@njit(cache=True, error_model="numpy")
def material_point(F, p, decay, gain, ginf, feff, Hq, S0q, full, tangent, S, D, A, Q, H, m, th, Na, M):
    """Stress S (6,) and tangent D (6, 6) (Pa) at one Gauss point; updates Hq (k, 6), S0q (6,).

    F (3, 3); decay, gain (k,): the step's Prony factors (:func:`cfm_core.prony.step_factors`);
    ginf = 1 - sum gamma; feff = ginf + sum gain (consistent tangent factor); full: add the
    volumetric term here (material points, the "full" element). Returns the status (0 ok,
    2 non-finite material derivative). A, Q, H (3, 3), m, th (3,), Na, M (3, 6) are scratch.
    """
    for i in range(3):
        for j in range(3):
            A[i, j] = F[0, i] * F[0, j] + F[1, i] * F[1, j] + F[2, i] * F[2, j]
    eig_sym3(A, Q, m)
    g = psi_grad(m[0], m[1], m[2], p)
    chk = g[0] + g[1] + g[2] + g[3] + g[4] + g[5]
    if not math.isfinite(chk):
        return ST_NONFINITE
    ga0 = 2.0 * g[0]
    ga1 = 2.0 * g[1]
    ga2 = 2.0 * g[2]
    k = decay.shape[0]
    for v in range(6):
        i = VI[v]
        j = VJ[v]
        s0 = ga0 * Q[i, 0] * Q[j, 0] + ga1 * Q[i, 1] * Q[j, 1] + ga2 * Q[i, 2] * Q[j, 2]
        if k > 0:
            d = s0 - S0q[v]
            S0q[v] = s0
            s = ginf * s0
            for r in range(k):
                Hq[r, v] = decay[r] * Hq[r, v] + gain[r] * d
                s += Hq[r, v]
        else:
            s = s0
        if full:
            s += 2.0 * (g[3] * Q[i, 0] * Q[j, 0] + g[4] * Q[i, 1] * Q[j, 1] + g[5] * Q[i, 2] * Q[j, 2])
        S[v] = s
    if not tangent:
        return ST_OK
    h = psi_hess(m[0], m[1], m[2], p)
    chk = h[0] + h[1] + h[2] + h[3] + h[4] + h[5] + h[6] + h[7] + h[8] + h[9] + h[10] + h[11]
    if not math.isfinite(chk):
        return ST_NONFINITE
    fi = feff if k > 0 else 1.0
    fv = 1.0 if full else 0.0
    gt0 = fi * g[0] + fv * g[3]
    gt1 = fi * g[1] + fv * g[4]
    gt2 = fi * g[2] + fv * g[5]
    H[0, 0] = fi * h[0] + fv * h[6]
    H[1, 1] = fi * h[1] + fv * h[7]
    H[2, 2] = fi * h[2] + fv * h[8]
    H[0, 1] = fi * h[3] + fv * h[9]
    H[1, 2] = fi * h[4] + fv * h[10]
    H[0, 2] = fi * h[5] + fv * h[11]
    H[1, 0] = H[0, 1]
    H[2, 1] = H[1, 2]
    H[2, 0] = H[0, 2]
    gt = (gt0, gt1, gt2)
    for kk in range(3):  # pairs (0,1), (1,2), (0,2)
        a = 0 if kk != 1 else 1
        b = 1 if kk == 0 else 2
        dm = m[a] - m[b]
        if abs(dm) <= THETA_TOL * max(abs(m[a]), abs(m[b])):
            th[kk] = 0.5 * (H[a, a] + H[b, b]) - H[a, b]
        else:
            th[kk] = (gt[a] - gt[b]) / dm
    for v in range(6):
        i = VI[v]
        j = VJ[v]
        for a in range(3):
            Na[a, v] = Q[i, a] * Q[j, a]
        M[0, v] = Q[i, 0] * Q[j, 1] + Q[i, 1] * Q[j, 0]
        M[1, v] = Q[i, 1] * Q[j, 2] + Q[i, 2] * Q[j, 1]
        M[2, v] = Q[i, 0] * Q[j, 2] + Q[i, 2] * Q[j, 0]
    for v in range(6):
        hv0 = 4.0 * (H[0, 0] * Na[0, v] + H[0, 1] * Na[1, v] + H[0, 2] * Na[2, v])
        hv1 = 4.0 * (H[1, 0] * Na[0, v] + H[1, 1] * Na[1, v] + H[1, 2] * Na[2, v])
        hv2 = 4.0 * (H[2, 0] * Na[0, v] + H[2, 1] * Na[1, v] + H[2, 2] * Na[2, v])
        t0 = 2.0 * th[0] * M[0, v]
        t1 = 2.0 * th[1] * M[1, v]
        t2 = 2.0 * th[2] * M[2, v]
        for u in range(v, 6):
            val = (hv0 * Na[0, u] + hv1 * Na[1, u] + hv2 * Na[2, u]
                   + t0 * M[0, u] + t1 * M[1, u] + t2 * M[2, u])
            D[v, u] = val
            D[u, v] = val
    return ST_OK


@njit(cache=True, error_model="numpy")
def volumetric_derivatives(theta, p):
    """(U', U'') of the volumetric term at J = theta (Pa), from the generated psi_grad / psi_hess.

    At the isotropic state m_a = theta^(2/3): dU = 2 m psi_vol,1 / theta and
    d2U = (4 m^2 psi_vol,12 - dU theta) / theta^2 (as :meth:`.constitutive.Constitutive.volumetric`).
    """
    mm = theta ** (2.0 / 3.0)
    g = psi_grad(mm, mm, mm, p)
    h = psi_hess(mm, mm, mm, p)
    dU = 2.0 * mm * g[3] / theta
    d2U = (4.0 * mm * mm * h[9] - dU * theta) / (theta * theta)
    return dU, d2U


@njit(cache=True, error_model="numpy", parallel=True)
def elements(u, conn, dN, w, p, decay, gain, ginf, feff, H_old, S0_old, H_new, S0_new,
             full, tangent, fe, Ke, theta, status, jbad):
    """Forces fe (E, 24) in N and stiffness Ke (E, 24, 24) in N/m of all elements (parallel).

    u (n, 3) nodal displacements (m); conn (E, 8); dN (E, Q, 8, 3) (1/m); w (E, Q) (m^3) (the
    element volume is their sum, taken in the kernel so that theta = 1 exactly at rest);
    H_old/H_new (k, E*Q, 6), S0_old/S0_new (E*Q, 6) Prony state (Pa), the new state written
    from the old (the old one is untouched, so a rejected iterate costs nothing); full: volumetric
    term at every Gauss point instead of mean dilatation. theta (E,) volume ratios (-); status (E,)
    0 ok, 1 inverted (jbad = J), 2 non-finite material derivative.
    """
    E = conn.shape[0]
    nq = w.shape[1]
    k = decay.shape[0]
    nchunk = min(E, 64)
    for ch in prange(nchunk):
        # scratch allocated once per chunk of elements (allocation costs more than an element's work)
        F = np.empty((3, 3))
        Finv = np.empty((3, 3))
        S = np.empty(6)
        D = np.empty((6, 6))
        B = np.empty((6, 24))
        DB = np.empty((6, 24))
        A3 = np.empty((3, 3))
        Q3 = np.empty((3, 3))
        H3 = np.empty((3, 3))
        m3 = np.empty(3)
        th3 = np.empty(3)
        Na = np.empty((3, 6))
        M6 = np.empty((3, 6))
        nsp = np.empty((8, 3))
        gv = np.empty(24)
        hv = np.empty((24, 24))
        ue = np.empty((8, 3))
        for e in range(ch * E // nchunk, (ch + 1) * E // nchunk):
            status[e] = ST_OK
            gv[:] = 0.0
            hv[:, :] = 0.0
            for a in range(8):
                for i in range(3):
                    ue[a, i] = u[conn[e, a], i]
            for i in range(24):
                fe[e, i] = 0.0
            if tangent:
                for i in range(24):
                    for j in range(24):
                        Ke[e, i, j] = 0.0
            vsum = 0.0
            wsum = 0.0  # the element volume summed in the same order as vsum: theta = 1 exactly at rest
            for q in range(nq):
                pidx = e * nq + q
                wq = w[e, q]
                wsum += wq
                for i in range(3):
                    for J in range(3):
                        s = 1.0 if i == J else 0.0
                        for a in range(8):
                            s += ue[a, i] * dN[e, q, a, J]
                        F[i, J] = s
                det = (F[0, 0] * (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1])
                       - F[0, 1] * (F[1, 0] * F[2, 2] - F[1, 2] * F[2, 0])
                       + F[0, 2] * (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]))
                if not (det > 0.0):
                    status[e] = ST_INVERTED
                    jbad[e] = det
                    break
                for r in range(k):
                    for v in range(6):
                        H_new[r, pidx, v] = H_old[r, pidx, v]
                for v in range(6):
                    S0_new[pidx, v] = S0_old[pidx, v]
                st = material_point(F, p, decay, gain, ginf, feff, H_new[:, pidx, :], S0_new[pidx, :],
                                    full, tangent, S, D, A3, Q3, H3, m3, th3, Na, M6)
                if st != ST_OK:
                    status[e] = st
                    break
                # B (6, 24): dE_v / du_(a,i); shear rows engineering
                for a in range(8):
                    for i in range(3):
                        c = 3 * a + i
                        for v in range(6):
                            I = VI[v]
                            Jj = VJ[v]
                            if I == Jj:
                                B[v, c] = F[i, I] * dN[e, q, a, I]
                            else:
                                B[v, c] = F[i, I] * dN[e, q, a, Jj] + F[i, Jj] * dN[e, q, a, I]
                for c in range(24):
                    s = 0.0
                    for v in range(6):
                        s += B[v, c] * S[v]
                    fe[e, c] += wq * s
                if tangent:
                    for v in range(6):
                        for c in range(24):
                            s = 0.0
                            for x in range(6):
                                s += D[v, x] * B[x, c]
                            DB[v, c] = wq * s
                    for c in range(24):
                        for d in range(c, 24):
                            s = 0.0
                            for v in range(6):
                                s += B[v, c] * DB[v, d]
                            Ke[e, c, d] += s
                    # geometric term: w dN_a . S . dN_b on the diagonal of the (a, b) blocks
                    for a in range(8):
                        sa0 = S[0] * dN[e, q, a, 0] + S[3] * dN[e, q, a, 1] + S[5] * dN[e, q, a, 2]
                        sa1 = S[3] * dN[e, q, a, 0] + S[1] * dN[e, q, a, 1] + S[4] * dN[e, q, a, 2]
                        sa2 = S[5] * dN[e, q, a, 0] + S[4] * dN[e, q, a, 1] + S[2] * dN[e, q, a, 2]
                        for b in range(a, 8):
                            gab = wq * (sa0 * dN[e, q, b, 0] + sa1 * dN[e, q, b, 1] + sa2 * dN[e, q, b, 2])
                            for i in range(3):
                                Ke[e, 3 * a + i, 3 * b + i] += gab
                if not full:
                    # spatial gradients n_a,i = dN_a,J Finv_Ji; g += wJ n; hv += wJ (n_ai n_bk - n_ak n_bi)
                    idet = 1.0 / det
                    Finv[0, 0] = (F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]) * idet
                    Finv[0, 1] = (F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2]) * idet
                    Finv[0, 2] = (F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1]) * idet
                    Finv[1, 0] = (F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2]) * idet
                    Finv[1, 1] = (F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0]) * idet
                    Finv[1, 2] = (F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2]) * idet
                    Finv[2, 0] = (F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]) * idet
                    Finv[2, 1] = (F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1]) * idet
                    Finv[2, 2] = (F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]) * idet
                    wJ = wq * det
                    vsum += wJ
                    for a in range(8):
                        for i in range(3):
                            nsp[a, i] = (dN[e, q, a, 0] * Finv[0, i] + dN[e, q, a, 1] * Finv[1, i]
                                         + dN[e, q, a, 2] * Finv[2, i])
                            gv[3 * a + i] += wJ * nsp[a, i]
                    if tangent:
                        for a in range(8):
                            for i in range(3):
                                c = 3 * a + i
                                for b in range(8):
                                    for kk in range(3):
                                        d = 3 * b + kk
                                        if d >= c:
                                            hv[c, d] += wJ * (nsp[a, i] * nsp[b, kk] - nsp[a, kk] * nsp[b, i])
                else:
                    vsum += wq * det
            if status[e] != ST_OK:
                continue
            th = vsum / wsum
            theta[e] = th
            if not full:
                dU, d2U = volumetric_derivatives(th, p)
                if not math.isfinite(dU + d2U):
                    status[e] = ST_NONFINITE
                    continue
                for c in range(24):
                    fe[e, c] += dU * gv[c]
                if tangent:
                    cg = d2U / wsum
                    for c in range(24):
                        for d in range(c, 24):
                            Ke[e, c, d] += cg * gv[c] * gv[d] + dU * hv[c, d]
            if tangent:
                for c in range(24):
                    for d in range(c + 1, 24):
                        Ke[e, d, c] = Ke[e, c, d]


@njit(cache=True)
def scatter_matrix(Ke, map_el, data):
    """data[map_el[e, i, j]] += Ke[e, i, j] (CSR data of the fixed pattern; serial, no races)."""
    E = Ke.shape[0]
    for e in range(E):
        for i in range(24):
            for j in range(24):
                data[map_el[e, i, j]] += Ke[e, i, j]


@njit(cache=True)
def scatter_vector(fe, edofs, out):
    """out[edofs[e, i]] += fe[e, i] (global vector from element vectors)."""
    for e in range(fe.shape[0]):
        for i in range(24):
            out[edofs[e, i]] += fe[e, i]
