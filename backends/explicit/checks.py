"""Checks every explicit run makes on its model before any work (InputError, SI units)."""

from __future__ import annotations

import numpy as np

from cfm_core.errors import InputError


def check_model(model) -> tuple[np.ndarray, np.ndarray]:
    """The model's nodes and hexahedra as contiguous arrays, after checking what an explicit run needs.

    Parameters
    ----------
    model : cfm_core.scene.model.Model
        The model to run.

    Returns
    -------
    nodes : (n, 3) ndarray of float64
        Reference coordinates (m).
    hexes : (e, 8) ndarray of int64
        Connectivity.

    Raises
    ------
    InputError
        Wrong array shapes, node indices out of range or no element, density or end time not
        positive, a sphere without positive radius (m) and mass (kg), a flat impactor with a sharp
        rim (edge_radius = 0 m), a prescribed dof not 0, 1 or 2.
    """
    nodes = np.ascontiguousarray(model.nodes, dtype=np.float64)
    hexes = np.ascontiguousarray(model.hexes, dtype=np.int64)
    if nodes.ndim != 2 or nodes.shape[1] != 3 or hexes.ndim != 2 or hexes.shape[1] != 8:
        raise InputError(f"model '{model.name}': nodes must be (n, 3) and hexes (e, 8); "
                         f"got {nodes.shape}, {hexes.shape}.")
    n = nodes.shape[0]
    if hexes.shape[0] == 0 or hexes.min() < 0 or hexes.max() >= n:
        raise InputError(f"model '{model.name}': hexes must index nodes 0..{n - 1} (and there must be at least one).")
    sph = model.sphere
    if sph is not None and sph.shape == "flat" and not float(sph.edge_radius) > 0.0:
        raise InputError(f"model '{model.name}': [impactor] edge_radius = {sph.edge_radius!r} m: a flat impactor with a "
                         f"sharp rim puts a stress singularity at the rim, which an explicit run cannot resolve; give "
                         f"a rounded rim (0 < edge_radius < radius, m; at least about two element sizes to resolve "
                         f"it) or run the implicit skfem backend, which accepts 0 with a warning.")
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


def check_point_inputs(t, F) -> tuple[np.ndarray, np.ndarray]:
    """Times and deformation gradients of a material-point history as float64 arrays.

    Parameters
    ----------
    t : (n,) array_like
        Times (s), not decreasing.
    F : (n, 3, 3) array_like
        Deformation gradients (-).

    Returns
    -------
    t : (n,) ndarray
    F : (n, 3, 3) ndarray

    Raises
    ------
    InputError
        Different numbers of times and gradients, or decreasing times.
    """
    t = np.ascontiguousarray(t, dtype=np.float64).reshape(-1)
    F = np.ascontiguousarray(F, dtype=np.float64).reshape(-1, 3, 3)
    if t.shape[0] != F.shape[0]:
        raise InputError(f"point: {t.shape[0]} times but {F.shape[0]} deformation gradients.")
    if t.size > 1 and not (np.diff(t) >= 0).all():
        raise InputError("point: times must not decrease.")
    return t, F
