"""skfem backend: the Gauss-point update equals the numpy reference (stress, tangent, Prony)."""

import numpy as np
import pytest

pytest.importorskip("skfem")

from cfm_core.material import kinematics as kin
from cfm_core.material import prony
from cfm_core.material import reference as ref
from cfm_core.material.registry import make_material
from cfm_core.simulation.registry import get_backend
from cfm_backends.skfem_implicit.constitutive import Constitutive, History


@pytest.fixture(scope="module")
def cfm():
    return make_material("cfm")


def _history():
    t = np.linspace(0.0, 0.05, 101)
    lam = 1.0 - 10.0 * t  # compression to 0.5, uniaxial-like: repeated lateral eigenvalues
    F = np.zeros((t.size, 3, 3))
    F[:, 0, 0] = lam
    F[:, 1, 1] = F[:, 2, 2] = lam ** -0.45
    F[50:, 0, 1] = 0.05  # a shear jump mid-way (rotated principal axes)
    return t, F


def test_point_equals_reference(cfm):
    t, F = _history()
    F[0] = np.diag([0.9, 1.05, 1.05])  # a jump at t[0]
    s = get_backend("skfem").point(cfm, t, F)
    r = kin.to_voigt(ref.stress_history(cfm, t, F))
    assert s.shape == (t.size, 6)
    np.testing.assert_allclose(s, r, rtol=0, atol=1e-10 * np.abs(r).max())


def test_point_elastic_and_identity(cfm):
    mat = make_material("cfm", elastic=True)
    s = get_backend("skfem").point(mat, np.zeros(1), np.eye(3)[None])
    assert np.abs(s).max() < 1e-9  # stress free at the reference state (repeated eigenvalues)


@pytest.mark.parametrize("F", [np.eye(3), np.diag([0.6, 1.3, 1.3]), np.diag([1.2, 0.9, 0.95])])
def test_tangent_equals_reference_with_prony_factor(cfm, F):
    c = Constitutive(cfm)
    dt = 2e-4
    hist = History.relaxed(c.k, 1)
    S, CC, _ = c.update(F[None], hist, dt, volumetric=True)
    factor = prony.effective_factor(dt, *cfm.prony_arrays())
    np.testing.assert_allclose(CC, ref.tangent(cfm, F[None], iso_factor=factor), rtol=1e-12, atol=1e-9)


def test_tangent_is_derivative_of_viscous_stress(cfm):
    """dS = CC : dE for the stress after a Prony step (consistent tangent), central differences."""
    c = Constitutive(cfm)
    F0 = np.array([[0.8, 0.05, 0.0], [0.02, 1.1, 0.03], [0.0, 0.01, 1.12]])
    hist = History.relaxed(c.k, 1)
    _, _, hist = c.update((0.5 * (F0 + np.eye(3)))[None], hist, 1e-3, tangent=False)
    dt = 5e-4
    S, CC, _ = c.update(F0[None], hist, dt, volumetric=True)
    h = 1e-7
    rng = np.random.default_rng(1)
    dF = rng.standard_normal((3, 3))
    Sp, _, _ = c.update((F0 + h * dF)[None], hist, dt, tangent=False, volumetric=True)
    Sm, _, _ = c.update((F0 - h * dF)[None], hist, dt, tangent=False, volumetric=True)
    dE = 0.5 * (dF.T @ F0 + F0.T @ dF)
    np.testing.assert_allclose((Sp - Sm)[0] / (2 * h), np.einsum("ijkl,kl->ij", CC[0], dE),
                               rtol=1e-6, atol=1e-6 * np.abs(S).max())


def test_volumetric_derivatives_from_kernels(cfm):
    c = Constitutive(cfm)
    theta = np.array([0.7, 1.0, 1.2])
    U, dU, d2U = c.volumetric(theta)
    h = 1e-6
    Up, _, _ = c.volumetric(theta + h)
    Um, dUm, _ = c.volumetric(theta - h)
    _, dUp, _ = c.volumetric(theta + h)
    np.testing.assert_allclose(dU, (Up - Um) / (2 * h), rtol=1e-6, atol=1e-3)
    np.testing.assert_allclose(d2U, (dUp - dUm) / (2 * h), rtol=1e-6)
    kappa = cfm.values["kappa"]
    assert U[1] == pytest.approx(0.0, abs=1e-9) and d2U[1] == pytest.approx(kappa, rel=1e-12)
