"""Pieces of the constitutive update shared by the element blocks and the point driver (numba).

The update itself (docs/conventions.md section 2) is written once, as the block stages of
``element.py``: C = F^T F = Q diag(m) Q^T (``eigen_block``), the material's derivatives with
respect to the eigenvalues m_a of C (``material_block``; ``psi_grad_hess_diag`` returns
psi_grad's 6 values then psi_hess_diag's 6, see ``codegen``), principal stresses and moduli
(``stress_block``) and the Prony series (``prony_block``). Here: the material stubs for
importing the kernels on their own, the status codes, the step's Prony factors and P = F S.
Symmetric tensors are 6-vectors in the order 11, 22, 33, 12, 23, 13.
"""

# >>> standalone (removed when the kernels are concatenated into a generated module)
import math

import numpy as np
from numba import njit
from cfm_backends.numba_cache import key_on_folder

from .layout import FASTMATH

key_on_folder(__file__)  # numba's cache of these kernels is keyed on every file of the folder


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


@njit(inline="always", fastmath=FASTMATH, error_model="numpy")
def first_piola(f00, f01, f02, f10, f11, f12, f20, f21, f22, s00, s11, s22, s01, s12, s02):
    """P = F S (row-major 9 values, Pa) for F and a symmetric S given by its 6 components."""
    return (f00 * s00 + f01 * s01 + f02 * s02, f00 * s01 + f01 * s11 + f02 * s12, f00 * s02 + f01 * s12 + f02 * s22,
            f10 * s00 + f11 * s01 + f12 * s02, f10 * s01 + f11 * s11 + f12 * s12, f10 * s02 + f11 * s12 + f12 * s22,
            f20 * s00 + f21 * s01 + f22 * s02, f20 * s01 + f21 * s11 + f22 * s12, f20 * s02 + f21 * s12 + f22 * s22)
