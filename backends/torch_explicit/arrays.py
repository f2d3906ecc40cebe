"""Device arrays of one run: geometry, masses, constraints, contact node data, initial state.

Geometry is the numba backend's (``cfm_backends.numba_explicit.geometry``, numpy float64: exact
volume, mean gradients B, hourglass vectors G, characteristic length L, lumped masses), so both
explicit backends see the same mesh to the last bit; it is computed in float64 and then converted
to the run's dtype. Every tensor is allocated on the run's device; nothing in the time loop
assumes CPU tensors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cfm_core.errors import InputError


@dataclass
class Arrays:
    """Fixed device tensors of a run (layouts: component first, element or node last)."""

    idx: object           # (8 N,) int64: node of (local node a, element e) at a N + e
    B: object             # (8, 3, N) mean shape-function gradients (1/m)
    BV: object            # (8, 3, N) V0 B (m^2)
    G: object             # (8, 4, N) hourglass vectors (-)
    L: object             # (N,) characteristic lengths (m)
    V0: object            # (N,) reference volumes (m^3)
    hgc: object           # (N,) -Q_hg rho V0^(2/3) / 4 (kg/m)
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


def check_model(model):
    """(nodes (n, 3) float64, hexes (e, 8) int64) after the numba backend's input checks."""
    nodes = np.ascontiguousarray(model.nodes, dtype=np.float64)
    hexes = np.ascontiguousarray(model.hexes, dtype=np.int64)
    if nodes.ndim != 2 or nodes.shape[1] != 3 or hexes.ndim != 2 or hexes.shape[1] != 8:
        raise InputError(f"model '{model.name}': nodes must be (n, 3) and hexes (e, 8); "
                         f"got {nodes.shape}, {hexes.shape}.")
    n = nodes.shape[0]
    if hexes.shape[0] == 0 or hexes.min() < 0 or hexes.max() >= n:
        raise InputError(f"model '{model.name}': hexes must index nodes 0..{n - 1} (and there must be at least one).")
    if not (float(model.density) > 0.0):
        raise InputError(f"model '{model.name}': density = {model.density!r} kg/m^3 must be > 0.")
    if not (float(model.end_time) > 0.0):
        raise InputError(f"model '{model.name}': end_time = {model.end_time!r} s must be > 0.")
    sph = model.sphere
    if sph is not None and not (sph.radius > 0.0 and sph.mass > 0.0):
        raise InputError(f"model '{model.name}': sphere radius {sph.radius!r} m and mass {sph.mass!r} kg must be > 0.")
    pr = model.prescribed
    if pr is not None and pr.dof not in (0, 1, 2):
        raise InputError(f"model '{model.name}': prescribed dof = {pr.dof!r}; use 0, 1 or 2.")
    return nodes, hexes


def build(model, o: dict, device, dtype):
    """(Arrays, initial uv (6, n), prony history size k) on ``device`` in ``dtype``."""
    import torch

    from cfm_backends.numba_explicit import geometry

    from .contact import PlaneNodes, SphereNodes

    nodes, hexes = check_model(model)
    n, ne = nodes.shape[0], hexes.shape[0]
    rho = float(model.density)
    V0, B, G, L = geometry.hex_geometry(nodes, hexes)
    mass = geometry.lumped_mass(hexes, V0, rho, n)
    free = np.ones((n, 3))
    free[mass <= 0.0] = 0.0
    mass = np.where(mass > 0.0, mass, 1.0)
    fixed = np.asarray(model.fixed_dofs, dtype=np.int64).reshape(-1, 2)
    free[fixed[:, 0], fixed[:, 1]] = 0.0
    pmask = None
    pnodes = None
    pr = model.prescribed
    if pr is not None:
        pn = np.ascontiguousarray(pr.nodes, dtype=np.int64)
        free[pn, pr.dof] = 0.0
        pm = np.zeros((n, 3))
        pm[pn, pr.dof] = 1.0
        pmask = _tensor(pm.T, dtype, device)
        pnodes = _tensor(pn, torch.int64, device)
    T = lambda a: _tensor(a, dtype, device)  # noqa: E731
    hgc = -o["hourglass"] * (rho * V0 ** (2.0 / 3.0) / 4.0)
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
    if o["initial_velocity"] is not None:
        v0 = np.asarray(o["initial_velocity"], dtype=np.float64)
        if v0.shape != (n, 3):
            raise InputError(f"torch backend: initial_velocity must have shape ({n}, 3), got {v0.shape}.")
        uv[3:6] = T((v0 * free).T)
    k = int(np.asarray(model.material.prony_arrays()[0]).size)
    return arrays, uv, k


def initial_state(k: int, ne: int, dtype, device):
    """Zero Prony history (k, 3, 3, N) and zero previous S0, S, E (3, 3, N)."""
    import torch

    from .element import ElementState

    z = lambda *shape: torch.zeros(shape, dtype=dtype, device=device)  # noqa: E731
    return ElementState(z(k, 3, 3, ne), z(3, 3, ne), z(3, 3, ne), z(3, 3, ne))


def interp(t: float, times: np.ndarray, values: np.ndarray) -> float:
    """Prescribed displacement at t (host arithmetic, as numba's np.interp)."""
    return float(np.interp(t, times, values)) if math.isfinite(t) else float(values[-1])
