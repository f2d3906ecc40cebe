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
    """F as a float64 array of shape (n, 3, 3); checks shape, finiteness and det F > 0.

    Parameters
    ----------
    F : array_like, shape (..., 3, 3)
        Deformation gradients (-); leading axes are flattened.

    Returns
    -------
    ndarray, shape (n, 3, 3)
        float64 copy or view of ``F``, n the product of the leading axes (1 for a single F).

    Raises
    ------
    InputError
        The last two axes are not (3, 3), an entry is NaN or infinite, or det F <= 0 (inverted
        or degenerate); the message names the index of the first bad F.
    """
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
    """Principal values of C = F^T F, by a symmetric eigen-decomposition (``numpy.linalg.eigh``).

    Parameters
    ----------
    F : array_like, shape (..., 3, 3)
        Deformation gradients (-), checked by :func:`as_batch`.

    Returns
    -------
    m : ndarray, shape (n, 3)
        Eigenvalues of C (squared principal stretches, -), ascending.
    Q : ndarray, shape (n, 3, 3)
        Orthonormal eigenvectors N_a as columns (``Q[:, :, a]``).
    J : ndarray, shape (n,)
        det F (-).

    Raises
    ------
    InputError
        From :func:`as_batch`: wrong shape, non-finite entry or det F <= 0.
    """
    F = as_batch(F)
    C = np.einsum("nki,nkj->nij", F, F)
    m, Q = np.linalg.eigh(C)
    return m, Q, np.linalg.det(F)


def from_principal(values, Q) -> np.ndarray:
    """Tensor Q diag(values) Q^T = sum_a values_a N_a (x) N_a, batched.

    Parameters
    ----------
    values : ndarray, shape (n, 3)
        Principal values (any unit, e.g. 2 psi_a in Pa for the second Piola-Kirchhoff stress).
    Q : ndarray, shape (n, 3, 3)
        Principal directions as columns, from :func:`principal`.

    Returns
    -------
    ndarray, shape (n, 3, 3)
        The symmetric tensors, in the unit of ``values``.
    """
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
    """Material tangent CC = 2 dS/dC (n, 3, 3, 3, 3) in Pa from psi gradient g and Hessian h.

    In the principal basis CC_aabb = 4 psi_ab and CC_abab = CC_abba = 2 theta_ab (a != b), with
    theta_ab = (psi_a - psi_b) / (m_a - m_b), or (psi_aa + psi_bb) / 2 - psi_ab when the relative
    gap is below ``THETA_TOL`` (the exact limit at repeated eigenvalues, error O(gap^2)); then
    rotated with Q (module docstring; docs/conventions.md section 2, numerical care).

    Parameters
    ----------
    m : ndarray, shape (n, 3)
        Eigenvalues of C (-).
    Q : ndarray, shape (n, 3, 3)
        Eigenvectors of C as columns.
    g : ndarray, shape (n, 3)
        d psi / d m_a (Pa).
    h : ndarray, shape (n, 6)
        d2 psi / d m_a d m_b in the order 11, 22, 33, 12, 23, 13 (Pa).

    Returns
    -------
    ndarray, shape (n, 3, 3, 3, 3)
        CC_ijkl in the reference (global) basis, Pa, with both minor symmetries and the major one.
    """
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
    """Symmetric tensors in Voigt order 11, 22, 33, 12, 23, 13 (no factor 2 on shear terms).

    Parameters
    ----------
    T : ndarray, shape (n, 3, 3)
        Symmetric tensors (any unit); only the upper triangle is read.

    Returns
    -------
    ndarray, shape (n, 6)
        Components in the unit of ``T``.
    """
    return np.stack([T[:, a, b] for a, b in VOIGT], axis=1)


def from_voigt(v) -> np.ndarray:
    """Symmetric tensors from Voigt order 11, 22, 33, 12, 23, 13 (inverse of :func:`to_voigt`).

    Parameters
    ----------
    v : ndarray, shape (..., 6)
        Components (any unit).

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Symmetric float64 tensors in the unit of ``v``.
    """
    T = np.empty(v.shape[:-1] + (3, 3))
    for k, (a, b) in enumerate(VOIGT):
        T[..., a, b] = v[..., k]
        T[..., b, a] = v[..., k]
    return T


def cauchy_from_pk2(F, S) -> np.ndarray:
    """Cauchy stress sigma = J^-1 F S F^T from the second Piola-Kirchhoff stress.

    Parameters
    ----------
    F : ndarray, shape (n, 3, 3)
        Deformation gradients (-), det F > 0 (not checked here; see :func:`as_batch`).
    S : ndarray, shape (n, 3, 3)
        Second Piola-Kirchhoff stress (Pa).

    Returns
    -------
    ndarray, shape (n, 3, 3)
        Cauchy stress (Pa).
    """
    J = np.linalg.det(F)
    return np.einsum("nik,nkl,njl->nij", F, S, F) / J[:, None, None]
