"""Reference (numpy) evaluation of energy, stresses and consistent tangent from principal values.

With psi(m1, m2, m3) a symmetric function of the eigenvalues m_a of C = F^T F (eigenvectors N_a,
projections M_a = N_a (x) N_a):

    S = 2 sum_a psi_a M_a                                   (second Piola-Kirchhoff, Pa)
    CC = 2 dS/dC,  in the principal basis:                   (material tangent, Pa)
        CC_aabb = 4 psi_ab,   CC_abab = CC_abba = 2 theta_ab  (a != b)
        theta_ab = (psi_a - psi_b) / (m_a - m_b),  -> psi_aa - psi_ab as m_b -> m_a
    sigma = J^-1 F S F^T                                     (Cauchy, Pa)

psi_a = d psi / d m_a. The limit of theta at repeated eigenvalues is exact for symmetric psi;
close to it, the symmetric form (psi_aa + psi_bb)/2 - psi_ab is used (error O(gap^2)), so stress
and tangent are correct at and near the reference state and uniaxial states. No derivative is
taken through the eigen-decomposition.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError

VOIGT = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))  # s11, s22, s33, s12, s23, s13
THETA_TOL = 1e-4  # relative eigenvalue gap below which theta uses the symmetric limit


def as_batch(F) -> np.ndarray:
    """F as a float64 array of shape (n, 3, 3); checks shape, finiteness and det F > 0."""
    F = np.asarray(F, dtype=np.float64)
    if F.shape[-2:] != (3, 3):
        raise InputError(f"deformation gradient must have shape (..., 3, 3), got {F.shape}.")
    F = F.reshape(-1, 3, 3)
    bad = ~np.isfinite(F).all(axis=(1, 2))
    if bad.any():
        raise InputError(f"deformation gradient {int(np.argmax(bad))} has a NaN or infinite entry.")
    J = np.linalg.det(F)
    if (J <= 0).any():
        i = int(np.argmax(J <= 0))
        raise InputError(f"deformation gradient {i} has det F = {J[i]:g} <= 0 (inverted or degenerate).")
    return F


def principal(F):
    """(m, Q, J): eigenvalues m (n, 3) of C, eigenvectors as columns of Q (n, 3, 3), J (n,)."""
    F = as_batch(F)
    C = np.einsum("nki,nkj->nij", F, F)
    m, Q = np.linalg.eigh(C)
    return m, Q, np.linalg.det(F)


def from_principal(values, Q) -> np.ndarray:
    """Tensor Q diag(values) Q^T, batched: values (n, 3), Q (n, 3, 3) -> (n, 3, 3)."""
    return np.einsum("nia,na,nja->nij", Q, values, Q)


def _theta(m, g, h):
    """theta_ab for pairs (0,1), (1,2), (0,2): arrays (n, 3). h: (n, 6) Hessian (11,22,33,12,23,13)."""
    out = np.empty_like(m)
    for k, (a, b, ab) in enumerate(((0, 1, 3), (1, 2, 4), (0, 2, 5))):
        dm = m[:, a] - m[:, b]
        close = np.abs(dm) <= THETA_TOL * np.maximum(np.abs(m[:, a]), np.abs(m[:, b]))
        safe = np.where(close, 1.0, dm)
        out[:, k] = np.where(close, 0.5 * (h[:, a] + h[:, b]) - h[:, ab], (g[:, a] - g[:, b]) / safe)
    return out


def tangent_from_principal(m, Q, g, h) -> np.ndarray:
    """Material tangent CC = 2 dS/dC (n, 3, 3, 3, 3) in Pa from psi gradient g and Hessian h."""
    n = m.shape[0]
    Cp = np.zeros((n, 3, 3, 3, 3))
    hmat = np.empty((n, 3, 3))
    for k, (a, b) in enumerate(VOIGT):
        hmat[:, a, b] = h[:, k]
        hmat[:, b, a] = h[:, k]
    for a in range(3):
        for b in range(3):
            Cp[:, a, a, b, b] = 4.0 * hmat[:, a, b]
    theta = _theta(m, g, h)
    for k, (a, b) in enumerate(((0, 1), (1, 2), (0, 2))):
        for i, j in ((a, b), (b, a)):
            Cp[:, i, j, i, j] = 2.0 * theta[:, k]
            Cp[:, i, j, j, i] = 2.0 * theta[:, k]
    return np.einsum("nia,njb,nkc,nld,nabcd->nijkl", Q, Q, Q, Q, Cp, optimize=True)


def to_voigt(T) -> np.ndarray:
    """Symmetric tensors (n, 3, 3) -> (n, 6) in the order 11, 22, 33, 12, 23, 13."""
    return np.stack([T[:, a, b] for a, b in VOIGT], axis=1)


def from_voigt(v) -> np.ndarray:
    """(n, 6) in the order 11, 22, 33, 12, 23, 13 -> symmetric tensors (n, 3, 3)."""
    T = np.empty(v.shape[:-1] + (3, 3))
    for k, (a, b) in enumerate(VOIGT):
        T[..., a, b] = v[..., k]
        T[..., b, a] = v[..., k]
    return T


def cauchy_from_pk2(F, S) -> np.ndarray:
    """sigma = J^-1 F S F^T (n, 3, 3), Pa."""
    J = np.linalg.det(F)
    return np.einsum("nik,nkl,njl->nij", F, S, F) / J[:, None, None]
