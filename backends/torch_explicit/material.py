"""The material's generated torch code, as the solver calls it (one definition, no copies).

The solver needs the gradient d psi / d m_a (stress) and the diagonal Hessian d2 psi / d m_a^2
(stable-step modulus) of the isochoric and volumetric energies in the eigenvalues m_a of C at every
element and step. Both come from the material's symbolic definition through the core's code
generator, ``material.kernels("torch")``: its ``psi_grad_hess_diag`` (the 12 values with shared
subexpressions: J^(-2/3) and the fibre exponentials once), or, for kernels generated before that
function existed, ``psi_grad`` then ``psi_hess_diag``. Parameters are passed as Python floats, so
that products of parameters stay host arithmetic and only the tensor ops run on the device.
"""

from __future__ import annotations

import math

import numpy as np

from cfm_core.errors import InputError
from cfm_core.material.prony import gamma_inf


def grad_hess_diag(material):
    """f(m1, m2, m3, p) -> 12 tensors: psi_grad's 6 values, then psi_hess_diag's 6 (Pa).

    Raises InputError when the material offers no torch code.
    """
    kernels = getattr(material, "kernels", None)
    if kernels is None:
        raise InputError(f"material '{getattr(material, 'name', material)}' has no generated torch code: the "
                         f"torch backend needs a cfm_core Material (material.kernels('torch')).")
    k = kernels("torch")
    try:
        return k.psi_grad_hess_diag
    except AttributeError:
        grad, hess = k.psi_grad, k.psi_hess_diag

    def both(m1, m2, m3, p):
        return tuple(grad(m1, m2, m3, p)) + tuple(hess(m1, m2, m3, p))

    return both


def parameters(material) -> list[float]:
    """The energy parameters and s_iso as Python floats (``material.param_array()``)."""
    return [float(x) for x in np.asarray(material.param_array(), dtype=np.float64)]


def prony(material) -> tuple[list[float], list[float], float]:
    """(gammas, taus (s), gamma_inf) of the active Prony series as Python floats."""
    gam, tau = (np.asarray(a, dtype=np.float64).reshape(-1) for a in material.prony_arrays())
    return gam.tolist(), tau.tolist(), gamma_inf(gam)


def prony_factors(dt: float, gammas, taus) -> tuple[list[float], list[float]]:
    """(decay_k, gain_k) = (exp(-dt/tau_k), gamma_k (tau_k/dt)(1 - exp(-dt/tau_k))); dt = 0: a jump.

    Host arithmetic with the numba backend's formulas (series for dt/tau < 1e-8).
    """
    decay, gain = [], []
    for g, tau in zip(gammas, taus):
        x = dt / tau
        if x < 1e-8:
            decay.append(1.0 - x)
            gain.append(g * (1.0 - 0.5 * x))
        else:
            decay.append(math.exp(-x))
            gain.append(g * (-math.expm1(-x) / x))
    return decay, gain
