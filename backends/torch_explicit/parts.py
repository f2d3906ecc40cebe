"""Parts (regions with their own material, parameters and density) in the torch element pass.

The run's model is renumbered so that each part's elements form one contiguous internal range
(``renumber.plan(..., groups=model.element_part())``). The element pass is then the
one-material pass with three per-part pieces:

- the material derivatives D (12, N): each part's generated code on its slice of the
  eigenvalues, with its parameters, concatenated along the element axis (:func:`composite`);
- the Prony update per element: every part's series padded to the largest term count k with
  gamma = 0 (a padded term stays 0: decay * 0 + 0 * dS0 = 0 exactly), so that the history is one
  (k, 6, N) tensor; decay and gain per element (2, k, N) and gamma_inf per element (N,), the
  batch's per-element form of ``element.prony_update``;
- the density per element (N,) in the stable step L / sqrt(M / rho) and the hourglass force
  (its factor -Q rho V0^(2/3) / 4 and the wave speed sqrt(M / rho)); the lumped masses use it too
  (``cfm_backends.explicit.geometry``).

A one-material model never comes here: its pass is unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import material as mat


@dataclass
class Layout:
    """The parts of a renumbered model (contiguous internal element ranges).

    Attributes
    ----------
    ranges : list of (int, int)
        Internal element range [start, stop) of each part, in ``model.part_list()`` order.
    ghd : list of callables
        Each part's ``psi_grad_hess_diag`` (:func:`material.grad_hess_diag`).
    params : list of list of float
        Each part's material parameters.
    gam, tau : (P, k) ndarray
        Prony gammas (-) and times (s), padded with gamma 0, tau 1 s to the largest k.
    ginf : (P,) ndarray
        gamma_inf = 1 - sum gamma of each part (-).
    k : list of int
        Each part's own number of Prony terms.
    part : (N,) ndarray of int64
        Part index of each internal element.
    density : (N,) ndarray
        Mass density of each internal element (kg/m^3).
    """

    ranges: list
    ghd: list
    params: list
    gam: np.ndarray
    tau: np.ndarray
    ginf: np.ndarray
    k: list
    part: np.ndarray
    density: np.ndarray

    @property
    def kmax(self) -> int:
        """Prony terms of the padded history."""
        return int(self.gam.shape[1])


def layout(model) -> Layout:
    """The :class:`Layout` of ``model`` (renumbered: each part one contiguous range).

    Raises
    ------
    ValueError
        A part that is not one contiguous range (an internal error: the model was not renumbered
        with ``groups``).
    """
    parts = model.part_list()
    ranges, series = [], []
    for p in parts:
        el = np.asarray(p.elements, dtype=np.int64)
        if el.size and not np.array_equal(el, np.arange(el[0], el[0] + el.size)):
            raise ValueError(f"part '{p.name}' is not a contiguous element range; renumber with groups")
        ranges.append((int(el[0]) if el.size else 0, int(el[0]) + el.size if el.size else 0))
        series.append(mat.prony(p.material))
    k = [len(g) for g, _, _ in series]
    kmax = max(k)
    gam = np.zeros((len(parts), kmax))
    tau = np.ones((len(parts), kmax))
    for i, (g, t, _) in enumerate(series):
        gam[i, :len(g)], tau[i, :len(t)] = g, t
    return Layout(ranges, [mat.grad_hess_diag(p.material) for p in parts],
                  [mat.parameters(p.material) for p in parts], gam, tau,
                  np.array([gi for _, _, gi in series]), k, model.element_part(), model.element_density())


def composite(ghds, ranges):
    """f(m1, m2, m3, params) -> 12 tensors: each part's derivatives on its range of the last axis.

    ``params[i]`` are part i's parameters (floats, or (B, 1) tensors in a batch whose m are
    (B, N)); the results are concatenated along the last axis in part order.
    """
    import torch

    def f(m1, m2, m3, params):
        outs = [g(m1[..., a:b], m2[..., a:b], m3[..., a:b], p) for g, (a, b), p in zip(ghds, ranges, params)]
        return tuple(torch.cat([torch.broadcast_to(o[j], m1[..., a:b].shape) for o, (a, b) in zip(outs, ranges)],
                               dim=-1) for j in range(12))

    return f


def factors(dtp: float, lay: Layout, part_index, dtype, device):
    """Prony (decay, gain) per element (2, k, N) for the previous step dtp (s); host arithmetic per
    part with the one-material formulas (:func:`material.prony_factors`), then one gather."""
    import torch

    rows = [mat.prony_factors(dtp, g, t) for g, t in zip(lay.gam.tolist(), lay.tau.tolist())]
    f = torch.tensor([[r[0] for r in rows], [r[1] for r in rows]], dtype=dtype)   # (2, P, k)
    f = f.permute(0, 2, 1).contiguous().to(device, non_blocking=True)             # (2, k, P)
    return f.index_select(2, part_index)


def frame_state_parts(user, ren, v, state, dt: float) -> dict:
    """A frame's state of a model with parts, in the user's numbering (``Result.frame_state`` entry).

    Returns
    -------
    dict
        ``velocity`` (n, 3) (m/s); ``prony_dt`` (s), the step that led to the frame; ``parts``: one
        dict per part of ``user.part_list()`` with ``name``, ``elements`` (the part's user element
        indices, ``Part.elements``) and, when the part has Prony terms, ``prony_H`` (k_p, e_p, 6)
        and ``prony_S0`` (e_p, 6) (Pa, Voigt 11, 22, 33, 12, 23, 13), rows in ``elements`` order:
        ``cfm_core.post.fields.element_stress(part.material, F[elements], state=part_dict |
        {'prony_dt': dt})`` gives the solver's stress of the part.
    """
    import torch

    def host(a):
        return a.to("cpu", torch.float64).numpy()

    out = {"velocity": ren.to_user_nodes(host(v.T)), "prony_dt": float(dt), "parts": []}
    H = ren.to_user_elements(host(state.H).transpose(0, 2, 1), axis=1) if state.H.shape[0] else None
    S0 = ren.to_user_elements(host(state.S0).T)
    for p in user.part_list():
        el = np.asarray(p.elements, dtype=np.int64)
        entry = {"name": p.name, "elements": el.copy()}
        kp = int(np.asarray(p.material.prony_arrays()[0]).size)
        if kp:
            entry["prony_H"] = np.ascontiguousarray(H[:kp][:, el])
            entry["prony_S0"] = np.ascontiguousarray(S0[el])
        out["parts"].append(entry)
    return out
