"""Device arrays of one run: geometry, masses, constraints, contact node data, initial state.

Geometry is the explicit layer's (``cfm_backends.explicit.geometry``, numpy float64: exact
volume, mean gradients B, hourglass vectors G, characteristic length L, lumped masses), the same
the numba backend uses, so both explicit backends see the same mesh to the last bit; it is computed in float64 and then converted
to the run's dtype. Every tensor is allocated on the run's device; nothing in the time loop
assumes CPU tensors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cfm_backends.explicit import geometry
from cfm_backends.explicit.checks import check_model
from cfm_backends.explicit.options import initial_velocity


@dataclass
class Arrays:
    """Fixed device tensors of a run (layouts: component first, element or node last)."""

    idx: object           # (8 N,) int64: node of (local node a, element e) at a N + e
    B: object             # (8, 3, N) mean shape-function gradients (1/m)
    BV: object            # (8, 3, N) V0 B (m^2)
    G: object             # (8, 4, N) hourglass vectors (-)
    L: object             # (N,) characteristic lengths (m)
    V0: object            # (N,) reference volumes (m^3)
    hgc: object           # (N,) -Q_hg rho V0^(2/3) / 4 (kg/m), rho per element with parts
    mass: object          # (n,) lumped nodal masses (kg; 1 for massless nodes, which are fixed)
    free: object          # (3, n) 1 on free dofs, 0 on fixed and prescribed ones
    pmask: object         # (3, n) 1 on prescribed dofs, or None
    sphere: object        # contact.SphereNodes or None
    plane: object         # contact.PlaneNodes or None
    pnodes: object        # (p,) prescribed nodes (int64) or None
    n: int
    ne: int


def _tensor(a, dtype, device):
    import torch

    return torch.as_tensor(np.ascontiguousarray(a), dtype=dtype, device=device)


def build(model, o, device, dtype):
    """(Arrays, initial uv (6, n), prony history size k) on ``device`` in ``dtype``; o: TorchOptions.

    With parts the hourglass factor uses each element's density and k is the largest part's
    number of Prony terms (the history of the others is padded, see :mod:`.parts`)."""
    import torch

    from .contact import PlaneNodes, SphereNodes

    nodes, hexes = check_model(model)
    n, ne = nodes.shape[0], hexes.shape[0]
    rho = float(model.density) if not model.parts else model.element_density()   # (N,) with parts
    V0, B, G, L = geometry.hex_geometry(nodes, hexes)
    mass, free, pm, pn = geometry.constraints(model, nodes, hexes, V0)
    pmask = None
    pnodes = None
    if model.prescribed is not None:
        pmask = _tensor(pm.T, dtype, device)
        pnodes = _tensor(pn, torch.int64, device)
    T = lambda a: _tensor(a, dtype, device)  # noqa: E731
    hgc = -o.hourglass * (rho * V0 ** (2.0 / 3.0) / 4.0)
    sphere = plane = None
    if model.sphere is not None:
        sn = np.ascontiguousarray(model.sphere_nodes, dtype=np.int64)
        sphere = SphereNodes(_tensor(sn, torch.int64, device), T(nodes[sn].T), T(mass[sn]), T(free[sn].T))
    if model.plane is not None:
        pl = np.ascontiguousarray(model.plane_nodes, dtype=np.int64)
        plane = PlaneNodes(_tensor(pl, torch.int64, device), T(nodes[pl, 2]), T(free[pl].T))
    arrays = Arrays(
        idx=_tensor(hexes.T.reshape(-1), torch.int64, device),
        B=T(B.transpose(1, 2, 0)), BV=T((B * V0[:, None, None]).transpose(1, 2, 0)),
        G=T(G.transpose(1, 2, 0)), L=T(L), V0=T(V0), hgc=T(hgc), mass=T(mass), free=T(free.T),
        pmask=pmask, sphere=sphere, plane=plane, pnodes=pnodes, n=n, ne=ne)
    uv = torch.zeros((6, n), dtype=dtype, device=device)
    v0 = initial_velocity(o, n, free, "torch")
    if v0 is not None:
        uv[3:6] = T(v0.T)
    k = max(int(np.asarray(p.material.prony_arrays()[0]).size) for p in model.part_list())
    return arrays, uv, k


def initial_state(k: int, ne: int, dtype, device):
    """Zero Prony history (k, 6, N) and zero previous S0, S, E (6, N) (symmetric tensors as 6-vectors)."""
    import torch

    from .element import ElementState

    z = lambda *shape: torch.zeros(shape, dtype=dtype, device=device)  # noqa: E731
    return ElementState(z(k, 6, ne), z(6, ne), z(6, ne), z(6, ne))


def interp(t: float, times: np.ndarray, values: np.ndarray) -> float:
    """Prescribed displacement at t (host arithmetic, as numba's np.interp)."""
    return float(np.interp(t, times, values)) if math.isfinite(t) else float(values[-1])
