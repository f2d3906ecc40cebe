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

Symmetric tensors of the state and the stress (S, S0, H_k, E) are 6-vectors in numba's order 11,
22, 33, 12, 23, 13 (``VOIGT``), so each op on them is a third smaller than on (3, 3, N); the
element forces are one (6, 8, N) tensor, internal then hourglass, summed to the nodes by one
``index_add_``. The pass dispatches about 730 ops (views included; was 930): the material's
generated code ~290, the eigen-decomposition ~235, the rest ~200. Each is a pass over a few rows
of N, so on the CPU the cost is per-op overhead (~1.5 us) plus memory traffic; ops on stacked rows
do the work of several (F, C, A V, the 6 stress components, the Prony terms), per-node views come
from one ``unbind`` each and the failure checks are one sum.

F is formed from the displacement u = x - X (not the position): the same F to round-off in
float64, and in float32 it keeps the strain's digits. The stages (``gather``, ``front`` =
``deformation`` + ``eigen.eig3`` + ``derivatives``, ``response``, ``scatter``) are pure functions (no host
synchronisation, no in-place change of their inputs), so that a step can be recomputed (eigen
fallback) and stages can be handed to ``torch.compile`` (:class:`Stages`).
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from .eigen import constant, eig3

VOIGT = (0, 4, 8, 1, 5, 2)              # 11, 22, 33, 12, 23, 13 of a (3, 3) viewed as (9,)
FULL = (0, 3, 5, 3, 1, 4, 5, 4, 2)      # the (3, 3) entries of a Voigt 6-vector
# products Q[I_k, a] Q[J_k, a] of the eigenvector matrix (viewed as (9,)) for the 6 Voigt pairs k and a
QI = tuple(3 * i + a for i in (0, 1, 2, 0, 1, 0) for a in range(3))
QJ = tuple(3 * j + a for j in (0, 1, 2, 1, 2, 2) for a in range(3))
WORK_WEIGHTS = (1.0, 1.0, 1.0, 2.0, 2.0, 2.0)   # S : E of symmetric tensors from their 6-vectors


class Kinematics(NamedTuple):
    F: torch.Tensor        # (3, 3, N) deformation gradient
    q: torch.Tensor        # (4, 3, N) hourglass mode velocities (m/s)
    J: torch.Tensor        # (N,) det F
    C: torch.Tensor        # (3, 3, N) right Cauchy-Green tensor
    m: torch.Tensor        # (3, N) eigenvalues of C
    Q: torch.Tensor        # (3, 3, N) eigenvectors (columns)
    fallback: torch.Tensor  # (N,) bool: eigen-decomposition to redo with Jacobi


class ElementState(NamedTuple):
    H: torch.Tensor        # (k, 6, N) Prony history (Pa)
    S0: torch.Tensor       # (6, N) instantaneous isochoric S of the previous step (Pa)
    S: torch.Tensor        # (6, N) second Piola-Kirchhoff stress of the previous step (Pa)
    E: torch.Tensor        # (6, N) Green-Lagrange strain of the previous step


class Response(NamedTuple):
    fe: torch.Tensor       # (6, 8, N) element nodal forces (N): internal (0:3), hourglass (3:6)
    dte: torch.Tensor      # (N,) L / c (s), inf for failed elements
    failed: torch.Tensor   # (N,) bool: inverted (see :func:`inverted`) or non-finite stress
    work: torch.Tensor     # () stress work increment (J, modelled part)
    work_e: torch.Tensor   # (N,) stress work increment per element (J)
    state: ElementState    # the updated state
    summary: torch.Tensor  # (5,) float64: min dte, its element, failed element count, work, fallback count


def inverted(J: torch.Tensor) -> torch.Tensor:
    """(...) bool: det F not positive or not finite (an inverted element; numba's status 1)."""
    return ~((J > 0.0) & (J < torch.inf))


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
    # per-node views from one unbind each (a Python-level view op costs about as much as a small op)
    ua, va = g[0:3, :, None].unbind(1), g[None, 3:6].unbind(2)       # (3, 1, N), (1, 3, N)
    Ba, Ga = B[None].unbind(1), G[:, :, None].unbind(0)              # (1, 3, N), (4, 1, N)
    F = ua[0] * Ba[0]
    q = Ga[0] * va[0]
    for a in range(1, 8):
        F.addcmul_(ua[a], Ba[a])
        q.addcmul_(Ga[a], va[a])
    F.view(9, -1)[0::4] += 1.0
    J, C = det_and_cauchy_green(F)
    return F, q, J, C


def det_and_cauchy_green(F: torch.Tensor):
    """(J = det F (N,), C = F^T F (3, 3, N)) of deformation gradients F (3, 3, N).

    J: numba's cofactor expansion along the first row.
    """
    f00, f01, f02 = F[0, 0], F[0, 1], F[0, 2]
    f10, f11, f12 = F[1, 0], F[1, 1], F[1, 2]
    f20, f21, f22 = F[2, 0], F[2, 1], F[2, 2]
    J = f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20) + f02 * (f10 * f21 - f11 * f20)
    C = F[0, :, None] * F[0, None, :]
    C.addcmul_(F[1, :, None], F[1, None, :]).addcmul_(F[2, :, None], F[2, None, :])
    return J, C


def matmul3(A: torch.Tensor, B: torch.Tensor) -> torch.Tensor:
    """A B per element for A, B (3, 3, N) (e.g. P = F S)."""
    a0, a1, a2 = A[:, :, None].unbind(1)
    b0, b1, b2 = B[None].unbind(1)
    return (a0 * b0).addcmul_(a1, b1).addcmul_(a2, b2)


def full(S: torch.Tensor) -> torch.Tensor:
    """(3, 3, N) symmetric tensors from their Voigt 6-vectors S (6, N)."""
    return S.index_select(0, constant(FULL, torch.int64, S.device)).view(3, 3, -1)


def voigt(A: torch.Tensor) -> torch.Tensor:
    """(6, N) Voigt 6-vectors (11, 22, 33, 12, 23, 13) of symmetric tensors A (3, 3, N)."""
    return A.reshape(9, -1).index_select(0, constant(VOIGT, torch.int64, A.device))


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
    """(S0_iso, S_vol) (6, N) in Pa: Q diag(2 psi_a) Q^T of the isochoric and volumetric parts.

    D (12, N): the derivatives (:func:`derivatives`); Q (3, 3, N): eigenvectors of C. Both parts
    from one table of eigenvector products q_ia q_ja (the 6 pairs, 3 directions a).
    """
    coef = 2.0 * D[0:6].view(2, 3, 1, -1)                    # 2 psi_a of the isochoric, volumetric parts
    Q9 = Q.reshape(9, -1)
    dev = Q.device
    QQ = (Q9.index_select(0, constant(QI, torch.int64, dev)) * Q9.index_select(0, constant(QJ, torch.int64, dev)))
    QQ = QQ.view(6, 3, -1).transpose(0, 1)                   # (a, pair, N)
    S2 = coef[:, 0] * QQ[None, 0]
    S2.addcmul_(coef[:, 1], QQ[None, 1]).addcmul_(coef[:, 2], QQ[None, 2])
    return S2[0], S2[1]


def prony_update(S0, S_vol, H, S0_old, factors, ginf: float):
    """(S, H_new): S = S_vol + gamma_inf S0 + sum_k H_k with H_k <- decay_k H_k + gain_k (S0 - S0_old).

    H (k, 6, N), S0_old (6, N): the Prony state; factors (2, k): decay_k, gain_k of the step,
    or (2, k, N) per element with ginf (N,) (a batch of runs, each with its own step and series);
    no Prony terms (k = 0): S = S_vol + S0 (elastic).
    """
    k = H.shape[0]
    if k == 0:
        return S_vol + S0, H
    d = S0 - S0_old
    if factors.dim() == 2:
        S = S_vol.add(S0, alpha=ginf)
        f = factors[:, :, None, None]
    else:
        S = S_vol + S0 * ginf
        f = factors[:, :, None, :]
    Hn = torch.addcmul(H * f[0], f[1], d)
    for j in range(k):
        S.add_(Hn[j])
    return S, Hn


def stress(kin: Kinematics, D: torch.Tensor, state: ElementState, factors, ginf: float, L, V0, hgc,
           rho: float, hgwave: int):
    """Stresses, stable steps, failures, stress work and the new state of all elements.

    D (12, N): the material derivatives at kin.m (:func:`derivatives`); factors (2, k): Prony decay
    and gain of the step since the previous pass; hgc = -Q_hg rho V0^(2/3) / 4 (N,); hgwave 0:
    hourglass wave speed from the isochoric modulus, 1: from the full one.
    Returns (P = F S (3, 3, N), c_hg q (4, 3, N), dte, failed, work, work per element (N,), new
    state, summary).
    """
    F, q, J, C, m, Q = kin.F, kin.q, kin.J, kin.C, kin.m, kin.Q
    S0, S_vol = principal_stresses(D, Q)
    S, Hn = prony_update(S0, S_vol, state.H, state.S0, factors, ginf)
    # longitudinal moduli along the principal directions (Pa): isochoric and total (numba's order)
    m4 = 4.0 * m
    mi = (2.0 * D[0:3]).addcmul_(m4, D[6:9])
    mt = (mi + 2.0 * D[3:6]).addcmul_(m4, D[9:12])
    mt_max = mt.amax(0)
    # failed: inverted, or a non-finite derivative or stress (one sum carries any inf / nan)
    failed = inverted(J) | ~torch.isfinite(D.sum(0) + S.sum(0) + mt_max)
    dte = torch.where((mt_max > 0.0) & ~failed, L / torch.sqrt(mt_max / rho), torch.inf)
    # first Piola-Kirchhoff stress and the hourglass mode forces per unit hourglass vector
    P = matmul3(F, full(S))
    mod = mi.amax(0) if hgwave == 0 else mt_max
    qc = q * torch.where(mod > 0.0, hgc * torch.sqrt(mod / rho), 0.0)
    # stress work (trapezoid in time) and the new state
    E = voigt(C)
    E[0:3] -= 1.0
    E *= 0.5
    w = ((state.S + S) * (E - state.E) * constant(WORK_WEIGHTS, S.dtype, S.device)[:, None]).sum(0)
    work_e = 0.5 * (V0 * w)
    work = work_e.sum()
    dmin, emin = torch.min(dte, 0)
    f64 = torch.float64
    summary = torch.stack([dmin.to(f64), emin.to(f64), failed.sum().to(f64), work.to(f64),
                           kin.fallback.sum().to(f64)])
    return P, qc, dte, failed, work, work_e, ElementState(Hn, S0, S, E), summary


def forces(P: torch.Tensor, qc: torch.Tensor, BV: torch.Tensor, G: torch.Tensor) -> torch.Tensor:
    """Element nodal forces (6, 8, N): internal V0 P B_a (0:3) and hourglass sum_alpha c_hg q_alpha G_a,alpha (3:6)."""
    fe = torch.empty((6,) + BV.shape[0:1] + BV.shape[2:], dtype=P.dtype, device=P.device)
    fint, fhg = fe[0:3], fe[3:6]
    p0, p1, p2 = P[:, :, None].unbind(1)
    b0, b1, b2 = BV[None].unbind(2)
    torch.mul(p0, b0, out=fint).addcmul_(p1, b1).addcmul_(p2, b2)
    qs, gs = qc[:, :, None].unbind(0), G[None].unbind(2)
    torch.mul(qs[0], gs[0], out=fhg)
    for s in range(1, 4):
        fhg.addcmul_(qs[s], gs[s])
    return fe


def response(kin: Kinematics, D: torch.Tensor, state: ElementState, factors, ginf: float, BV, G, L, V0, hgc,
             rho: float, hgwave: int, stages=None) -> Response:
    """Stresses, element forces, stable steps, failures and stress work of all elements.

    BV = V0 B (8, 3, N), G (8, 4, N); the other arguments as for :func:`stress`; ``stages`` (a
    :class:`Stages`) when its stress and forces functions are to be used (compiled ones).
    """
    st_fn, f_fn = (stress, forces) if stages is None else (stages.stress, stages.forces)
    P, qc, dte, failed, work, work_e, new, summary = st_fn(kin, D, state, factors, ginf, L, V0, hgc, rho, hgwave)
    return Response(f_fn(P, qc, BV, G), dte, failed, work, work_e, new, summary)


def scatter(fe: torch.Tensor, idx: torch.Tensor, n: int) -> torch.Tensor:
    """Nodal sums (6, n): internal (0:3) and hourglass (3:6) forces from the element forces fe
    (6, 8, N), by one ``index_add_`` over idx = conn^T flattened."""
    out = torch.zeros((6, n), dtype=fe.dtype, device=fe.device)
    return out.index_add_(1, idx, fe.view(6, -1))
