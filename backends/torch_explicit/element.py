"""Element pass of the explicit solver, vectorised over elements (torch, any device).

The numba backend's ``element_pass`` (kernels/element.py, kernels/constitutive.py) with the loop
over elements replaced by batched tensor ops. Layout: component first, element last, so that every
op works on contiguous rows of length N (elements): displacements and velocities ``uv`` (6, n),
shape-function gradients B (8, 3, N), hourglass vectors G (8, 4, N), tensors (3, 3, N).

Total Lagrangian hex8, one-point integration (Flanagan & Belytschko 1981):

    F = I + sum_a u_a (x) B_a,   q_alpha = sum_a v_a G_a,alpha          (kinematics)
    C = F^T F = Q diag(m) Q^T,   S0_iso = Q diag(2 psi_iso,a) Q^T,  S_vol = Q diag(2 psi_vol,a) Q^T
    H_k <- decay_k H_k + gain_k (S0_iso - S0_old),  S = S_vol + gamma_inf S0_iso + sum_k H_k
    f_a^int = V0 F S B_a,   f_a^hg = c_hg sum_alpha q_alpha G_a,alpha,  c_hg = -Q_hg rho c V0^(2/3) / 4
    dt_e = L / sqrt(M_max / rho),   M_a = 2 psi_a + 4 m_a psi_aa        (stable step, Pa)
    stress work: V0 (S_old + S) / 2 : (E - E_old),   E = (C - I) / 2    (J)

F is formed from the displacement u = x - X (not the position): the same F to round-off in
float64, and in float32 it keeps the strain's digits. The stages (``gather``, ``front`` =
``deformation`` + ``eigen.eig3`` + ``derivatives``, ``response``, ``scatter``) are pure functions (no host
synchronisation, no in-place change of their inputs), so that a step can be recomputed (eigen
fallback) and stages can be handed to ``torch.compile`` (:class:`Stages`).
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from .eigen import eig3


class Kinematics(NamedTuple):
    F: torch.Tensor        # (3, 3, N) deformation gradient
    q: torch.Tensor        # (4, 3, N) hourglass mode velocities (m/s)
    J: torch.Tensor        # (N,) det F
    C: torch.Tensor        # (3, 3, N) right Cauchy-Green tensor
    m: torch.Tensor        # (3, N) eigenvalues of C
    Q: torch.Tensor        # (3, 3, N) eigenvectors (columns)
    fallback: torch.Tensor  # (N,) bool: eigen-decomposition to redo with Jacobi


class ElementState(NamedTuple):
    H: torch.Tensor        # (k, 3, 3, N) Prony history (Pa)
    S0: torch.Tensor       # (3, 3, N) instantaneous isochoric S of the previous step (Pa)
    S: torch.Tensor        # (3, 3, N) second Piola-Kirchhoff stress of the previous step (Pa)
    E: torch.Tensor        # (3, 3, N) Green-Lagrange strain of the previous step


class Response(NamedTuple):
    fint: torch.Tensor     # (3, 8, N) internal element nodal forces (N)
    fhg: torch.Tensor      # (3, 8, N) hourglass element nodal forces (N)
    dte: torch.Tensor      # (N,) L / c (s), inf for failed elements
    bad: torch.Tensor      # (N,) int8: 0 ok, 1 inverted (J <= 0), 2 non-finite stress
    work: torch.Tensor     # () stress work increment (J, modelled part)
    work_e: torch.Tensor   # (N,) stress work increment per element (J)
    state: ElementState    # the updated state
    summary: torch.Tensor  # (5,) float64: min dte, its element, first failed element (N if none), work, fallback count


def gather(uv: torch.Tensor, idx: torch.Tensor, ne: int) -> torch.Tensor:
    """Element nodal displacements and velocities (6, 8, N) from uv (6, n).

    idx: conn^T flattened (8 N,), or its flat form (6, 8 N) from :func:`flat_index` (one gather
    from the flattened uv: about 4 times faster on the CPU than ``index_select`` along dim 1).
    """
    if idx.dim() == 2:
        return uv.reshape(-1).index_select(0, idx.reshape(-1)).view(6, 8, ne)
    return uv.index_select(1, idx).view(6, 8, ne)


def flat_index(idx: torch.Tensor, n: int) -> torch.Tensor:
    """(6, 8 N): the positions of uv (6, n) flattened, row c at c n + idx."""
    return idx[None, :] + n * torch.arange(6, dtype=idx.dtype, device=idx.device)[:, None]


def deformation(g: torch.Tensor, B: torch.Tensor, G: torch.Tensor):
    """(F (3, 3, N), q (4, 3, N), J (N,), C (3, 3, N)) from the element nodal values g (6, 8, N)."""
    F = g[0:3, 0, None] * B[None, 0]
    q = G[0, :, None] * g[None, 3:6, 0]
    for a in range(1, 8):
        F.addcmul_(g[0:3, a, None], B[None, a])
        q.addcmul_(G[a, :, None], g[None, 3:6, a])
    F = F + torch.eye(3, dtype=F.dtype, device=F.device)[:, :, None]
    J, C = det_and_cauchy_green(F)
    return F, q, J, C


def det_and_cauchy_green(F: torch.Tensor):
    """(J = det F (N,), C = F^T F (3, 3, N)) of deformation gradients F (3, 3, N)."""
    f00, f01, f02 = F[0, 0], F[0, 1], F[0, 2]
    f10, f11, f12 = F[1, 0], F[1, 1], F[1, 2]
    f20, f21, f22 = F[2, 0], F[2, 1], F[2, 2]
    J = f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20) + f02 * (f10 * f21 - f11 * f20)
    C = F[0, :, None] * F[0, None, :]
    C.addcmul_(F[1, :, None], F[1, None, :]).addcmul_(F[2, :, None], F[2, None, :])
    return J, C


def matmul3(A: torch.Tensor, B: torch.Tensor) -> torch.Tensor:
    """A B per element for A, B (3, 3, N) (e.g. P = F S)."""
    out = A[:, 0, None] * B[None, 0]
    return out.addcmul_(A[:, 1, None], B[None, 1]).addcmul_(A[:, 2, None], B[None, 2])


def derivatives(ghd, p, m: torch.Tensor) -> torch.Tensor:
    """D (12, N): the material's psi_grad (6) and psi_hess_diag (6) values (Pa) at eigenvalues m (3, N)."""
    return torch.stack(ghd(m[0], m[1], m[2], p))


def front(g: torch.Tensor, B: torch.Tensor, G: torch.Tensor, ghd, p) -> tuple[Kinematics, torch.Tensor]:
    """Kinematics (deformation, eigen-decomposition of C) and the material derivatives D (12, N)."""
    F, q, J, C = deformation(g, B, G)
    m, Q, fallback = eig3(C)
    return Kinematics(F, q, J, C, m, Q, fallback), derivatives(ghd, p, m)


class Stages(NamedTuple):
    """The element-pass stages as the solver calls them: plain functions, or compiled ones.

    With ``torch.compile`` each of :func:`front` (deformation, eigen-decomposition, material
    derivatives), :func:`stress` and :func:`forces` is compiled on its own. The gather (indirect
    loads) ran slower compiled than eager with torch 2.13 on the CPU, and with everything in one
    graph inductor recomputed the material derivatives inside every consumer loop; separate graphs
    make it write each stage's results once.
    """

    front: object
    stress: object
    forces: object

    @classmethod
    def make(cls, compile_mode=False) -> "Stages":
        if not compile_mode:
            return cls(front, stress, forces)
        mode = None if compile_mode is True else compile_mode
        c = lambda f: torch.compile(f, mode=mode, dynamic=False)  # noqa: E731
        return cls(c(front), c(stress), c(forces))


def kinematics(g: torch.Tensor, B: torch.Tensor, G: torch.Tensor) -> Kinematics:
    """F, hourglass modes, J, C and its eigen-decomposition of all elements from g (6, 8, N)."""
    F, q, J, C = deformation(g, B, G)
    m, Q, fallback = eig3(C)
    return Kinematics(F, q, J, C, m, Q, fallback)


def principal_stresses(D: torch.Tensor, Q: torch.Tensor):
    """(S0_iso, S_vol) (3, 3, N) in Pa: Q diag(2 psi_a) Q^T of the isochoric and volumetric parts.

    D (12, N): the derivatives (:func:`derivatives`); Q (3, 3, N): eigenvectors of C.
    """
    coef = 2.0 * D[0:6].view(2, 3, -1)                       # 2 psi_a of the isochoric, volumetric parts
    W = Q[None] * coef[:, None]                              # (part, i, a, N)
    S2 = W[:, :, None, 0] * Q[None, None, :, 0]
    S2.addcmul_(W[:, :, None, 1], Q[None, None, :, 1]).addcmul_(W[:, :, None, 2], Q[None, None, :, 2])
    return S2[0], S2[1]


def prony_update(S0, S_vol, H, S0_old, factors, ginf: float):
    """(S, H_new): S = S_vol + gamma_inf S0 + sum_k H_k with H_k <- decay_k H_k + gain_k (S0 - S0_old).

    H (k, 3, 3, N), S0_old (3, 3, N): the Prony state; factors (2, k): decay_k, gain_k of the step,
    or (2, k, N) per element with ginf (N,) (a batch of runs, each with its own step and series);
    no Prony terms (k = 0): S = S_vol + S0 (elastic).
    """
    k = H.shape[0]
    if k == 0:
        return S_vol + S0, H
    d = S0 - S0_old
    if factors.dim() == 2:
        S = S_vol.add(S0, alpha=ginf)
        Hn = H * factors[0, :, None, None, None]
    else:
        S = S_vol + S0 * ginf
        Hn = H * factors[0, :, None, None, :]
    for j in range(k):
        S.add_(Hn[j].add_(d * factors[1, j]))
    return S, Hn


def stress(kin: Kinematics, D: torch.Tensor, state: ElementState, factors, ginf: float, L, V0, hgc,
           rho: float, hgwave: int):
    """Stresses, stable steps, failures, stress work and the new state of all elements.

    D (12, N): the material derivatives at kin.m (:func:`derivatives`); factors (2, k): Prony decay
    and gain of the step since the previous pass; hgc = -Q_hg rho V0^(2/3) / 4 (N,); hgwave 0:
    hourglass wave speed from the isochoric modulus, 1: from the full one.
    Returns (P = F S (3, 3, N), c_hg q (4, 3, N), dte, bad, work, work per element (N,), new state,
    summary).
    """
    F, q, J, C, m, Q = kin.F, kin.q, kin.J, kin.C, kin.m, kin.Q
    ne = F.shape[-1]
    S0, S_vol = principal_stresses(D, Q)
    S, Hn = prony_update(S0, S_vol, state.H, state.S0, factors, ginf)
    # longitudinal moduli along the principal directions (Pa): isochoric and total
    m4 = 4.0 * m
    mi = (2.0 * D[0:3]).addcmul(m4, D[6:9])
    mt = (mi + 2.0 * D[3:6]).addcmul(m4, D[9:12])
    mt_max = mt.amax(0)
    inverted = ~(J > 0.0) | ~torch.isfinite(J)
    nonfinite = ~torch.isfinite(D.sum(0)) | ~torch.isfinite(S.sum((0, 1)) + mt_max)
    failed = inverted | nonfinite
    bad = torch.where(inverted, 1, torch.where(nonfinite, 2, 0)).to(torch.int8)
    dte = torch.where(mt_max > 0.0, L / torch.sqrt(mt_max / rho), torch.inf)
    dte = torch.where(failed, torch.inf, dte)
    # first Piola-Kirchhoff stress and the hourglass mode forces per unit hourglass vector
    P = matmul3(F, S)
    mod = (mi if hgwave == 0 else mt).amax(0)
    qc = q * torch.where(mod > 0.0, hgc * torch.sqrt(mod / rho), 0.0)
    # stress work (trapezoid in time) and the new state
    E = 0.5 * (C - torch.eye(3, dtype=C.dtype, device=C.device)[:, :, None])
    w = ((state.S + S) * (E - state.E)).sum((0, 1))
    work_e = 0.5 * (V0 * w)
    work = work_e.sum()
    dmin, emin = torch.min(dte, 0)
    first_bad = torch.where(failed, torch.arange(ne, device=F.device), ne).amin()
    f64 = torch.float64
    summary = torch.stack([dmin.to(f64), emin.to(f64), first_bad.to(f64), work.to(f64),
                           kin.fallback.sum().to(f64)])
    return P, qc, dte, bad, work, work_e, ElementState(Hn, S0, S, E), summary


def forces(P: torch.Tensor, qc: torch.Tensor, BV: torch.Tensor, G: torch.Tensor):
    """Element nodal forces (3, 8, N) each: internal V0 P B_a and hourglass sum_alpha c_hg q_alpha G_a,alpha."""
    fint = P[:, 0, None] * BV[None, :, 0]
    fint.addcmul_(P[:, 1, None], BV[None, :, 1]).addcmul_(P[:, 2, None], BV[None, :, 2])
    fhg = qc[0, :, None] * G[None, :, 0]
    for s in range(1, 4):
        fhg.addcmul_(qc[s, :, None], G[None, :, s])
    return fint, fhg


def response(kin: Kinematics, D: torch.Tensor, state: ElementState, factors, ginf: float, BV, G, L, V0, hgc,
             rho: float, hgwave: int, stages=None) -> Response:
    """Stresses, element forces, stable steps, failures and stress work of all elements.

    BV = V0 B (8, 3, N), G (8, 4, N); the other arguments as for :func:`stress`; ``stages`` (a
    :class:`Stages`) when its stress and forces functions are to be used (compiled ones).
    """
    st_fn, f_fn = (stress, forces) if stages is None else (stages.stress, stages.forces)
    P, qc, dte, bad, work, work_e, new, summary = st_fn(kin, D, state, factors, ginf, L, V0, hgc, rho, hgwave)
    fint, fhg = f_fn(P, qc, BV, G)
    return Response(fint, fhg, dte, bad, work, work_e, new, summary)


def scatter(fint: torch.Tensor, fhg: torch.Tensor, idx: torch.Tensor, n: int) -> torch.Tensor:
    """Nodal sums (6, n): internal (0:3) and hourglass (3:6) forces from the element forces (3, 8, N)
    each, by ``index_add_`` over idx = conn^T flattened."""
    out = torch.zeros((6, n), dtype=fint.dtype, device=fint.device)
    out[0:3].index_add_(1, idx, fint.reshape(3, -1))
    out[3:6].index_add_(1, idx, fhg.reshape(3, -1))
    return out
