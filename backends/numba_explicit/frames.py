"""What a numba run stores at a ParaView frame besides the displacement (``Result.frame_state``).

After a call of the time loop the positions are x^{n+1}, the velocities v^{n+1/2}, and the
element blocks hold the Prony state of step n (history stresses H, isochoric S0_old) with the
step dt just taken (``S_DTPREV``): the next element pass computes the stress at x^{n+1} from
exactly these, and so does :func:`cfm_core.post.fields.element_stress`.
"""

from __future__ import annotations

import numpy as np

from .kernels import layout as K


def frame_state(prep, ne: int, k: int) -> dict:
    """Velocity (n, 3) (m/s) and, for k > 0 Prony terms, ``prony_H`` (k, ne, 6), ``prony_S0``
    (ne, 6) (Pa, Voigt 11, 22, 33, 12, 23, 13) and ``prony_dt`` (s), copies."""
    from .solver import per_element

    out = {"velocity": prep.st[1].copy()}
    if k > 0:
        H = per_element(prep.st[4], 6 * k, 0, 6 * k, ne)
        out["prony_H"] = np.ascontiguousarray(H.reshape(ne, k, 6).transpose(1, 0, 2))
        out["prony_S0"] = per_element(prep.st[3], K.ED_N, K.ED_S0, 6, ne)
        out["prony_dt"] = float(prep.sc[K.S_DTPREV])
    return out
