"""The material-point driver of the numba backend: stress along a prescribed history of F.

Runs the element blocks' constitutive stages (``element.py``) on a block of one column, so that
``cfm point --backend numba`` checks exactly the code the drop test runs.
"""

# >>> standalone (removed when the kernels are concatenated into a generated module)
import numpy as np
from numba import njit
from cfm_backends.numba_cache import key_on_folder

from .constitutive import first_piola, prony_step
from .element import eigen_block, eigen_fallback, material_block, prony_block, stress_block
from .layout import *  # noqa: F401,F403

key_on_folder(__file__)  # numba's cache of these kernels is keyed on every file of the folder
# <<< standalone


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def point_history(t, F, p, gam, tau, ginf, out):
    """Cauchy stress sigma = J^-1 F S F^T (Pa) along a history F (n, 3, 3) at times t (n,) (s).

    Starts undeformed and relaxed at t[0] (a deformation present at t[0] is a jump). Writes
    out (n, 6) in the order 11, 22, 33, 12, 23, 13. Returns (status, index, J, m0, m1, m2) of
    the first failure (status 0: none; 1 inverted, m = 0; 2 non-finite).
    """
    k = gam.shape[0]
    ed = np.zeros(ED_N * BLOCK)
    eh = np.zeros(6 * k * BLOCK)
    wk = np.zeros(W_N * BLOCK)
    decay = np.zeros(k)
    gain = np.zeros(k)
    for n in range(t.shape[0]):
        prony_step(0.0 if n == 0 else t[n] - t[n - 1], gam, tau, decay, gain)
        for r in range(9):
            wk[(W_F + r) * BLOCK] = F[n, r // 3, r % 3]
        eigen_block(wk, 1)
        eigen_fallback(wk, 1)
        material_block(wk, p, 1)
        stress_block(wk, 1)
        prony_block(wk, ed, eh, decay, gain, ginf, 1)
        J = wk[W_J * BLOCK]
        st = wk[W_ST * BLOCK]
        if st != 0.0:
            if st == 1.0:
                return 1, n, J, 0.0, 0.0, 0.0
            return 2, n, J, wk[W_M * BLOCK], wk[(W_M + 1) * BLOCK], wk[(W_M + 2) * BLOCK]
        f00 = F[n, 0, 0]
        f01 = F[n, 0, 1]
        f02 = F[n, 0, 2]
        f10 = F[n, 1, 0]
        f11 = F[n, 1, 1]
        f12 = F[n, 1, 2]
        f20 = F[n, 2, 0]
        f21 = F[n, 2, 1]
        f22 = F[n, 2, 2]
        p00, p01, p02, p10, p11, p12, p20, p21, p22 = first_piola(
            f00, f01, f02, f10, f11, f12, f20, f21, f22, wk[W_S * BLOCK], wk[(W_S + 1) * BLOCK],
            wk[(W_S + 2) * BLOCK], wk[(W_S + 3) * BLOCK], wk[(W_S + 4) * BLOCK], wk[(W_S + 5) * BLOCK])
        ij = 1.0 / J
        out[n, 0] = (p00 * f00 + p01 * f01 + p02 * f02) * ij
        out[n, 1] = (p10 * f10 + p11 * f11 + p12 * f12) * ij
        out[n, 2] = (p20 * f20 + p21 * f21 + p22 * f22) * ij
        out[n, 3] = (p00 * f10 + p01 * f11 + p02 * f12) * ij
        out[n, 4] = (p10 * f20 + p11 * f21 + p12 * f22) * ij
        out[n, 5] = (p00 * f20 + p01 * f21 + p02 * f22) * ij
    return 0, -1, 1.0, 0.0, 0.0, 0.0
