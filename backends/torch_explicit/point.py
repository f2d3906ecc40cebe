"""Material-point driver of the torch backend: Cauchy stress along a deformation history.

The solver's constitutive update on a batch: C, its eigen-decomposition and the material's
generated derivatives for all n points at once (``element.principal_stresses``), then the Prony
recurrence (``element.prony_update``) step by step in time, sigma = J^-1 F S F^T. Undeformed and
relaxed before t[0] (a deformation present at t[0] is a jump), as the numba backend's
``point_history``. No host synchronisation inside the time loop.
"""

from __future__ import annotations

import numpy as np

from cfm_backends.explicit import errors
from cfm_backends.explicit.checks import check_point_inputs
from cfm_core.errors import NumericalError

from . import material as mat
from .options import resolve_device, resolve_dtype


def point_history(material, t, F, device="cpu", dtype="float64") -> np.ndarray:
    """Cauchy stress (n, 6) in Pa (11, 22, 33, 12, 23, 13) along F (n, 3, 3) at times t (n,) in s."""
    import torch

    from .eigen import eig3_full
    from .element import det_and_cauchy_green, derivatives, full, inverted, matmul3, principal_stresses, prony_update

    t, F = check_point_inputs(t, F)
    dev, dt = resolve_device(device), resolve_dtype(dtype)
    n = t.shape[0]
    if n == 0:
        return np.zeros((0, 6))
    ghd = mat.grad_hess_diag(material)
    p = mat.parameters(material)
    gam, tau, ginf = mat.prony(material)
    k = len(gam)
    with torch.inference_mode():
        f = torch.as_tensor(F.transpose(1, 2, 0).copy(), dtype=dt, device=dev)       # (3, 3, n)
        J, C = det_and_cauchy_green(f)
        inv = inverted(J)
        Cs = torch.where(inv, torch.eye(3, dtype=dt, device=dev)[:, :, None], C)
        m, Q = eig3_full(Cs)
        D = derivatives(ghd, p, m)
        S0, S_vol = principal_stresses(D, Q)
        steps = np.diff(t, prepend=t[0])
        fac = np.array([mat.prony_factors(float(h), gam, tau) for h in steps]).reshape(n, 2, k)
        fac = torch.as_tensor(fac, dtype=dt, device=dev)
        H = torch.zeros((k, 6, 1), dtype=dt, device=dev)
        S0_old = torch.zeros((6, 1), dtype=dt, device=dev)
        S = torch.empty_like(S0)
        for i in range(n):
            s0 = S0[:, i:i + 1]
            Si, H = prony_update(s0, S_vol[:, i:i + 1], H, S0_old, fac[i], ginf)
            S[:, i:i + 1] = Si
            S0_old = s0
        sig = matmul3(matmul3(f, full(S)), f.transpose(0, 1)) * (1.0 / J)     # J^-1 F S F^T
        out = torch.stack([sig[0, 0], sig[1, 1], sig[2, 2], sig[0, 1], sig[1, 2], sig[0, 2]], dim=1)
        nonfinite = ~torch.isfinite(D.sum(0)) | ~torch.isfinite(out.sum(1))
        failed = inv | nonfinite
        first = int(torch.where(failed, torch.arange(n, device=dev), n).amin())
    if first < n:
        if bool(inv[first]):
            raise NumericalError(f"point {first} (t = {t[first]:.6g} s): det F = {float(J[first]):.4g} <= 0 "
                                 f"(inverted).", time=float(t[first]), element=first, quantity="J")
        raise errors.nonfinite(material, f"point {first} (t = {t[first]:.6g} s)", m[:, first].tolist(),
                               float(J[first]), float(t[first]), first, float32=dt == torch.float32)
    return out.to("cpu", torch.float64).numpy()
