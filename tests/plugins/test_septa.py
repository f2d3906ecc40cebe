"""The septa-fibre term against an independent integration over the sphere.

Truth: the mean over all directions of the fibre law, integrated adaptively (scipy ``quad_vec``
over the azimuth, Gauss-Legendre over cos(theta) split exactly at the cone I4 = 1 where the
tension-only switch sits), in the eigenframe of C with the stress and tangent written from
dI4bar/dC directly (not through principal stretches or generated code):

    S = 2 < f'(I4) G >,   G = dI4bar/dC = J^(-2/3) N - (I4bar / 3) C^-1,   N = n (x) n
    CC = 4 < f''(I4) G (x) G > + 4 < f'(I4) dG/dC >
    dG/dC_ijkl = -(1/3) J^(-2/3) (N_ij Ci_kl + Ci_ij N_kl) + (I4bar/9) Ci_ij Ci_kl
                 + (I4bar/6) (Ci_ik Ci_jl + Ci_il Ci_jk)

The plugin's sphere rule is exact for polynomials up to its degree; the tension-only switch is
not one, so the comparison measures the rule's real error (states and tolerances below).
"""

import numpy as np
import pytest
from scipy.integrate import quad_vec

from cfm_core.material import reference as ref
from cfm_core.material import MaterialSpec
from cfm_plugins.septa import CFM_SEPTA, septa_term
from cfm_plugins.sphere_quadrature import RULES, moment_errors, squared_directions

K1S, K2S = 1000.0, 2.0
NODES, GL_W = np.polynomial.legendre.leggauss(48)


def _law(d):
    """f, f', f'' of the exponential fibre law at I4 = 1 + d, zero for d < 0 (active side at d = 0)."""
    e = np.exp(K2S * d**2)
    on = d >= 0.0
    f = np.where(on, K1S / (2 * K2S) * (e - 1.0), 0.0)
    f1 = np.where(on, K1S * d * e, 0.0)
    f2 = np.where(on, K1S * (1.0 + 2.0 * K2S * d**2) * e, 0.0)
    return f, f1, f2


def truth(F):
    """(W Pa, S (3,3) Pa, CC (3,3,3,3) Pa) of the septa term by adaptive integration over the sphere."""
    C = F.T @ F
    m, Q = np.linalg.eigh(C)
    J = np.sqrt(np.prod(m))
    mbar = m * J ** (-2 / 3)
    eps = mbar - 1.0
    eps[np.abs(eps) < 1e-13] = 0.0  # the reference state: every fibre exactly on the switch
    Ci = np.diag(1.0 / m)
    jm = J ** (-2 / 3)

    def inner(phi):
        c, s = np.cos(phi), np.sin(phi)
        A = eps[0] * c * c + eps[1] * s * s
        cuts = [-1.0, 1.0]
        if A * eps[2] < 0.0:  # the cone I4 = 1 crosses this meridian at u = +-u*
            us = np.sqrt(A / (A - eps[2]))
            cuts = [-1.0, -us, us, 1.0]
        acc = 0.0
        for a, b in zip(cuts[:-1], cuts[1:]):
            u = 0.5 * (b - a) * NODES + 0.5 * (a + b)
            w = 0.5 * (b - a) * GL_W
            r = np.sqrt(1.0 - u * u)
            n = np.stack([r * c, r * s, u], axis=1)
            N = n[:, :, None] * n[:, None, :]
            d = n**2 @ eps  # I4bar - 1
            I4 = 1.0 + d
            f, f1, f2 = _law(d)
            G = jm * N - I4[:, None, None] / 3 * Ci
            dG = (-(jm / 3) * (np.einsum("pij,kl->pijkl", N, Ci) + np.einsum("ij,pkl->pijkl", Ci, N))
                  + (I4 / 9)[:, None, None, None, None] * np.einsum("ij,kl->ijkl", Ci, Ci)[None]
                  + (I4 / 6)[:, None, None, None, None]
                  * (np.einsum("ik,jl->ijkl", Ci, Ci) + np.einsum("il,jk->ijkl", Ci, Ci))[None])
            CC = 4 * f2[:, None, None, None, None] * np.einsum("pij,pkl->pijkl", G, G) \
                + 4 * f1[:, None, None, None, None] * dG
            S = 2 * f1[:, None, None] * G
            vec = np.concatenate([f[:, None], S.reshape(-1, 9), CC.reshape(-1, 81)], axis=1)
            acc = acc + w @ vec
        return acc

    e1, e2 = eps[0], eps[1]
    points = []
    if e1 * e2 < 0.0:  # azimuths where A(phi) changes sign
        p = np.arctan(np.sqrt(-e1 / e2))
        points = sorted({p, np.pi - p, np.pi + p, 2 * np.pi - p})
    total, _ = quad_vec(inner, 0.0, 2 * np.pi, epsabs=1e-11, epsrel=1e-11, points=points or None)
    total /= 4 * np.pi
    W, S, CC = total[0], total[1:10].reshape(3, 3), total[10:].reshape(3, 3, 3, 3)
    S = Q @ S @ Q.T
    CC = np.einsum("ia,jb,kc,ld,abcd->ijkl", Q, Q, Q, Q, CC)
    return W, S, CC


def _only_septa(degree):
    spec = MaterialSpec.compose(f"septa-only-{degree}", (septa_term(degree),))
    return spec.bind({"k1s": K1S, "k2s": K2S})


def _states():
    lam = 0.7  # uniaxial compression (isochoric 0.7) with a 5 % volume loss
    uni = np.diag([lam, lam**-0.5, lam**-0.5]) * 0.95 ** (1 / 3)
    shear = np.eye(3)
    shear[0, 1] = 0.5  # simple shear, gamma = 0.5
    return {"reference": np.eye(3), "uniaxial compression": uni, "simple shear": shear}


def _scale(t):
    return max(np.abs(t).max(), 1e-300)


@pytest.mark.parametrize("degree", sorted(RULES))
def test_rules_integrate_monomials_exactly(degree):
    w, sq = squared_directions(degree)
    assert abs(w.sum() - 1.0) < 1e-14 and (w > 0).all()
    assert np.allclose(sq.sum(axis=1), 1.0, atol=1e-15)
    assert np.abs(moment_errors(w, sq, degree)).max() < 1e-14
    w, sq = squared_directions(degree, bits=40)  # as the septa term uses them: rows sum to exactly 1
    assert (sq.sum(axis=1) == 1.0).all() and np.abs(moment_errors(w, sq, degree)).max() < 1e-12
    assert np.abs(moment_errors(w, sq, degree + 2)).max() > 1e-9  # and no more than that degree


def test_energy_symmetric_in_the_stretches():
    material = _only_septa(11)
    k = material.kernels("numpy")
    p = material.param_array()
    m = np.array([1.3, 0.8, 1.05])
    base = k.psi_energy(*m, p)[0]
    for perm in ((1, 0, 2), (0, 2, 1), (2, 1, 0), (1, 2, 0)):
        assert k.psi_energy(*m[list(perm)], p)[0] == pytest.approx(base, rel=1e-13)


# Relative errors measured (max over components, relative to the largest component; energy
# relative to the truth) with k1s = 1000 Pa, k2s = 2:
#   degree 11: uniaxial W 4.8e-5, S 2.6e-3, CC 5.4e-3;  shear W 1.1e-2, S 1.0e-2, CC 5.3e-2
#   degree 17: uniaxial W 7.6e-4, S 1.3e-3, CC 4.4e-3;  shear W 2.4e-3, S 3.0e-3, CC 3.5e-2
#   reference state (polynomial integrand): both below 2e-12.
# Tolerances: about 1.5-2x the measurement.
TOL = {11: {"reference": (1e-12, 1e-12, 1e-11), "uniaxial compression": (1e-4, 5e-3, 1e-2),
            "simple shear": (2e-2, 2e-2, 8e-2)},
       17: {"reference": (1e-12, 1e-12, 1e-11), "uniaxial compression": (1.5e-3, 2.5e-3, 8e-3),
            "simple shear": (5e-3, 6e-3, 6e-2)}}


@pytest.mark.parametrize("degree", [11, pytest.param(17, marks=pytest.mark.slow)])
@pytest.mark.parametrize("state", list(_states()))
def test_energy_stress_tangent_against_sphere_integral(state, degree):
    F = _states()[state]
    W, S, CC = truth(F)
    material = _only_septa(degree)
    W_q = ref.energy(material, F)[0]
    S_q = ref.pk2(material, F)[0]
    CC_q = ref.tangent(material, F)[0]
    tw, ts, tc = TOL[degree][state]
    assert abs(W_q - W) <= tw * max(abs(W), K1S * 1e-12)
    assert np.abs(S_q - S).max() <= ts * max(_scale(S), K1S * 1e-12)
    assert np.abs(CC_q - CC).max() <= tc * _scale(CC)


def test_reference_state_stiffness_is_isotropic_4k_over_15():
    """All fibres on the switch, active side: initial shear modulus 4 k1s / 15 (module docstring)."""
    _, _, CC = truth(np.eye(3))
    assert CC[0, 1, 0, 1] == pytest.approx(4 * K1S / 15, rel=1e-10)


def test_cfm_septa_registered_material():
    from cfm_core import make_material

    m = make_material("cfm-septa")
    assert m.spec is CFM_SEPTA or m.spec.name == "cfm-septa"
    names = [p.name for p in m.spec.parameters]
    assert {"c", "k1", "k2", "k1s", "k2s", "kappa"} <= set(names)


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["numba", "torch", "skfem"])
def test_cfm_septa_runs_on_every_backend(backend):
    """The registered cfm-septa on each backend's material-point path against the numpy reference."""
    from cfm_core import get_backend, make_material
    from cfm_core.simulation.point import run_history

    b = get_backend(backend)
    ok, why = b.available()
    if not ok:
        pytest.skip(f"{backend}: {why}")
    m = make_material("cfm-septa", {"k1s": 500.0, "k2s": 1.5})
    t = np.linspace(0.0, 5e-3, 11)
    F = np.tile(np.eye(3), (t.size, 1, 1))
    F[:, 0, 0] = 1.0 - 60.0 * t  # compression to 0.7 in 5 ms
    F[:, 0, 1] = 40.0 * t  # with shear
    truth = run_history(m, t, F)
    got = run_history(m, t, F, b)
    assert np.abs(got - truth).max() <= 1e-8 * np.abs(truth).max()


#: Table 1 Prony series (g_i, tau_i in s), written here independently of the plugin's TABLE1_PRONY.
TABLE1_G, TABLE1_TAU = np.array([0.45, 0.435, 0.094]), np.array([1e-3, 0.1, 10.0])


@pytest.mark.parametrize("backend", ["reference", "numba", "torch", "skfem"])
def test_registered_cfm_septa_relaxes_with_the_table1_prony_series(backend):
    """Default run, every backend: the registered cfm-septa (default parameters) held after a jump to
    an isochoric stretch with shear relaxes as the Table 1 series says (long-term moduli convention):

        sigma(t) = sigma_el(F) (g_inf + sum g_i exp(-t / tau_i)) / g_inf,   g_inf = 1 - sum g_i

    sigma_el: the elastic material's stress at F (J = 1: no volumetric part, all of it relaxes).
    A cfm-septa composed without its Prony series (or with other terms) gives a constant stress."""
    from cfm_core import get_backend, make_material
    from cfm_core.simulation.point import run_history

    b = None if backend == "reference" else get_backend(backend)
    if b is not None:
        ok, why = b.available()
        if not ok:
            pytest.skip(f"{backend}: {why}")
    m = make_material("cfm-septa")
    jump = 1e-12  # s: the step up to F (its Prony error ~ jump / tau1 = 1e-9)
    t = np.array([0.0, jump, 5e-4, 1e-3, 3e-3, 0.05, 0.3, 5.0, 40.0])
    lam = 0.75
    F = np.tile(np.diag([lam, lam**-0.5, lam**-0.5]), (t.size, 1, 1))
    F[1:, 0, 1] = 0.1
    F[0] = np.eye(3)
    elastic = run_history(make_material("cfm-septa", elastic=True), t[1:2], F[1:2])[0]
    ginf = 1.0 - TABLE1_G.sum()
    ratio = (ginf + np.exp(-(t[1:, None] - jump) / TABLE1_TAU) @ TABLE1_G) / ginf
    truth = ratio[:, None] * elastic[None]
    got = run_history(m, t, F, b)
    assert np.abs(got[0]).max() < 1e-9 * np.abs(elastic).max()  # the reference state: stress-free
    err = np.abs(got[1:] - truth).max() / np.abs(truth).max()
    print(f"{backend}: relaxation ratio {ratio[0]:.4g} -> {ratio[-1]:.4g}, error {err:.2e}")
    assert err < 1e-8
    assert ratio[0] == pytest.approx(1.0 / ginf) and 1.0 < ratio[-1] < 1.1  # 47.6 x down to nearly relaxed
