"""Total Lagrangian hex8: internal forces and consistent tangent, vectorised over (E, Q).

Isochoric part at the 2 x 2 x 2 Gauss points (P = F S, S from :mod:`.constitutive`):

    f_a,i = sum_q w_q F_iK S_KJ dN_a,J
    K_ai,bk = sum_q w_q [ dN_a,J S_JL dN_b,L delta_ik + B_(IJ),ai CC_IJKL B_(KL),bk ]

Volumetric part, locking free ("mean-dilatation", Simo-Taylor-Pister 1985: the three-field
Hu-Washizu element with element-constant pressure and dilatation, condensed): the energy is
V_e U(theta_e) with theta_e = v_e / V_e the element's volume ratio, v_e = sum_q w_q J_q. With
the spatial gradients n_a,i = dN_a,J F^-1_Ji:

    g_ai = d v_e / d u_ai = sum_q w_q J_q n_a,i
    f_vol = U'(theta) g,   K_vol = U''(theta) / V_e g g^T + U'(theta) sum_q w_q J_q (n_ai n_bk - n_ak n_bi)

the exact Hessian of a discrete energy, so the tangent is symmetric and Newton quadratic. The
isochoric energy is invariant under a volumetric scaling of F, so this equals the F-bar element
with F_bar = (theta / J)^(1/3) F. ``volumetric="full"`` integrates U(J) at every Gauss point
instead (locks for nearly incompressible materials; kept to show the difference).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .constitutive import Constitutive, History
from .discretization import Discretization

VOIGT = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))
_VI = np.array([a for a, _ in VOIGT])
_VJ = np.array([b for _, b in VOIGT])


class Inverted(Exception):
    """J <= 0 at a Gauss point: the step is rejected (the solver cuts it or reports it)."""

    def __init__(self, element: int, value: float):
        super().__init__(f"element {element}: J = {value:g}")
        self.element = element
        self.value = value


@dataclass
class ElementState:
    """Result of one evaluation: forces (E, 24), stiffness (E, 24, 24) or None, new history."""

    force: np.ndarray
    stiffness: np.ndarray | None
    history: History | None
    theta: np.ndarray


def deformation_gradient(disc: Discretization, u: np.ndarray) -> np.ndarray:
    """F (E, Q, 3, 3) from nodal displacements u (n, 3) in m."""
    ue = u[disc.conn]  # (E, 8, 3)
    E, Q = disc.w.shape
    F = np.matmul(np.repeat(ue.transpose(0, 2, 1), Q, axis=0), disc.dN.reshape(E * Q, 8, 3))  # du_i/dX_J
    F += np.eye(3)
    return F.reshape(E, Q, 3, 3)


def _b_matrix(F: np.ndarray, dN: np.ndarray) -> np.ndarray:
    """B (E, Q, 6, 24): delta E (Voigt, engineering shear) = B delta u_e."""
    # dE_IJ/du_ai = 1/2 (F_iI dN_aJ + F_iJ dN_aI); shear rows take twice that. Built with the
    # Gauss points as the last (contiguous) axis: numpy's broadcasting over the small 3 x 8 axes
    # is several times slower the other way round.
    E, Q = F.shape[:2]
    P = E * Q
    Ft = np.ascontiguousarray(F.reshape(P, 3, 3).transpose(1, 2, 0))  # (i, I, P)
    Nt = np.ascontiguousarray(dN.reshape(P, 8, 3).transpose(2, 1, 0))  # (J, a, P)
    B = np.empty((6, 8, 3, P))
    for v, (I, J) in enumerate(VOIGT):
        np.multiply(Nt[J][:, None, :], Ft[:, I][None, :, :], out=B[v])
        B[v] += Nt[I][:, None, :] * Ft[:, J][None, :, :]
    B[:3] *= 0.5
    return np.ascontiguousarray(B.reshape(6, 24, P).transpose(2, 0, 1)).reshape(E, Q, 6, 24)


def _btdb(B: np.ndarray, DB: np.ndarray) -> np.ndarray:
    """K_e = B_e^T (D B)_e for stacks (E, n, 24) -> (E, 24, 24): one BLAS product per element,
    which is several times faster than numpy's stacked matmul for these small matrices."""
    K = np.empty((B.shape[0], B.shape[2], DB.shape[2]))
    for e in range(B.shape[0]):
        np.matmul(B[e].T, DB[e], out=K[e])
    return K


def _voigt_tangent(CC: np.ndarray) -> np.ndarray:
    """(P, 3, 3, 3, 3) -> (P, 6, 6) in the order 11, 22, 33, 12, 23, 13."""
    return CC[:, _VI[:, None], _VJ[:, None], _VI[None, :], _VJ[None, :]]


def evaluate(disc: Discretization, mat: Constitutive, u: np.ndarray, hist: History | None, dt: float,
             *, tangent: bool = True, volumetric: str = "mean-dilatation") -> ElementState:
    """Element forces (N) and stiffness (N/m) at displacement u (n, 3) for a step dt (s) from hist.

    Raises :class:`Inverted` if J <= 0 at a Gauss point; NumericalError (element named) on a
    non-finite material derivative.
    """
    E, Q = disc.w.shape
    F = deformation_gradient(disc, u)
    J = np.linalg.det(F)
    if not (J > 0).all():
        bad = ~(J > 0)
        e = int(np.argmax(bad.any(axis=1)))
        raise Inverted(e, float(J[e][bad[e]][0]))
    full = volumetric == "full"
    Fp = F.reshape(-1, 3, 3)
    emap = np.repeat(np.arange(E), Q)
    S, CC, new = mat.update(Fp, hist, dt, tangent=tangent, volumetric=full, where="element",
                            index_map=emap)
    S = S.reshape(E, Q, 3, 3)
    B = _b_matrix(F, disc.dN)
    Sv = S[:, :, _VI, _VJ]  # (E, Q, 6)
    w = disc.w
    Bt = B.reshape(E, Q * 6, 24).transpose(0, 2, 1)  # (E, 24, Q*6)
    force = np.matmul(Bt, (Sv * w[:, :, None]).reshape(E, Q * 6, 1))[:, :, 0]
    K = None
    if tangent:
        # numpy's matmul is fast on 3-D stacks of small matrices, slow on 4-D ones: flatten (E, Q)
        D = _voigt_tangent(CC) * w.reshape(-1, 1, 1)  # (P, 6, 6)
        DB = np.matmul(D, B.reshape(E * Q, 6, 24))
        K = _btdb(B.reshape(E, Q * 6, 24), DB.reshape(E, Q * 6, 24))  # (E, 24, 24)
        dNw = (disc.dN * w[:, :, None, None]).reshape(E * Q, 8, 3)
        geo = np.matmul(np.matmul(dNw, S.reshape(E * Q, 3, 3)), disc.dN.reshape(E * Q, 8, 3).transpose(0, 2, 1))
        geo = geo.reshape(E, Q, 8, 8).sum(axis=1)  # (E, 8, 8)
        K4 = K.reshape(E, 8, 3, 8, 3)
        for i in range(3):
            K4[:, :, i, :, i] += geo
    vol = disc.volume
    theta = (w * J).sum(axis=1) / vol
    if not full:
        U, dU, d2U = mat.volumetric(theta, index_map=np.arange(E))
        Finv = np.linalg.inv(Fp)
        n = np.matmul(disc.dN.reshape(E * Q, 8, 3), Finv).reshape(E, Q, 24)  # spatial gradients n_a,i
        wJ = w * J
        g = np.matmul(wJ[:, None, :], n)[:, 0, :]  # (E, 24)
        force = force + dU[:, None] * g
        if tangent:
            nn = np.matmul(n.transpose(0, 2, 1), n * wJ[:, :, None]).reshape(E, 8, 3, 8, 3)
            hv = (nn - nn.transpose(0, 1, 4, 3, 2)).reshape(E, 24, 24)
            K += (d2U / vol)[:, None, None] * g[:, :, None] * g[:, None, :] + dU[:, None, None] * hv
    return ElementState(force=force, stiffness=K, history=new, theta=theta)
