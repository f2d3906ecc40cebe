"""Reference evaluation of a :class:`~cfm_core.material.Material` with numpy (float64).

This is the truth every backend is checked against. Elastic functions give the *instantaneous*
response (g = 1); :func:`stress_history` integrates the Prony series along a history.
"""

from __future__ import annotations

import numpy as np

from . import kinematics as kin
from . import prony
from .diagnose import describe_nonfinite
from ..errors import InputError, NumericalError


def _evaluate(material, m, *names):
    k = material.kernels("numpy")
    p = material.param_array()
    with np.errstate(over="ignore", invalid="ignore"):
        outs = [np.stack(getattr(k, name)(m[:, 0], m[:, 1], m[:, 2], p), axis=1) for name in names]
    for name, o in zip(names, outs):
        if not np.isfinite(o).all():
            i = int(np.argmax(~np.isfinite(o).all(axis=1)))
            raise NumericalError(f"{name} is not finite at point {i}: {describe_nonfinite(material, m[i])}.",
                                 element=i, quantity=f"non-finite {name} of material '{material.name}'")
    return outs


def principal_response(material, m, *names):
    """The material's generated functions at squared principal stretches m (for a caller that has
    already decomposed C, e.g. :mod:`cfm_core.post.fields`).

    Parameters
    ----------
    material : Material
        A bound material.
    m : ndarray, shape (n, 3)
        Eigenvalues of C (-), from :func:`cfm_core.material.kinematics.principal`.
    *names : str
        Kernel names: ``"psi_energy"`` ((W, U), Pa), ``"psi_grad"`` (6 first derivatives: 3
        isochoric, 3 volumetric, Pa), ``"psi_hess"``.

    Returns
    -------
    list of ndarray
        One (n, k) array per name.

    Raises
    ------
    NumericalError
        A non-finite value (names the point and the eigenvalues of C).
    """
    return _evaluate(material, np.asarray(m, dtype=np.float64), *names)


def energy(material, F) -> np.ndarray:
    """Instantaneous strain energy per reference volume psi = W(l1, l2, l3) + U(J)
    (docs/conventions.md section 2; for the CFM paper Eq. 1-7).

    Parameters
    ----------
    material : Material
        A bound material.
    F : array_like, shape (n, 3, 3) or (3, 3)
        Deformation gradients (-), det F > 0.

    Returns
    -------
    ndarray, shape (n,)
        psi in Pa = J/m^3 (isochoric part with the material's moduli factor s_iso).

    Raises
    ------
    InputError
        ``F`` has the wrong shape, a non-finite entry or det F <= 0.
    NumericalError
        The generated energy or its derivatives are not finite at a point (e.g. the fibre
        exponential overflows float64); names the point (``element``) and the eigenvalues of C.
    """
    m, _, _ = kin.principal(F)
    (e,) = _evaluate(material, m, "psi_energy")
    return e[:, 0] + e[:, 1]


def pk2_parts(material, F):
    """Isochoric (instantaneous) and volumetric second Piola-Kirchhoff stress, S = 2 d psi / d C.

    Parameters
    ----------
    material : Material
        A bound material.
    F : array_like, shape (n, 3, 3) or (3, 3)
        Deformation gradients (-), det F > 0.

    Returns
    -------
    S0_iso : ndarray, shape (n, 3, 3)
        Instantaneous isochoric part (Pa), the input of the Prony recurrence.
    S_vol : ndarray, shape (n, 3, 3)
        Volumetric part (Pa), elastic.

    Raises
    ------
    InputError
        ``F`` has the wrong shape, a non-finite entry or det F <= 0.
    NumericalError
        The generated energy or its derivatives are not finite at a point (e.g. the fibre
        exponential overflows float64); names the point (``element``) and the eigenvalues of C.
    """
    m, Q, _ = kin.principal(F)
    (g,) = _evaluate(material, m, "psi_grad")
    return kin.from_principal(2.0 * g[:, :3], Q), kin.from_principal(2.0 * g[:, 3:], Q)


def pk2(material, F) -> np.ndarray:
    """Instantaneous second Piola-Kirchhoff stress S = 2 d psi / d C.

    Parameters
    ----------
    material : Material
        A bound material.
    F : array_like, shape (n, 3, 3) or (3, 3)
        Deformation gradients (-), det F > 0.

    Returns
    -------
    ndarray, shape (n, 3, 3)
        S (Pa), isochoric plus volumetric part.

    Raises
    ------
    InputError
        ``F`` has the wrong shape, a non-finite entry or det F <= 0.
    NumericalError
        The generated energy or its derivatives are not finite at a point (e.g. the fibre
        exponential overflows float64); names the point (``element``) and the eigenvalues of C.
    """
    S_iso, S_vol = pk2_parts(material, F)
    return S_iso + S_vol


def cauchy(material, F) -> np.ndarray:
    """Instantaneous Cauchy stress sigma = J^-1 F S F^T.

    Parameters
    ----------
    material : Material
        A bound material.
    F : array_like, shape (n, 3, 3) or (3, 3)
        Deformation gradients (-), det F > 0.

    Returns
    -------
    ndarray, shape (n, 3, 3)
        sigma (Pa).

    Raises
    ------
    InputError
        ``F`` has the wrong shape, a non-finite entry or det F <= 0.
    NumericalError
        The generated energy or its derivatives are not finite at a point (e.g. the fibre
        exponential overflows float64); names the point (``element``) and the eigenvalues of C.
    """
    F = kin.as_batch(F)
    return kin.cauchy_from_pk2(F, pk2(material, F))


def tangent(material, F, iso_factor: float = 1.0) -> np.ndarray:
    """Material tangent CC = 2 dS/dC = dS/dE, from principal-stretch derivatives
    (:func:`cfm_core.material.kinematics.tangent_from_principal`).

    Parameters
    ----------
    material : Material
        A bound material.
    F : array_like, shape (n, 3, 3) or (3, 3)
        Deformation gradients (-), det F > 0.
    iso_factor : float
        Factor on the isochoric part (-): 1 for the instantaneous response, the Prony series'
        :func:`cfm_core.material.prony.effective_factor` for the consistent viscoelastic tangent.

    Returns
    -------
    ndarray, shape (n, 3, 3, 3, 3)
        CC_ijkl (Pa).

    Raises
    ------
    InputError
        ``F`` has the wrong shape, a non-finite entry or det F <= 0.
    NumericalError
        The generated energy or its derivatives are not finite at a point (e.g. the fibre
        exponential overflows float64); names the point (``element``) and the eigenvalues of C.
    """
    m, Q, _ = kin.principal(F)
    g, h = _evaluate(material, m, "psi_grad", "psi_hess")
    g_tot = iso_factor * g[:, :3] + g[:, 3:]
    h_tot = iso_factor * h[:, :6] + h[:, 6:]
    return kin.tangent_from_principal(m, Q, g_tot, h_tot)


def viscous_step(material, state, dt: float, S0_iso, S_vol):
    """One Prony step at a material point (:func:`cfm_core.material.prony.update`); ``state`` is
    not modified.

    Parameters
    ----------
    material : Material
        A bound material; an elastic one (no Prony terms) returns S0_iso + S_vol and no state.
    state : tuple of (ndarray, ndarray) or None
        None (undeformed, relaxed) or ``(H, S0_old)``: history stresses H, shape (k, 3, 3), and
        the previous instantaneous isochoric stress S0_old, shape (3, 3), both Pa.
    dt : float
        Step (s); 0 = instantaneous jump.
    S0_iso, S_vol : ndarray, shape (3, 3)
        Instantaneous isochoric and volumetric second Piola-Kirchhoff stress at the end of the
        step (Pa).

    Returns
    -------
    S : ndarray, shape (3, 3)
        Viscoelastic second Piola-Kirchhoff stress (Pa).
    new_state : tuple of (ndarray, ndarray) or None
        ``(H_new, S0_iso)`` for the next step; None for an elastic material.
    """
    gammas, taus = material.prony_arrays()
    if gammas.size == 0:
        return S0_iso + S_vol, None
    H, S0_old = state if state is not None else (np.zeros((gammas.size, 3, 3)), np.zeros((3, 3)))
    H_new, S_iso = prony.update(H, S0_old, S0_iso, dt, gammas, taus)
    return S_iso + S_vol, (H_new, S0_iso)


def stress_history(material, t, F) -> np.ndarray:
    """Cauchy stress along a deformation history with Prony viscoelasticity.

    The material is undeformed and relaxed before t[0]; a deformation already present at t[0] is
    applied as a jump (instantaneous response). Exact exponential recurrence per step
    (docs/conventions.md section 2).

    Parameters
    ----------
    material : Material
        A bound material (elastic or viscoelastic).
    t : array_like, shape (n,)
        Non-decreasing times (s).
    F : array_like, shape (n, 3, 3)
        Deformation gradients at those times (-), det F > 0.

    Returns
    -------
    ndarray, shape (n, 3, 3)
        Cauchy stress (Pa).

    Raises
    ------
    InputError
        ``t`` is not 1-D, its length differs from the number of F, the times decrease (the
        message names the index), or an F is invalid (shape, non-finite, det F <= 0).
    NumericalError
        Non-finite generated derivatives at a point (fibre exponential overflow).
    """
    t = np.asarray(t, dtype=np.float64)
    F = kin.as_batch(F)
    if t.ndim != 1 or t.shape[0] != F.shape[0]:
        raise InputError(f"times ({t.shape}) and deformation gradients ({F.shape[0]}) must match in length.")
    if t.size > 1 and not (np.diff(t) >= 0).all():
        i = int(np.argmax(np.diff(t) < 0)) + 1
        raise InputError(f"times must not decrease: t[{i}] = {t[i]:g} s < t[{i-1}] = {t[i-1]:g} s.")
    S_iso0, S_vol = pk2_parts(material, F)
    S = np.empty_like(S_iso0)
    state = None
    for n in range(t.size):
        dt = 0.0 if n == 0 else t[n] - t[n - 1]
        S[n], state = viscous_step(material, state, dt, S_iso0[n], S_vol[n])
    return kin.cauchy_from_pk2(F, S)
