"""What a generated user material must return, from the numpy reference (the harness's truth).

:func:`history` steps :func:`cfm_core.material.reference.viscous_step` along a deformation
history as a solver's increments do (the material undeformed and relaxed at t[0]), keeping the
Prony state after each step; :func:`jaumann_tangent` is the perturbation formula for Abaqus's
DDSDDE (Miehe 1996; Sun et al. 2008) evaluated with the reference, by central differences:

    C^MJ_ijkl = [tau_ij(F + dF_kl) - tau_ij(F - dF_kl)] / (2 J eps),
    dF_kl = eps/2 (e_k (x) e_l + e_l (x) e_k) F,

with the Prony state of the previous step held fixed (the consistent tangent of the step).
"""

from __future__ import annotations

import numpy as np

from ..material import kinematics as kin
from ..material import reference

ORDER_STANDARD = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))  # Abaqus/Standard: 11, 22, 33, 12, 13, 23


def _stress(material, state, dt, F):
    """(Cauchy stress, new state) of one reference step to F (3, 3)."""
    S0, Sv = reference.pk2_parts(material, F)
    S, new = reference.viscous_step(material, state, dt, S0[0], Sv[0])
    return kin.cauchy_from_pk2(F[None], S[None])[0], new


def history(material, t, F):
    """Cauchy stress and Prony state after each step of a history starting undeformed at t[0].

    Parameters
    ----------
    material : Material
        A bound material.
    t : array_like, shape (n,)
        Non-decreasing times (s).
    F : array_like, shape (n, 3, 3)
        Deformation gradients (-), det F > 0; F[0] is the start of the first step.

    Returns
    -------
    sigma : ndarray, shape (n, 3, 3)
        Cauchy stress (Pa) after each step (row 0: the state at t[0], a jump from F = I).
    states : list of (ndarray, ndarray) or None
        Prony state ``(H, S0_old)`` after each step (None for an elastic material).

    Raises
    ------
    InputError
        An F is invalid (det F <= 0, non-finite).
    NumericalError
        Non-finite generated derivatives (fibre exponential overflow).
    """
    t = np.asarray(t, dtype=np.float64)
    F = kin.as_batch(F)
    sigma = np.empty_like(F)
    states = []
    state = None
    for n in range(t.size):
        sigma[n], state = _stress(material, state, 0.0 if n == 0 else t[n] - t[n - 1], F[n])
        states.append(state)
    return sigma, states


def jaumann_tangent(material, F, state, dt: float, eps: float = 1e-6) -> np.ndarray:
    """DDSDDE of one step by the perturbation formula (central differences), Abaqus order.

    Parameters
    ----------
    material : Material
        A bound material.
    F : array_like, shape (3, 3)
        Deformation gradient at the end of the step (-).
    state : tuple or None
        Prony state at the start of the step (from :func:`history`).
    dt : float
        Step (s).
    eps : float
        Perturbation size (-).

    Returns
    -------
    ndarray, shape (6, 6)
        C^MJ (Pa), rows and columns in the order 11, 22, 33, 12, 13, 23.
    """
    F = np.asarray(F, dtype=np.float64)
    J = np.linalg.det(F)
    out = np.empty((6, 6))
    for col, (k, l) in enumerate(ORDER_STANDARD):
        E = np.zeros((3, 3))
        E[k, l] += 0.5 * eps
        E[l, k] += 0.5 * eps
        taus = []
        for sign in (1.0, -1.0):
            Fp = F + sign * E @ F
            sig, _ = _stress(material, state, dt, Fp)
            taus.append(np.linalg.det(Fp) * sig)
        dtau = (taus[0] - taus[1]) / (2.0 * J * eps)
        out[:, col] = [dtau[a, b] for a, b in ORDER_STANDARD]
    return out


def to_order(sigma, order) -> np.ndarray:
    """Symmetric tensors (n, 3, 3) as (n, 6) vectors in a solver's component order.

    Parameters
    ----------
    sigma : ndarray, shape (n, 3, 3)
        Symmetric tensors (any unit).
    order : sequence of (int, int)
        Six index pairs, e.g. :data:`ORDER_STANDARD`.

    Returns
    -------
    ndarray, shape (n, 6)
        Components in that order.
    """
    return np.stack([sigma[:, a, b] for a, b in order], axis=1)
