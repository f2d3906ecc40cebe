"""The Prony state of a frame (``Result.frame_state``) for a model with several parts.

Two structures are accepted by :mod:`cfm_core.post.fields`:

* **one array** (the one-part structure, unchanged): ``prony_H`` ndarray (k, e, 6) and
  ``prony_S0`` ndarray (e, 6) over all e elements of the model in the user's element order, with
  ``prony_dt`` (s). With several parts it is accepted only when every part with Prony terms has
  the same k (k = 0 parts are skipped: their material has no history).
* **one array per part** (parts with different numbers of Prony terms): ``prony_H`` a list of
  ``len(model.part_list())`` entries in part order, entry p an ndarray (k_p, e_p, 6) or None
  (no Prony terms), ``prony_S0`` a list of (e_p, 6) ndarrays or None, rows in the order of
  ``part.elements`` (increasing user element index), and one ``prony_dt`` (s) for all parts.
  :func:`part_prony_state` builds it from a backend's per-part arrays in any element order.
* **a list of parts** (what the torch backend stores): ``parts`` a list in part order of dicts
  ``{"name", "elements": (e_p,) user element indices, "prony_H": (k_p, e_p, 6), "prony_S0":
  (e_p, 6)}`` (the two arrays absent for a part without Prony terms), rows in ``elements``
  order, and one ``prony_dt`` (s); read through :func:`part_prony_state`.

Units: H and S0 in Pa (Voigt 11, 22, 33, 12, 23, 13: the history stresses and the previous
isochoric second Piola-Kirchhoff stress), dt in s.
"""

from __future__ import annotations

import numpy as np


def _prony_count(material) -> int:
    return int(np.asarray(material.prony_arrays()[0]).size)


def part_prony_state(model, H, S0, dt: float, elements=None) -> dict:
    """The per-part Prony state of a frame, as ``Result.frame_state`` holds it for several parts.

    The adaptor for the explicit backends: they keep one state block per part (elements grouped
    by part in their internal order) and hand each part's block here with the user's index of
    each row; the result is in the structure :func:`part_prony_states` reads.

    Parameters
    ----------
    model : Model
        The user's model (not a backend's renumbered copy): its :meth:`part_list` order and each
        part's ``elements`` (user indices).
    H : sequence of ndarray or None
        One entry per part: history stresses (k_p, e_p, 6) (Pa, Voigt), None or k_p = 0 for a
        part whose material has no Prony terms.
    S0 : sequence of ndarray or None
        One entry per part: previous isochoric stress (e_p, 6) (Pa, Voigt), None as for H.
    dt : float
        The step that led to the frame (s), one for all parts.
    elements : sequence of ndarray, optional
        One (e_p,) int array per part: the user element index of each row of that part's H and
        S0, e.g. ``renumbering.elements[internal_part.elements]``; default: rows already in the
        order of ``part.elements``.

    Returns
    -------
    dict
        ``{"prony_H": [ (k_p, e_p, 6) or None, ...], "prony_S0": [(e_p, 6) or None, ...],
        "prony_dt": dt}``, rows in the order of ``part.elements`` (copies, float64).

    Raises
    ------
    ValueError
        Wrong number of entries, a shape that does not match the part (k_p of its material, e_p
        of its elements), or ``elements`` that are not the part's elements.
    """
    parts = model.part_list()
    for name, seq in (("H", H), ("S0", S0)) + ((("elements", elements),) if elements is not None else ()):
        if len(seq) != len(parts):
            raise ValueError(f"part_prony_state: {name} has {len(seq)} entries; the model has {len(parts)} parts.")
    out_H, out_S0 = [], []
    for i, part in enumerate(parts):
        k, own = _prony_count(part.material), np.asarray(part.elements, dtype=np.int64)
        if k == 0 or H[i] is None:
            if k:
                raise ValueError(f"part_prony_state: part {i} ({part.name!r}, material {part.material.name!r}) has "
                                 f"{k} Prony terms but no state was given.")
            out_H.append(None)
            out_S0.append(None)
            continue
        h, s0 = np.asarray(H[i], dtype=np.float64), np.asarray(S0[i], dtype=np.float64)
        if h.shape != (k, own.size, 6) or s0.shape != (own.size, 6):
            raise ValueError(f"part_prony_state: part {i} ({part.name!r}) needs H ({k}, {own.size}, 6) and S0 "
                             f"({own.size}, 6); got {h.shape} and {s0.shape}.")
        if elements is not None:
            rows = np.asarray(elements[i], dtype=np.int64)
            order = np.argsort(rows, kind="stable")
            if not np.array_equal(rows[order], own):
                raise ValueError(f"part_prony_state: elements[{i}] are not the elements of part {part.name!r}.")
            h, s0 = h[:, order], s0[order]
        out_H.append(h.copy())
        out_S0.append(s0.copy())
    return {"prony_H": out_H, "prony_S0": out_S0, "prony_dt": float(dt)}


def part_prony_states(model, state) -> list:
    """Each part's Prony state of a frame, from either structure of the module docstring.

    Parameters
    ----------
    model : Model
        The model that ran.
    state : dict or None
        A ``Result.frame_state`` entry (None, or without ``prony_H``: no state stored).

    Returns
    -------
    list of dict or None
        One per part in :meth:`part_list` order: ``{"prony_H": (k_p, e_p, 6), "prony_S0":
        (e_p, 6), "prony_dt": dt}`` with rows in the order of ``part.elements``, or None where no
        state was stored or the part's material has no Prony terms.

    Raises
    ------
    ValueError
        A state that does not fit the parts (a count of entries, terms or elements), named.
    """
    parts = model.part_list()
    if state is not None and state.get("prony_H") is None and state.get("parts"):
        entries = state["parts"]
        if len(entries) != len(parts):
            raise ValueError(f"frame_state: {len(entries)} parts stored; the model has {len(parts)}.")
        state = part_prony_state(model, [e.get("prony_H") for e in entries], [e.get("prony_S0") for e in entries],
                                 float(state["prony_dt"]), elements=[e["elements"] for e in entries])
    if state is None or state.get("prony_H") is None:
        return [None] * len(parts)
    H, S0, dt = state["prony_H"], state["prony_S0"], float(state["prony_dt"])
    out = []
    if isinstance(H, np.ndarray):
        if H.ndim != 3 or H.shape[1:] != (model.n_elements, 6) or np.shape(S0) != (model.n_elements, 6):
            raise ValueError(f"frame_state: prony_H {H.shape} / prony_S0 {np.shape(S0)} do not fit the model's "
                             f"{model.n_elements} elements (k, e, 6) / (e, 6).")
        for i, part in enumerate(parts):
            k = _prony_count(part.material)
            if k == 0:
                out.append(None)
                continue
            if k != H.shape[0]:
                raise ValueError(f"frame_state: one prony_H array of {H.shape[0]} terms, but part {i} "
                                 f"({part.name!r}, material {part.material.name!r}) has {k}; parts with different "
                                 f"numbers of terms need one array per part (cfm_core.post.part_state).")
            idx = np.asarray(part.elements, dtype=np.int64)
            out.append({"prony_H": H[:, idx], "prony_S0": np.asarray(S0)[idx], "prony_dt": dt})
        return out
    if len(H) != len(parts) or len(S0) != len(parts):
        raise ValueError(f"frame_state: prony_H has {len(H)} and prony_S0 {len(S0)} entries; the model has "
                         f"{len(parts)} parts (one entry per part, cfm_core.post.part_state).")
    for i, part in enumerate(parts):
        k, e = _prony_count(part.material), len(part.elements)
        if H[i] is None or k == 0:
            if k and H[i] is None:
                raise ValueError(f"frame_state: part {i} ({part.name!r}) has {k} Prony terms but prony_H[{i}] is None.")
            out.append(None)
            continue
        h, s0 = np.asarray(H[i]), np.asarray(S0[i])
        if h.shape != (k, e, 6) or s0.shape != (e, 6):
            raise ValueError(f"frame_state: part {i} ({part.name!r}) needs prony_H[{i}] ({k}, {e}, 6) and "
                             f"prony_S0[{i}] ({e}, 6); got {h.shape} and {s0.shape}.")
        out.append({"prony_H": h, "prony_S0": s0, "prony_dt": dt})
    return out
