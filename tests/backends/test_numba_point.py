"""Material point driver of the numba backend (the solver's own constitutive update)."""

import math

import numpy as np
import pytest

pytest.importorskip("numba")
from cfm_backends.numba_explicit import NumbaExplicitBackend
from fixtures.hand_derived import NEO_HOOKEAN_SOURCE, NeoHookeanStandIn
from cfm_core.errors import NumericalError

MU, KAPPA = 2.0e3, 60.0e3
VOIGT = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))


def nh_parts(F):
    """Independent numpy Neo-Hookean: (S_iso, S_vol) in Pa from the invariant form."""
    C = F.T @ F
    J = np.linalg.det(F)
    Ci = np.linalg.inv(C)
    S_iso = MU * J ** (-2.0 / 3.0) * (np.eye(3) - np.trace(C) / 3.0 * Ci)
    S_vol = KAPPA * (J - 1.0) * J * Ci
    return S_iso, S_vol


def to_cauchy(F, S):
    sig = F @ S @ F.T / np.linalg.det(F)
    return np.array([sig[i, j] for i, j in VOIGT])


def history():
    t = np.linspace(0.0, 0.02, 81)
    F = np.empty((t.size, 3, 3))
    for n, s in enumerate(t / t[-1]):
        F[n] = np.array([[1 + 0.3 * s, 0.2 * s, 0.0], [0.05 * s, 1 - 0.15 * s, 0.1 * s], [0.0, 0.0, 1 - 0.1 * s]])
    return t, F


def test_elastic_against_numpy():
    t, F = history()
    sig = NumbaExplicitBackend().point(NeoHookeanStandIn(MU, KAPPA), t, F)
    ref = np.array([to_cauchy(f, sum(nh_parts(f))) for f in F])
    np.testing.assert_allclose(sig, ref, rtol=1e-11, atol=1e-11 * np.abs(ref).max())


def test_reference_state_and_uniaxial_repeated_eigenvalues():
    F = np.array([np.eye(3), np.diag([1.2, 1 / math.sqrt(1.2), 1 / math.sqrt(1.2)]), np.diag([0.8, 0.8, 1.0])])
    sig = NumbaExplicitBackend().point(NeoHookeanStandIn(MU, KAPPA), np.zeros(3), F)
    assert np.all(sig[0] == 0.0)
    ref = np.array([to_cauchy(f, sum(nh_parts(f))) for f in F])
    np.testing.assert_allclose(sig, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_prony_against_numpy_recurrence():
    gam, tau = np.array([0.5, 0.3]), np.array([2e-3, 3e-2])
    t, F = history()
    sig = NumbaExplicitBackend().point(NeoHookeanStandIn(MU, KAPPA, gam, tau), t, F)
    H = np.zeros((2, 3, 3))
    S0_old = np.zeros((3, 3))
    ref = []
    for n in range(t.size):
        dt = 0.0 if n == 0 else t[n] - t[n - 1]
        S0, Sv = nh_parts(F[n])
        for k in range(2):
            decay = math.exp(-dt / tau[k])
            gain = gam[k] * (tau[k] / dt * (1 - decay) if dt > 0 else 1.0)
            H[k] = decay * H[k] + gain * (S0 - S0_old)
        S0_old = S0
        ref.append(to_cauchy(F[n], Sv + (1 - gam.sum()) * S0 + H.sum(axis=0)))
    ref = np.array(ref)
    np.testing.assert_allclose(sig, ref, rtol=1e-10, atol=1e-10 * np.abs(ref).max())


def test_step_relaxation_follows_g():
    """Small shear step at t = 0+, held: sigma_12(t) / sigma_12(0+) = g(t)."""
    gam, tau = np.array([0.45, 0.435, 0.094]), np.array([1e-3, 0.1, 10.0])
    t = np.concatenate([[0.0, 1e-12], np.geomspace(1e-5, 30.0, 200)])
    F = np.repeat(np.eye(3)[None], t.size, axis=0)
    F[1:, 0, 1] = 1e-6
    sig = NumbaExplicitBackend().point(NeoHookeanStandIn(MU, KAPPA, gam, tau), t, F)
    g = 1 - gam.sum() + (gam[None, :] * np.exp(-t[1:, None] / tau[None, :])).sum(axis=1)
    np.testing.assert_allclose(sig[1:, 3] / sig[1, 3], g, rtol=1e-5)


def test_inverted_point_raises():
    F = np.array([np.eye(3), np.diag([1.0, 1.0, -0.5])])
    with pytest.raises(NumericalError, match="point 1") as info:
        NumbaExplicitBackend().point(NeoHookeanStandIn(MU, KAPPA), np.array([0.0, 1e-3]), F)
    assert info.value.quantity == "J"


class Overflowing(NeoHookeanStandIn):
    """Neo-Hookean whose gradient carries exp(p2 (I1 - 3)^2): overflows for large stretch."""

    def param_array(self):
        return np.array([self.mu, self.kappa, 1000.0])

    def numba_source(self):
        return NEO_HOOKEAN_SOURCE.replace(
            "    return (a * (1.0 - i1 / (3.0 * m1)),",
            "    a = a * math.exp(p[2] * (i1 - 3.0) ** 2)\n    return (a * (1.0 - i1 / (3.0 * m1)),")


def test_exp_overflow_is_reported():
    F = np.array([np.eye(3), np.diag([3.0, 1.0, 1.0])])
    with pytest.raises(NumericalError, match="overflow") as info:
        NumbaExplicitBackend().point(Overflowing(MU, KAPPA, name="overflowing"), np.array([0.0, 1e-3]), F)
    assert info.value.element == 1 and info.value.time == pytest.approx(1e-3)


def test_cfm_against_core_reference():
    from cfm_core.material import reference
    from cfm_core.material.registry import make_material

    mat = make_material("cfm", {}, "long-term", False)
    t = np.linspace(0.0, 5e-3, 41)
    F = np.empty((t.size, 3, 3))
    for n, s in enumerate(t / t[-1]):   # compression with shear: fibres switch on and off
        F[n] = np.array([[1 + 0.25 * s, 0.1 * s, 0.0], [0.0, 1 + 0.2 * s, 0.0], [0.05 * s, 0.0, 1 - 0.4 * s]])
    sig = NumbaExplicitBackend().point(mat, t, F)
    ref = reference.stress_history(mat, t, F)
    ref = np.array([[r[i, j] for i, j in VOIGT] for r in ref])
    np.testing.assert_allclose(sig, ref, rtol=1e-9, atol=1e-10 * np.abs(ref).max())


def test_combined_derivatives_match_the_material_functions():
    """The kernels call psi_grad_hess_diag (generated with shared subexpressions): it must equal
    the material's own psi_grad and psi_hess_diag."""
    from cfm_backends.numba_explicit import codegen
    from cfm_core.material.registry import make_material

    rng = np.random.default_rng(3)
    for mat in (make_material("cfm", {}, "long-term", False), NeoHookeanStandIn(MU, KAPPA)):
        mod = codegen.load(mat)
        p = mat.param_array()
        for m in np.exp(rng.normal(scale=0.3, size=(200, 3))):
            both = np.array(mod.psi_grad_hess_diag(*m, p))
            ref = np.concatenate([mod.psi_grad(*m, p), mod.psi_hess_diag(*m, p)])
            np.testing.assert_allclose(both, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
