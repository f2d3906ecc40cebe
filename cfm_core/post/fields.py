"""Per-element and nodal fields of a stored frame, for the ParaView output and ``cfm fields``.

The element fields are evaluated as the explicit element does: one deformation gradient per
element, F = sum_a x_a (x) B_a with B the mean shape-function gradient over the reference
element (Flanagan-Belytschko uniform-strain hexahedron, exact 2x2x2 Gauss integration; the
element centre value on a parallelepiped). Elastic quantities come from the numpy reference
material (:mod:`cfm_core.material.reference`), exact for the material definition.

The stress is the one the solver used when the backend stored its Prony state at the frame
(``Result.frame_state``: history stresses H, previous isochoric S0 and the step dt): the same
exact recurrence (:func:`cfm_core.material.prony.update`) applied to the frame's positions gives
the viscoelastic stress of the solver's next element pass at those positions. Without that state
a viscoelastic material's stress fields are the instantaneous (elastic) response and carry the
suffix ``_instantaneous`` in their names, so that nothing is called the solver's stress that
is not. An elastic material (or ``elastic = true``) has no history: its stress is exact.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..material import kinematics as kin
from ..material import prony
from ..material import reference as ref
from ..scene.mesh import _shape_gradients
from .part_state import part_prony_state, part_prony_states  # the frame_state structure of parts


@dataclass(frozen=True)
class FieldInfo:
    """One output field: VTU array name (with its unit), components, unit and meaning."""

    key: str
    where: str          # "cell" or "point"
    components: int
    unit: str
    description: str

    def array_name(self, suffix: str = "") -> str:
        """The array name in the VTU file: ``key[suffix] [unit]`` (unit "-" for dimensionless)."""
        return f"{self.key}{suffix} [{self.unit}]"


#: Every field ``--fields`` accepts (stress fields: Cauchy, Pa; strains: logarithmic, -).
FIELDS = {f.key: f for f in (
    FieldInfo("cauchy_stress", "cell", 6, "Pa", "Cauchy stress, components 11, 22, 33, 12, 23, 13"),
    FieldInfo("pressure", "cell", 1, "Pa", "pressure -trace(sigma)/3 (positive in compression)"),
    FieldInfo("von_mises", "cell", 1, "Pa", "von Mises equivalent stress sqrt(3/2 s:s), s the deviator"),
    FieldInfo("J", "cell", 1, "-", "volume ratio det F"),
    FieldInfo("log_strain", "cell", 3, "-", "principal logarithmic strains ln(lambda), descending"),
    FieldInfo("max_shear_strain", "cell", 1, "-", "maximum logarithmic shear strain (e_max - e_min) / 2"),
    FieldInfo("energy_density", "cell", 1, "J/m^3", "instantaneous strain energy psi per reference volume"),
    FieldInfo("fibre_switch", "cell", 3, "-", "1 where the fibre family of the isochoric principal stretch "
              "pair (1,2), (2,3), (1,3) (stretches descending) is stretched, x_ab >= 1, else 0; NaN in "
              "elements whose material has no fibre families (no circular-fibers term)"),
    FieldInfo("part", "cell", 1, "-", "part index in the scene's part order, 0 for a one-part specimen (names: "
              "the VTU header note and fields.json 'parts')"),
    FieldInfo("material_id", "cell", 1, "-", "index of the element's material among the run's distinct materials "
              "(name, parameters, moduli, elastic), in part order; 0 for one material (names: fields.json 'parts')"),
    FieldInfo("displacement", "point", 3, "m", "nodal displacement x - X (points are written deformed)"),
    FieldInfo("velocity", "point", 3, "m/s", "nodal velocity (explicit backends: the half-step v^(n+1/2))"),
)}
STRESS_FIELDS = ("cauchy_stress", "pressure", "von_mises")
DEFAULT_FIELDS = ("cauchy_stress", "pressure", "von_mises", "J", "log_strain", "max_shear_strain",
                  "energy_density", "fibre_switch", "part", "material_id", "displacement", "velocity")
#: The energy term whose three circular fibre families ``fibre_switch`` describes.
FIBRE_TERM = "circular-fibers"


def parse_fields(text) -> tuple[str, ...]:
    """The field keys of a ``--fields`` value.

    Parameters
    ----------
    text : str or sequence of str or None
        Comma-separated keys, ``"all"``, or None for :data:`DEFAULT_FIELDS`.

    Returns
    -------
    tuple of str
        Known keys in the order of :data:`FIELDS`.

    Raises
    ------
    InputError
        An unknown key (names it and lists the keys allowed).
    """
    if text is None or text == "all":
        return DEFAULT_FIELDS if text is None else tuple(FIELDS)
    keys = [k.strip() for k in (text.split(",") if isinstance(text, str) else text) if k.strip()]
    bad = [k for k in keys if k not in FIELDS]
    if bad or not keys:
        raise InputError(f"--fields: unknown field {bad[0] if bad else '(none given)'!r}; allowed: "
                         f"{', '.join(FIELDS)} (comma-separated) or 'all'.")
    return tuple(k for k in FIELDS if k in keys)


def mean_gradients(nodes, hexes) -> np.ndarray:
    """Mean shape-function gradients B (e, 8, 3) (1/m) over each reference hexahedron.

    Parameters
    ----------
    nodes : array_like, shape (n, 3)
        Reference coordinates (m).
    hexes : array_like, shape (e, 8)
        Node indices, VTK hexahedron order.

    Returns
    -------
    ndarray, shape (e, 8, 3)
        (1/V0) int dN_a/dX dV (1/m), exact with 2x2x2 Gauss points; F = sum_a x_a (x) B_a is
        the uniform-strain deformation gradient of the explicit element.
    """
    X = np.asarray(nodes, dtype=np.float64)[np.asarray(hexes)]
    g = 1.0 / np.sqrt(3.0)
    points = np.array(list(itertools.product((-g, g), repeat=3)))
    dN = _shape_gradients(points)                                # (p, 8, 3)
    Jm = np.einsum("eai,pak->epik", X, dN)
    det = np.linalg.det(Jm)
    dNdX = np.einsum("pak,epkj->epaj", dN, np.linalg.inv(Jm))
    return np.einsum("ep,epaj->eaj", det, dNdX) / det.sum(axis=1)[:, None, None]


def deformation_gradients(B, hexes, x) -> np.ndarray:
    """F (e, 3, 3) (-) of each element from current node positions x (n, 3) (m) and B (e, 8, 3)."""
    return np.swapaxes(np.asarray(x, dtype=np.float64)[np.asarray(hexes)], 1, 2) @ B


def _from_principal(values, Q):
    """Q diag(values) Q^T batched, as :func:`cfm_core.material.kinematics.from_principal` (matmul: faster)."""
    return (Q * values[:, None, :]) @ np.swapaxes(Q, 1, 2)


def element_stress(material, F, state=None, principal=None):
    """Second Piola-Kirchhoff and Cauchy stress of elements at F, as the solver evaluates them.

    Parameters
    ----------
    material : Material
        The bound material of the run.
    F : ndarray, shape (e, 3, 3)
        Deformation gradients (-).
    state : dict, optional
        The backend's Prony state at the frame: ``prony_H`` (k, e, 6) and ``prony_S0`` (e, 6)
        (Pa, Voigt 11, 22, 33, 12, 23, 13) and ``prony_dt`` (s), the step that led to the frame.
    principal : tuple, optional
        ``(m, Q, J)`` of :func:`cfm_core.material.kinematics.principal` of F, when already known.

    Returns
    -------
    sigma : ndarray, shape (e, 3, 3)
        Cauchy stress (Pa).
    exact : bool
        True when this is the solver's stress (elastic material, or Prony state given); False:
        the instantaneous response of a viscoelastic material.
    """
    m, Q, J = principal if principal is not None else kin.principal(F)
    (g,) = ref.principal_response(material, m, "psi_grad")
    S_iso, S_vol = _from_principal(2.0 * g[:, :3], Q), _from_principal(2.0 * g[:, 3:], Q)
    gammas, taus = material.prony_arrays()
    exact = gammas.size == 0 or (state is not None and "prony_H" in state)
    if gammas.size == 0 or not exact:
        S = S_iso + S_vol
    else:
        H = kin.from_voigt(np.asarray(state["prony_H"], dtype=np.float64))      # (k, e, 3, 3)
        S0_old = kin.from_voigt(np.asarray(state["prony_S0"], dtype=np.float64))
        _, S_visc = prony.update(H, S0_old, S_iso, float(state["prony_dt"]), gammas, taus)
        S = S_visc + S_vol
    return F @ S @ np.swapaxes(F, 1, 2) / J[:, None, None], exact


def has_fibre_families(material) -> bool:
    """True when the material has the circular fibre families :data:`FIBRE_TERM` (``fibre_switch``
    is defined for its elements; NaN elsewhere)."""
    return any(t.name == FIBRE_TERM for t in material.spec.isochoric)


def _fibre_switch(m, J) -> np.ndarray:
    """(e, 3) 0/1: x_ab >= 1 for the isochoric principal stretch pairs (1,2), (2,3), (1,3), descending."""
    mb = np.sort(m, axis=1)[:, ::-1] * J[:, None] ** (-2.0 / 3.0)      # isochoric squared stretches
    pairs = ((0, 1), (1, 2), (0, 2))
    return np.stack([((mb[:, a] + mb[:, b]) / 2.0 >= 1.0).astype(np.float64) for a, b in pairs], axis=1)


def cell_fields(material, F, keys, state=None, material_id=None, principal=None) -> tuple[dict, bool]:
    """The element fields ``keys`` of elements of one material at deformation gradients F.

    Parameters
    ----------
    material : Material
        The bound material.
    F : ndarray, shape (e, 3, 3)
        Element deformation gradients (-).
    keys : sequence of str
        Keys of :data:`FIELDS` (point fields are ignored here).
    state : dict, optional
        Prony state of the frame for these elements (:func:`element_stress`).
    material_id : ndarray, shape (e,), optional
        Material index per element; zeros when None (also ``part``: zeros).
    principal : tuple, optional
        ``(m, Q, J)``: eigenvalues (e, 3) and eigenvectors (e, 3, 3) of C = F^T F and det F,
        when already known.

    Returns
    -------
    fields : dict of str to ndarray
        Key -> (e,) or (e, components) array in the unit of :data:`FIELDS`; ``fibre_switch`` is
        NaN when the material has no fibre families (:func:`has_fibre_families`).
    exact : bool
        Whether the stress fields are the solver's (see :func:`element_stress`).
    """
    out, exact = {}, True
    if principal is None:
        J = np.linalg.det(F)
        m, Q = np.linalg.eigh(np.swapaxes(F, 1, 2) @ F)     # as kinematics.principal, with matmul
    else:
        m, Q, J = principal
    if any(k in keys for k in STRESS_FIELDS):
        sigma, exact = element_stress(material, F, state, principal=(m, Q, J))
        if "cauchy_stress" in keys:
            out["cauchy_stress"] = kin.to_voigt(sigma)
        p = -np.trace(sigma, axis1=1, axis2=2) / 3.0
        if "pressure" in keys:
            out["pressure"] = p
        if "von_mises" in keys:
            dev = sigma + p[:, None, None] * np.eye(3)
            out["von_mises"] = np.sqrt(1.5 * np.einsum("eij,eij->e", dev, dev))
    if "J" in keys:
        out["J"] = J
    eps = 0.5 * np.log(np.sort(m, axis=1)[:, ::-1])
    if "log_strain" in keys:
        out["log_strain"] = eps
    if "max_shear_strain" in keys:
        out["max_shear_strain"] = 0.5 * (eps[:, 0] - eps[:, 2])
    if "energy_density" in keys:
        (e,) = ref.principal_response(material, m, "psi_energy")
        out["energy_density"] = e[:, 0] + e[:, 1]
    if "fibre_switch" in keys:
        out["fibre_switch"] = (_fibre_switch(m, J) if has_fibre_families(material)
                               else np.full((len(F), 3), np.nan))
    if "part" in keys:
        out["part"] = np.zeros(len(F))
    if "material_id" in keys:
        out["material_id"] = (np.zeros(len(F)) if material_id is None
                              else np.asarray(material_id, dtype=np.float64))
    return out, exact


def model_cell_fields(model, F, keys, state=None) -> tuple[dict, bool]:
    """The element fields ``keys`` of a model: each element with its own part's material.

    Parameters
    ----------
    model : Model
        The model that ran (:meth:`~cfm_core.scene.model.Model.part_list`).
    F : ndarray, shape (e, 3, 3)
        Element deformation gradients (-), all elements of the model.
    keys : sequence of str
        Keys of :data:`FIELDS`.
    state : dict, optional
        The frame's ``Result.frame_state`` entry; its Prony state in either structure of
        :func:`part_prony_states`.

    Returns
    -------
    fields : dict of str to ndarray
        As :func:`cell_fields`, every element filled by its part; ``part`` the part index and
        ``material_id`` the index in :func:`distinct_materials` (float arrays).
    exact : bool
        True when the stress of every part is the solver's.

    Raises
    ------
    ValueError
        A Prony state whose structure does not match the parts (:func:`part_prony_states`).
    """
    parts = model.part_list()
    if len(parts) == 1:  # one material: the single-material path, unchanged
        return cell_fields(parts[0].material, F, keys, state)
    states = part_prony_states(model, state)
    J = np.linalg.det(F)
    m, Q = np.linalg.eigh(np.swapaxes(F, 1, 2) @ F)
    out, exact = {}, True
    for part, st in zip(parts, states):
        idx = np.asarray(part.elements, dtype=np.int64)
        if idx.size == 0:
            continue
        sub, ex = cell_fields(part.material, F[idx], keys, st, principal=(m[idx], Q[idx], J[idx]))
        exact = exact and ex
        for k, a in sub.items():
            if k not in out:
                out[k] = np.empty((len(F),) + a.shape[1:])
            out[k][idx] = a
    if "part" in keys:
        out["part"] = model.element_part().astype(np.float64)
    if "material_id" in keys:
        _, of_part = distinct_materials(parts)
        out["material_id"] = np.asarray(of_part, dtype=np.float64)[model.element_part()]
    return out, exact


def _material_key(material) -> tuple:
    return (material.name, material.moduli, bool(material.elastic), tuple(sorted(material.values.items())))


def distinct_materials(parts) -> tuple[list, list[int]]:
    """The distinct materials of parts (same name, parameter values, moduli and elastic flag:
    one), in order of first use, and each part's index among them.

    Parameters
    ----------
    parts : sequence of Part

    Returns
    -------
    materials : list of Material
    of_part : list of int
        ``materials[of_part[i]]`` is part i's material (the ``material_id`` field).
    """
    keys, materials, of_part = [], [], []
    for p in parts:
        key = _material_key(p.material)
        if key not in keys:
            keys.append(key)
            materials.append(p.material)
        of_part.append(keys.index(key))
    return materials, of_part


__all__ = ["FIELDS", "DEFAULT_FIELDS", "STRESS_FIELDS", "FIBRE_TERM", "FieldInfo", "parse_fields",
           "mean_gradients", "deformation_gradients", "element_stress", "cell_fields", "model_cell_fields",
           "distinct_materials", "has_fibre_families", "part_prony_state", "part_prony_states"]
