"""Constitutive update at one material point (numba, scalars only).

Given F: J = det F (J <= 0 is an inversion), C = F^T F = Q diag(m) Q^T, and from the material's
generated functions (docs/conventions.md section 2; derivatives with respect to the eigenvalues m_a of C):

    S0_iso = Q diag(2 d psi_iso / d m_a) Q^T,   S_vol = Q diag(2 d psi_vol / d m_a) Q^T   (Pa)

Prony series on the isochoric part, exact exponential recurrence per step dt (s):

    H_k <- exp(-dt/tau_k) H_k + gamma_k (tau_k/dt)(1 - exp(-dt/tau_k)) (S0_new - S0_old)
    S = S_vol + gamma_inf S0_iso + sum_k H_k

``psi_grad_hess_diag`` returns psi_grad's 6 values then psi_hess_diag's 6 (see ``codegen``).

Stable-step modulus: along each principal direction a, d^2 Psi / d lambda_a^2 with
lambda_a = sqrt(m_a) is M_a = 2 psi_a + 4 m_a psi_aa (Pa), using the instantaneous isochoric
energy (conservative: the Prony series only lowers the isochoric stiffness within a step).
Symmetric tensors are 6-vectors in the order 11, 22, 33, 12, 23, 13.
"""

# >>> standalone (removed when the kernels are concatenated into a generated module)
import math

import numpy as np
from numba import njit

from .eigen import eig3
from .layout import FASTMATH


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def psi_grad_hess_diag(m1, m2, m3, p):  # stub: generated modules define it from the material
    return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0


psi_grad_hess_diag_v = psi_grad_hess_diag   # generated modules: the vectorisable variant
# <<< standalone

ST_OK = 0
ST_INVERTED = 1
ST_NONFINITE = 2


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def prony_step(dt, gam, tau, decay, gain):
    """Fill decay_k = exp(-dt/tau_k), gain_k = gamma_k (tau_k/dt)(1 - exp(-dt/tau_k)); dt = 0: jump."""
    for j in range(gam.shape[0]):
        x = dt / tau[j]
        if x < 1e-8:
            decay[j] = 1.0 - x
            gain[j] = gam[j] * (1.0 - 0.5 * x)
        else:
            decay[j] = math.exp(-x)
            gain[j] = gam[j] * (-math.expm1(-x) / x)


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def material_point(f00, f01, f02, f10, f11, f12, f20, f21, f22, p, decay, gain, ginf, H, S0old):
    """Second Piola-Kirchhoff stress at one point, updating the Prony state H (k, 6), S0old (6,).

    decay, gain (k,): the step's Prony factors exp(-dt/tau_k) and gamma_k (tau_k/dt)(1 -
    exp(-dt/tau_k)) from :func:`prony_step` (the same for every element, computed once per step).

    Returns (status, J, S11, S22, S33, S12, S23, S13, C11, C22, C33, C12, C23, C13,
    M_max, M_iso_max, m0, m1, m2): status 0 ok, 1 inverted (J <= 0 or not finite),
    2 non-finite material derivative; M_max (Pa) the largest longitudinal modulus over the
    principal directions, M_iso_max its isochoric part; m the eigenvalues of C.
    The Prony state is left untouched when status != 0.
    """
    J = (f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20)
         + f02 * (f10 * f21 - f11 * f20))
    c00 = f00 * f00 + f10 * f10 + f20 * f20
    c11 = f01 * f01 + f11 * f11 + f21 * f21
    c22 = f02 * f02 + f12 * f12 + f22 * f22
    c01 = f00 * f01 + f10 * f11 + f20 * f21
    c12 = f01 * f02 + f11 * f12 + f21 * f22
    c02 = f00 * f02 + f10 * f12 + f20 * f22
    if not (J > 0.0) or not math.isfinite(J):
        return (ST_INVERTED, J, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, c00, c11, c22, c01, c12, c02,
                0.0, 0.0, 0.0, 0.0, 0.0)
    m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22 = eig3(c00, c01, c02, c11, c12, c22)
    i0, i1, i2, v0, v1, v2, h0, h1, h2, w0, w1, w2 = psi_grad_hess_diag(m0, m1, m2, p)
    st, t00, t11, t22, t01, t12, t02, mt, mi = principal_stress(
        m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22,
        i0, i1, i2, v0, v1, v2, h0, h1, h2, w0, w1, w2, decay, gain, ginf, H, S0old)
    return (st, J, t00, t11, t22, t01, t12, t02, c00, c11, c22, c01, c12, c02,
            mt, mi, m0, m1, m2)


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def principal_stress(m0, m1, m2, q00, q01, q02, q10, q11, q12, q20, q21, q22,
                     i0, i1, i2, v0, v1, v2, h0, h1, h2, w0, w1, w2, decay, gain, ginf, H, S0old):
    """S (Pa) from the eigen-decomposition C = Q diag(m) Q^T and the material's derivatives.

    i, v: d psi_iso / d m_a and d psi_vol / d m_a; h, w: the second derivatives d^2 / d m_a^2
    (Pa). Updates the Prony state H (k, 6), S0old (6,) (left untouched on failure).
    Returns (status, S11, S22, S33, S12, S23, S13, M_max, M_iso_max): status 0 ok,
    2 non-finite derivative (the other values are then 0).
    """
    chk = i0 + i1 + i2 + v0 + v1 + v2 + h0 + h1 + h2 + w0 + w1 + w2
    if not math.isfinite(chk):
        return ST_NONFINITE, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    # S0_iso and S_vol in the principal basis: sum_a 2 psi_a N_a (x) N_a
    a0 = 2.0 * i0
    a1 = 2.0 * i1
    a2 = 2.0 * i2
    s00 = a0 * q00 * q00 + a1 * q01 * q01 + a2 * q02 * q02
    s11 = a0 * q10 * q10 + a1 * q11 * q11 + a2 * q12 * q12
    s22 = a0 * q20 * q20 + a1 * q21 * q21 + a2 * q22 * q22
    s01 = a0 * q00 * q10 + a1 * q01 * q11 + a2 * q02 * q12
    s12 = a0 * q10 * q20 + a1 * q11 * q21 + a2 * q12 * q22
    s02 = a0 * q00 * q20 + a1 * q01 * q21 + a2 * q02 * q22
    b0 = 2.0 * v0
    b1 = 2.0 * v1
    b2 = 2.0 * v2
    t00 = b0 * q00 * q00 + b1 * q01 * q01 + b2 * q02 * q02
    t11 = b0 * q10 * q10 + b1 * q11 * q11 + b2 * q12 * q12
    t22 = b0 * q20 * q20 + b1 * q21 * q21 + b2 * q22 * q22
    t01 = b0 * q00 * q10 + b1 * q01 * q11 + b2 * q02 * q12
    t12 = b0 * q10 * q20 + b1 * q11 * q21 + b2 * q12 * q22
    t02 = b0 * q00 * q20 + b1 * q01 * q21 + b2 * q02 * q22
    k = decay.shape[0]
    if k > 0:
        d00 = s00 - S0old[0]
        d11 = s11 - S0old[1]
        d22 = s22 - S0old[2]
        d01 = s01 - S0old[3]
        d12 = s12 - S0old[4]
        d02 = s02 - S0old[5]
        S0old[0] = s00
        S0old[1] = s11
        S0old[2] = s22
        S0old[3] = s01
        S0old[4] = s12
        S0old[5] = s02
        t00 += ginf * s00
        t11 += ginf * s11
        t22 += ginf * s22
        t01 += ginf * s01
        t12 += ginf * s12
        t02 += ginf * s02
        for j in range(k):
            e = decay[j]
            g = gain[j]
            H[j, 0] = e * H[j, 0] + g * d00
            H[j, 1] = e * H[j, 1] + g * d11
            H[j, 2] = e * H[j, 2] + g * d22
            H[j, 3] = e * H[j, 3] + g * d01
            H[j, 4] = e * H[j, 4] + g * d12
            H[j, 5] = e * H[j, 5] + g * d02
            t00 += H[j, 0]
            t11 += H[j, 1]
            t22 += H[j, 2]
            t01 += H[j, 3]
            t12 += H[j, 4]
            t02 += H[j, 5]
    else:
        t00 += s00
        t11 += s11
        t22 += s22
        t01 += s01
        t12 += s12
        t02 += s02
    # longitudinal moduli along the principal directions (Pa)
    mi0 = 2.0 * i0 + 4.0 * m0 * h0
    mi1 = 2.0 * i1 + 4.0 * m1 * h1
    mi2 = 2.0 * i2 + 4.0 * m2 * h2
    mt0 = mi0 + 2.0 * v0 + 4.0 * m0 * w0
    mt1 = mi1 + 2.0 * v1 + 4.0 * m1 * w1
    mt2 = mi2 + 2.0 * v2 + 4.0 * m2 * w2
    mt = max(mt0, max(mt1, mt2))
    mi = max(mi0, max(mi1, mi2))
    return ST_OK, t00, t11, t22, t01, t12, t02, mt, mi


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def first_piola(f00, f01, f02, f10, f11, f12, f20, f21, f22, s00, s11, s22, s01, s12, s02):
    """P = F S (row-major 9 values, Pa) for F and a symmetric S given by its 6 components."""
    return (f00 * s00 + f01 * s01 + f02 * s02, f00 * s01 + f01 * s11 + f02 * s12, f00 * s02 + f01 * s12 + f02 * s22,
            f10 * s00 + f11 * s01 + f12 * s02, f10 * s01 + f11 * s11 + f12 * s12, f10 * s02 + f11 * s12 + f12 * s22,
            f20 * s00 + f21 * s01 + f22 * s02, f20 * s01 + f21 * s11 + f22 * s12, f20 * s02 + f21 * s12 + f22 * s22)


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def point_history(t, F, p, gam, tau, ginf, out):
    """Cauchy stress sigma = J^-1 F S F^T (Pa) along a history F (n, 3, 3) at times t (n,) (s).

    Starts undeformed and relaxed at t[0] (a deformation present at t[0] is a jump). Writes
    out (n, 6) in the order 11, 22, 33, 12, 23, 13. Returns (status, index, J, m0, m1, m2) of
    the first failure (status 0: none).
    """
    k = gam.shape[0]
    H = np.zeros((k, 6))
    S0old = np.zeros(6)
    decay = np.zeros(k)
    gain = np.zeros(k)
    for n in range(t.shape[0]):
        prony_step(0.0 if n == 0 else t[n] - t[n - 1], gam, tau, decay, gain)
        f00 = F[n, 0, 0]
        f01 = F[n, 0, 1]
        f02 = F[n, 0, 2]
        f10 = F[n, 1, 0]
        f11 = F[n, 1, 1]
        f12 = F[n, 1, 2]
        f20 = F[n, 2, 0]
        f21 = F[n, 2, 1]
        f22 = F[n, 2, 2]
        (st, J, s00, s11, s22, s01, s12, s02, c00, c11, c22, c01, c12, c02,
         mt, mi, m0, m1, m2) = material_point(f00, f01, f02, f10, f11, f12, f20, f21, f22,
                                              p, decay, gain, ginf, H, S0old)
        if st == ST_OK and not math.isfinite(s00 + s11 + s22 + s01 + s12 + s02):
            st = ST_NONFINITE
        if st != ST_OK:
            return st, n, J, m0, m1, m2
        # P = F S, sigma = P F^T / J
        p00, p01, p02, p10, p11, p12, p20, p21, p22 = first_piola(f00, f01, f02, f10, f11, f12, f20, f21, f22,
                                                                  s00, s11, s22, s01, s12, s02)
        ij = 1.0 / J
        out[n, 0] = (p00 * f00 + p01 * f01 + p02 * f02) * ij
        out[n, 1] = (p10 * f10 + p11 * f11 + p12 * f12) * ij
        out[n, 2] = (p20 * f20 + p21 * f21 + p22 * f22) * ij
        out[n, 3] = (p00 * f10 + p01 * f11 + p02 * f12) * ij
        out[n, 4] = (p10 * f20 + p11 * f21 + p12 * f22) * ij
        out[n, 5] = (p00 * f20 + p01 * f21 + p02 * f22) * ij
    return 0, -1, 1.0, 0.0, 0.0, 0.0
