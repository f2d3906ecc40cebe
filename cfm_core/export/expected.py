"""What a generated user material must return, from the numpy reference (the harness's truth).

:func:`history` steps :func:`cfm_core.material.reference.viscous_step` along a deformation
history as a solver's increments do (the material undeformed and relaxed at t[0]), keeping the
Prony state after each step; :func:`jaumann_tangent` is the perturbation formula for Abaqus's
DDSDDE (Miehe 1996; Sun et al. 2008) evaluated with the reference, by central differences:

    C^MJ_ijkl = [tau_ij(F + dF_kl) - tau_ij(F - dF_kl)] / (2 J eps),
    dF_kl = eps/2 (e_k (x) e_l + e_l (x) e_k) F,

with the Prony state of the previous step held fixed (the consistent tangent of the step);
:func:`rate_tangent` is the same loop for either rate: with the Truesdell rate (the Jaumann
stress terms d tau + tau d taken off) it gives LS-DYNA's utan es = c / J.
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
    """DDSDDE of one step by the perturbation formula (central differences), Abaqus order:
    :func:`rate_tangent` with the Jaumann rate (material, F (3, 3), state, dt in s, eps as there).

    Returns
    -------
    ndarray, shape (6, 6)
        C^MJ (Pa), rows and columns in the order 11, 22, 33, 12, 13, 23.
    """
    return rate_tangent(material, F, state, dt, "jaumann", ORDER_STANDARD, eps)


def rate_tangent(material, F, state, dt: float, rate: str, order, eps: float = 1e-6) -> np.ndarray:
    """Tangent of a rate of the Kirchhoff stress over J, by the perturbation formula (central
    differences): a velocity gradient d = sym(e_k (x) e_l), no spin (dF = eps d F), so that

    - ``"jaumann"``: J C^MJ : d = d tau / d eps (Abaqus's DDSDDE; Miehe 1996, Sun et al. 2008);
    - ``"truesdell"``: c : d = d tau / d eps - (d tau + tau d), the Lie derivative of tau: c / J is
      the push-forward of dS/dE over J (LS-DYNA's utan es).

    Parameters
    ----------
    material : Material
        A bound material.
    F : array_like, shape (3, 3)
        Deformation gradient at the end of the step (-).
    state : tuple or None
        Prony state at the start of the step (from :func:`history`), held fixed: the consistent
        tangent of the step.
    dt : float
        Step (s).
    rate : {"jaumann", "truesdell"}
        Objective rate.
    order : sequence of (int, int)
        The six index pairs of rows and columns (e.g. :data:`ORDER_STANDARD`); shear columns for
        engineering shear strain.
    eps : float
        Perturbation size (-).

    Returns
    -------
    ndarray, shape (6, 6)
        The tangent (Pa).

    Raises
    ------
    ValueError
        ``rate`` is not one of the two.
    """
    if rate not in ("jaumann", "truesdell"):
        raise ValueError(f"rate {rate!r}: use 'jaumann' or 'truesdell'")
    F = np.asarray(F, dtype=np.float64)
    J = np.linalg.det(F)
    tau = J * _stress(material, state, dt, F)[0] if rate == "truesdell" else np.zeros((3, 3))
    out = np.empty((6, 6))
    for col, (k, l) in enumerate(order):
        d = np.zeros((3, 3))
        d[k, l] += 0.5
        d[l, k] += 0.5
        taus = []
        for sign in (1.0, -1.0):
            Fp = F + sign * eps * d @ F
            sig, _ = _stress(material, state, dt, Fp)
            taus.append(np.linalg.det(Fp) * sig)
        dtau = ((taus[0] - taus[1]) / (2.0 * eps) - (d @ tau + tau @ d)) / J
        out[:, col] = [dtau[a, b] for a, b in order]
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
