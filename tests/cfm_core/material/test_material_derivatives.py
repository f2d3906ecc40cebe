"""Stress and tangent from the single material definition against finite differences."""

import numpy as np
import pytest

from cfm_core import make_material
from cfm_core.material import reference as ref

MATERIALS = [("cfm", {}), ("cfm", {"k2": 20.0}), ("neo-hookean", {}), ("ogden", {}), ("mooney-rivlin", {})]


def rotation(rng):
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q @ np.diag(np.sign(np.diag(r)))
    return q if np.linalg.det(q) > 0 else -q


def random_F(rng, n, spread=0.25):
    out = []
    while len(out) < n:
        F = np.eye(3) + spread * rng.standard_normal((3, 3))
        if np.linalg.det(F) > 0.3:
            out.append(F)
    return np.array(out)


def nearly_repeated_F(rng, gap):
    """F = R diag(a, a + gap, b) R' : two principal stretches a relative gap apart."""
    a, b = 1.0 + 0.2 * rng.random(), 0.8 + 0.1 * rng.random()
    R1, R2 = rotation(rng), rotation(rng)
    return R1 @ np.diag([a, a * (1 + gap), b]) @ R2


def energy_of_C(material, C):
    L = np.linalg.cholesky(C)  # C = L L^T, so F = L^T has F^T F = C
    return ref.energy(material, L.T)[0]


def fd_stress(material, F, h=1e-6):
    C = F.T @ F
    S = np.zeros((3, 3))
    for i in range(3):
        for j in range(i, 3):
            dC = np.zeros((3, 3))
            dC[i, j] += h / 2
            dC[j, i] += h / 2
            S[i, j] = S[j, i] = 2 * (energy_of_C(material, C + dC) - energy_of_C(material, C - dC)) / (2 * h)
    return S


def fiber_switch_distance(F):
    m = np.linalg.eigvalsh(F.T @ F) * np.linalg.det(F) ** (-2 / 3)
    x = [(m[a] + m[b]) / 2 for a, b in ((0, 1), (1, 2), (0, 2))]
    return min(abs(v - 1) for v in x)


@pytest.mark.parametrize("name,params", MATERIALS)
def test_stress_is_energy_derivative(name, params):
    mat = make_material(name, params)
    rng = np.random.default_rng(1)
    Fs = list(random_F(rng, 6)) + [nearly_repeated_F(rng, g) for g in (1e-3, 1e-6, 0.0)]
    for F in Fs:
        S = ref.pk2(mat, F)[0]
        S_fd = fd_stress(mat, F)
        scale = max(np.abs(S).max(), 1e-3 * mat.values.get("kappa", 1.0))
        assert np.abs(S - S_fd).max() / scale < 2e-6


@pytest.mark.parametrize("name,params", MATERIALS)
def test_tangent_is_stress_derivative(name, params):
    mat = make_material(name, params)
    rng = np.random.default_rng(2)
    Fs = [F for F in random_F(rng, 8) if fiber_switch_distance(F) > 1e-3][:5]
    Fs += [nearly_repeated_F(rng, g) for g in (1e-2, 1e-5, 1e-9, 0.0)]
    Fs += [np.eye(3), np.diag([0.7, 1.2, 1.2])]
    h = 1e-6
    # the tension-only fibre switch is only C^1: its tangent jumps at x_ab = 1 (e.g. at F = I)
    Fs = [F for F in Fs if fiber_switch_distance(F) > 1e-3 or name != "cfm"]
    for F in Fs:
        CC = ref.tangent(mat, F)[0]
        C = F.T @ F
        for k in range(3):
            for l in range(k, 3):
                dC = np.zeros((3, 3))
                dC[k, l] += h / 2
                dC[l, k] += h / 2
                Fp = np.linalg.cholesky(C + dC).T
                Fm = np.linalg.cholesky(C - dC).T
                dS = (ref.pk2(mat, Fp)[0] - ref.pk2(mat, Fm)[0]) / (2 * h)
                # dS = CC : dC / 2 with dC_kl = dC_lk = h/2 (k != l) or dC_kk = h: both give CC_ijkl h / 2
                expected = 2 * dS
                got = CC[:, :, k, l]
                scale = np.abs(CC).max()
                assert np.abs(got - expected).max() / scale < 1e-6, (F, k, l)


@pytest.mark.parametrize("name,params", MATERIALS)
def test_reference_state_is_stress_free(name, params):
    mat = make_material(name, params)
    assert np.abs(ref.pk2(mat, np.eye(3))).max() < 1e-9 * mat.values.get("kappa", 1.0)
    assert abs(ref.energy(mat, np.eye(3))[0]) < 1e-9


def test_small_strain_moduli_of_cfm_match_hand_calculation():
    """At the reference state: bulk modulus = kappa (U''(1) = kappa) and shear modulus = c + k1/2.

    The fibre switch sits exactly at the reference (x_ab = 1); the tangent there is the one of the
    active side (x >= 1): each pair adds k1 (x - 1)^2 / 2 with x - 1 = eps_a + eps_b, i.e. k1/2 in shear.
    """
    mat = make_material("cfm", elastic=True)
    CC = ref.tangent(mat, np.eye(3))[0]
    assert CC[0, 1, 0, 1] == pytest.approx(10.0 + 1320.0 / 2, rel=1e-10)
    bulk = (CC[0, 0, 0, 0] + 2 * CC[0, 0, 1, 1]) / 3
    assert bulk == pytest.approx(666.1e3, rel=1e-10)
    lipid_only = ref.tangent(make_material("cfm", {"k1": 1e-12}, elastic=True), np.eye(3))[0]
    assert lipid_only[0, 1, 0, 1] == pytest.approx(10.0, rel=1e-9)


@pytest.mark.parametrize("name,params", MATERIALS)
def test_objectivity_and_isotropy(name, params):
    mat = make_material(name, params)
    rng = np.random.default_rng(3)
    for F in random_F(rng, 4):
        Q = rotation(rng)
        sigma = ref.cauchy(mat, F)[0]
        # objectivity: sigma(QF) = Q sigma(F) Q^T
        assert np.allclose(ref.cauchy(mat, Q @ F)[0], Q @ sigma @ Q.T, rtol=1e-10, atol=1e-10 * np.abs(sigma).max())
        # isotropy: S(F Q) = Q^T S(F) Q
        S = ref.pk2(mat, F)[0]
        assert np.allclose(ref.pk2(mat, F @ Q)[0], Q.T @ S @ Q, rtol=1e-10, atol=1e-10 * np.abs(S).max())
        assert ref.energy(mat, F @ Q)[0] == pytest.approx(ref.energy(mat, F)[0], rel=1e-12)


def test_fiber_switch_is_C1():
    """Stress is continuous across x = 1 (value and slope of the fibre energy vanish there)."""
    mat = make_material("cfm", {"c": 1e-3}, elastic=True)
    # isochoric equibiaxial-type state with x_12 = lam^2 = 1 +- eps: F = diag(l, l, l^-2)
    for eps in (1e-6, 1e-9):
        lo = np.diag([np.sqrt(1 - eps), np.sqrt(1 - eps), 1 / (1 - eps)])
        hi = np.diag([np.sqrt(1 + eps), np.sqrt(1 + eps), 1 / (1 + eps)])
        dS = np.abs(ref.pk2(mat, hi) - ref.pk2(mat, lo)).max()
        assert dS < 100 * eps * 1e3  # Lipschitz with modulus ~ c + k1, no jump
