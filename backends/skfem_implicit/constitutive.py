"""Constitutive update at integration points, shared by the solver and the material-point driver.

Everything comes from the single material definition: the generated numpy kernels give
psi_grad and psi_hess in the eigenvalues m_a of C; :mod:`cfm_core.material.kinematics` builds stress and
the consistent tangent from them (exact at repeated eigenvalues); :mod:`cfm_core.material.prony` advances
the viscoelastic history. For P points with deformation gradients F (P, 3, 3):

    S0_iso = 2 sum_a psi_iso,a M_a                           (instantaneous isochoric PK2, Pa)
    H_i   <- exp(-dt/tau_i) H_i + gain_i (S0_iso - S0_old)   (Prony recurrence, docs/conventions.md 2)
    S      = gamma_inf S0_iso + sum_i H_i  [+ S_vol]          (PK2, Pa)
    CC     = f_eff CC0_iso  [+ CC_vol],  f_eff = gamma_inf + sum_i gain_i  (= 2 dS/dC, Pa)

The volumetric part is added here only for ``volumetric=True`` (material points, and the
fully integrated "full" element option); the locking-free solver treats it per element
(mean dilatation, :mod:`.element`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cfm_core.material import kinematics as kin
from cfm_core.material import prony
from cfm_core.material.diagnose import describe_nonfinite
from cfm_core.errors import NumericalError


@dataclass
class History:
    """Viscoelastic state of P points: H (k, P, 3, 3) Prony stresses, S0 (P, 3, 3) last S0_iso (Pa)."""

    H: np.ndarray
    S0: np.ndarray

    @classmethod
    def relaxed(cls, k: int, P: int) -> "History":
        """Undeformed, relaxed state (all zeros)."""
        return cls(np.zeros((k, P, 3, 3)), np.zeros((P, 3, 3)))


class Constitutive:
    """A bound material prepared for batched evaluation (kernels, parameters, Prony arrays)."""

    def __init__(self, material):
        self.material = material
        self.kernels = material.kernels("numpy")
        self.params = material.param_array()
        self.gammas, self.taus = material.prony_arrays()
        self.k = int(self.gammas.size)

    # ------------------------------------------------------------------ raw kernels
    def _call(self, name: str, m: np.ndarray, where: str, index_map=None) -> np.ndarray:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            out = np.stack(getattr(self.kernels, name)(m[:, 0], m[:, 1], m[:, 2], self.params), axis=1)
        bad = ~np.isfinite(out).all(axis=1)
        if bad.any():
            i = int(np.argmax(bad))
            j = int(index_map[i]) if index_map is not None else i
            raise NumericalError(f"{name} is not finite at {where} {j}: {describe_nonfinite(self.material, m[i])}.",
                                 element=j, quantity=f"non-finite {name} of material '{self.material.name}'")
        return out

    def volumetric(self, theta: np.ndarray, index_map=None):
        """(U, U', U'') of the volumetric term at J = theta (E,), from the generated kernels.

        Evaluated at the isotropic state m_a = theta^(2/3): with dJ/dm_a = J / (2 m_a),
        d psi/d m_1 = U' J / (2m) and d2 psi/(d m_1 d m_2) = (U'' J^2 + U' J) / (4 m^2).
        """
        m = np.repeat((theta ** (2.0 / 3.0))[:, None], 3, axis=1)
        e = self._call("psi_energy", m, "element", index_map)
        g = self._call("psi_grad", m, "element", index_map)
        h = self._call("psi_hess", m, "element", index_map)
        mm = m[:, 0]
        dU = 2.0 * mm * g[:, 3] / theta
        d2U = (4.0 * mm * mm * h[:, 9] - dU * theta) / theta ** 2
        return e[:, 1], dU, d2U

    # ------------------------------------------------------------------ the update
    def update(self, F: np.ndarray, hist: History | None, dt: float, *, tangent: bool = True,
               volumetric: bool = False, where: str = "point", index_map=None):
        """Stress (and tangent) at P points for a step dt (s) from ``hist``; hist is not modified.

        Returns (S (P, 3, 3) PK2 in Pa, CC (P, 3, 3, 3, 3) in Pa or None, new History or None).
        ``where``/``index_map`` name the failing entity (e.g. "element" and point -> element) in
        the NumericalError raised on a non-finite energy derivative.
        """
        C = np.einsum("pki,pkj->pij", F, F)
        m, Q = np.linalg.eigh(C)
        g = self._call("psi_grad", m, where, index_map)
        S0 = kin.from_principal(2.0 * g[:, :3], Q)
        if self.k and hist is not None:
            H_new, S_iso = prony.update(hist.H, hist.S0, S0, dt, self.gammas, self.taus)
            factor = prony.effective_factor(dt, self.gammas, self.taus)
            new = History(H_new, S0)
        else:  # elastic, or no history given: the instantaneous response
            S_iso, factor, new = S0, 1.0, None
        S = S_iso + kin.from_principal(2.0 * g[:, 3:], Q) if volumetric else S_iso
        CC = None
        if tangent:
            h = self._call("psi_hess", m, where, index_map)
            g_t = factor * g[:, :3] + (g[:, 3:] if volumetric else 0.0)
            h_t = factor * h[:, :6] + (h[:, 6:] if volumetric else 0.0)
            CC = kin.tangent_from_principal(m, Q, g_t, h_t)
        return S, CC, new

    def energy_iso(self, F: np.ndarray) -> np.ndarray:
        """Instantaneous isochoric energy per reference volume (P,), Pa."""
        C = np.einsum("pki,pkj->pij", F, F)
        m = np.linalg.eigvalsh(C)
        return self._call("psi_energy", m, "point")[:, 0]


def point_history(material, t: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Cauchy stress (n, 6) in Pa (11, 22, 33, 12, 23, 13) along F (n, 3, 3) at times t (n,) in s.

    The solver's update applied to one material point with the local volumetric term; relaxed
    before t[0] (a deformation at t[0] is a jump, as in :func:`cfm_core.material.reference.stress_history`).
    """
    F = kin.as_batch(F)
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    model = Constitutive(material)
    hist = History.relaxed(model.k, 1)
    out = np.empty((t.size, 3, 3))
    for n in range(t.size):
        dt = 0.0 if n == 0 else float(t[n] - t[n - 1])
        S, _, new = model.update(F[n:n + 1], hist, dt, tangent=False, volumetric=True, where="row",
                                 index_map=np.array([n]))
        hist = new if new is not None else hist
        out[n] = S[0]
    return kin.to_voigt(kin.cauchy_from_pk2(F, out))
