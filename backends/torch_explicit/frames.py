"""What a torch run stores at a ParaView frame besides the displacement (``Result.frame_state``).

After a step the positions are x^{n+1}, the velocities v^{n+1/2}, and the element state holds the
Prony history H and isochoric S0 of step n with the step dt just taken: the next element pass
computes the stress at x^{n+1} from exactly these, and so does
:func:`cfm_core.post.fields.element_stress`. A model with parts stores its Prony state per part
instead (:func:`.parts.frame_state_parts`: ``velocity``, ``prony_dt`` and ``parts``, a list of
``name``, ``elements``, ``prony_H``, ``prony_S0`` per part).
"""

from __future__ import annotations

import numpy as np


def frame_state(v, state, dt: float, ne: int) -> dict:
    """Velocity (n, 3) (m/s) from v (3, n) and, with Prony terms, ``prony_H`` (k, ne, 6),
    ``prony_S0`` (ne, 6) (Pa, Voigt 11, 22, 33, 12, 23, 13) and ``prony_dt`` (s), float64 copies."""
    import torch

    def host(a):
        return a.to("cpu", torch.float64).numpy().copy()

    out = {"velocity": host(v.T)}
    if state.H.shape[0] > 0:
        out["prony_H"] = np.ascontiguousarray(host(state.H)[:, :, :ne].transpose(0, 2, 1))
        out["prony_S0"] = np.ascontiguousarray(host(state.S0)[:, :ne].T)
        out["prony_dt"] = float(dt)
    return out
