"""What a numba run stores at a ParaView frame besides the displacement (``Result.frame_state``).

After a call of the time loop the positions are x^{n+1}, the velocities v^{n+1/2}, and the
element blocks hold the Prony state of step n (history stresses H, isochoric S0_old) with the
step dt just taken (``S_DTPREV``): the next element pass computes the stress at x^{n+1} from
exactly these, and so does :func:`cfm_core.post.fields.element_stress`.

Structure (user's node and element numbering):

* one material (``Model.parts`` empty or one part): ``velocity`` (n, 3) (m/s) and, for k > 0
  Prony terms, ``prony_H`` (k, e, 6), ``prony_S0`` (e, 6) (Pa, Voigt 11, 22, 33, 12, 23, 13),
  ``prony_dt`` (s), as before parts existed;
* several parts (``Model.multi_material``): ``velocity`` (n, 3) and, when any part has Prony
  terms, ``prony_dt`` (s) and ``parts``: one dict per part in ``Model.part_list()`` order,
  ``{"name", "elements": (e_p,) user element indices (sorted), "prony_H": (k_p, e_p, 6),
  "prony_S0": (e_p, 6)}`` (the arrays absent for a part without Prony terms), rows in
  ``elements`` order: the structure the torch backend stores, read by
  :func:`cfm_core.post.part_state.part_prony_states`.
"""

from __future__ import annotations

import numpy as np

from .kernels import layout as K


def frame_state(prep, model, k: int | None = None) -> dict:
    """The frame state of the run ``prep`` of ``model`` (the user's) in the user's numbering;
    copies. See the module docstring for the structure. Called as ``frame_state(prep, ne, k)``
    (ne elements, k Prony terms of a one-material run): the same dict in the solver's numbering."""
    from .solver import per_element

    if k is not None:
        out = {"velocity": prep.st[1].copy()}
        ne = int(model)
        if k > 0:
            H = per_element(prep.st[4], 6 * k, 0, 6 * k, ne)
            out["prony_H"] = np.ascontiguousarray(H.reshape(ne, k, 6).transpose(1, 0, 2))
            out["prony_S0"] = per_element(prep.st[3], K.ED_N, K.ED_S0, 6, ne)
            out["prony_dt"] = float(prep.sc[K.S_DTPREV])
        return out
    ren = prep.ren
    ne = model.n_elements
    out = {"velocity": ren.to_user_nodes(prep.st[1])}
    ks = prep.ks
    if not model.multi_material:
        k = ks[0]
        if k > 0:
            H = per_element(prep.st[4], 6 * k, 0, 6 * k, ne)
            out["prony_H"] = ren.to_user_elements(np.ascontiguousarray(H.reshape(ne, k, 6).transpose(1, 0, 2)), axis=1)
            out["prony_S0"] = ren.to_user_elements(per_element(prep.st[3], K.ED_N, K.ED_S0, 6, ne))
            out["prony_dt"] = float(prep.sc[K.S_DTPREV])
        return out
    if max(ks) == 0:
        return out
    entries = []
    for (ea, eb), pt, part in zip(prep.ranges, prep.parts, model.part_list()):
        n_p, k = eb - ea, int(pt[K.PT_GAM].shape[0])
        user = ren.elements[ea:eb]                       # user element of each internal one
        order = np.argsort(user, kind="stable")         # -> the order of part.elements (sorted)
        entry = {"name": part.name, "elements": user[order].astype(np.int64)}
        if k > 0:
            H = per_element(pt[K.PT_EH], 6 * k, 0, 6 * k, n_p).reshape(n_p, k, 6).transpose(1, 0, 2)
            entry["prony_H"] = np.ascontiguousarray(H[:, order])
            entry["prony_S0"] = per_element(pt[K.PT_ED], K.ED_N, K.ED_S0, 6, n_p)[order]
        entries.append(entry)
    out["parts"] = entries
    out["prony_dt"] = float(prep.sc[K.S_DTPREV])
    return out
