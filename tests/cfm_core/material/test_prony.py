"""Prony viscoelasticity: relaxation, long-term response, large steps, against a direct convolution."""

import numpy as np
import pytest

from cfm_core import make_material
from cfm_core.material import reference as ref
from cfm_core.material.prony import relaxation_function
from cfm_verification.truths import convolution_reference  # hereditary integral, hand-written Eq. 2-7


def shear_history(t, gamma):
    F = np.repeat(np.eye(3)[None], t.size, axis=0)
    F[:, 0, 1] = gamma
    return F


@pytest.mark.parametrize("steps", [np.logspace(-6, 2, 60), np.array([1e-4, 30.0])])
def test_step_relaxation_follows_g(steps):
    """A held small shear relaxes exactly as g(t), whatever the step sizes."""
    mat = make_material("cfm", moduli="instantaneous")
    t = np.concatenate([[0.0], steps])
    sigma = ref.stress_history(mat, t, shear_history(t, 1e-6))
    ratio = sigma[:, 0, 1] / sigma[0, 0, 1]
    g = relaxation_function(t, *mat.prony_arrays())
    assert np.allclose(ratio, g, rtol=1e-9, atol=1e-12)


def test_long_term_is_gamma_inf_times_instantaneous():
    mat = make_material("cfm", {"k2": 3.0}, moduli="instantaneous")
    t = np.array([0.0, 1e3])  # held for 100 tau3
    F = np.diag([0.8, 1.1, 1.15])[None].repeat(2, axis=0)
    S_iso0, S_vol = ref.pk2_parts(mat, F)
    sigma = ref.stress_history(mat, t, F)
    gammas, _ = mat.prony_arrays()
    from cfm_core.material.kinematics import cauchy_from_pk2

    expected = cauchy_from_pk2(F, (1 - gammas.sum()) * S_iso0 + S_vol)
    assert np.allclose(sigma[1], expected[1], rtol=1e-10, atol=1e-9)


def test_long_term_moduli_convention_relaxes_to_the_written_parameters():
    """moduli='long-term': after full relaxation the response is the elastic one with c, k1 as written."""
    visco = make_material("cfm", moduli="long-term")
    elastic = make_material("cfm", elastic=True)
    t = np.array([0.0, 2e3])
    F = np.diag([0.7, 1.2, 1.2])[None].repeat(2, axis=0)
    assert np.allclose(ref.stress_history(visco, t, F)[1], ref.cauchy(elastic, F)[1], rtol=1e-9)


def test_steps_much_larger_than_tau_stay_stable_and_bounded():
    mat = make_material("cfm", {"tau1": 1e-7}, moduli="instantaneous")
    t = np.linspace(0, 0.02, 21)  # dt = 1 ms = 1e4 tau1
    lam = 1 - 10 * t
    F = np.zeros((t.size, 3, 3))
    F[:, 0, 0] = lam
    F[:, 1, 1] = F[:, 2, 2] = 1 / np.sqrt(lam)
    sigma = ref.stress_history(mat, t, F)
    inst = ref.cauchy(mat, F)
    assert np.isfinite(sigma).all()
    assert (np.abs(sigma[:, 0, 0]) <= np.abs(inst[:, 0, 0]) * (1 + 1e-12)).all()
    # the first term relaxes fully within each step: equal to the series without it, i.e. the
    # moduli scaled by (1 - g1) and the other gammas renormalised by 1/(1 - g1)
    v = mat.values
    s = 1 - v["g1"]
    no_term1 = make_material("cfm", {"c": v["c"] * s, "k1": v["k1"] * s, "g1": 0.0, "g2": v["g2"] / s,
                                     "g3": v["g3"] / s, "tau1": 1e-7}, moduli="instantaneous")
    sig2 = ref.stress_history(no_term1, t, F)
    dev = sigma[:, 0, 0] - sigma[:, 1, 1]
    dev2 = sig2[:, 0, 0] - sig2[:, 1, 1]
    assert np.allclose(dev[1:], dev2[1:] , rtol=2e-4)


def test_viscoelastic_history_matches_direct_convolution():
    mat = make_material("cfm")
    t = np.linspace(0, 4e-3, 41)  # 0.1 ms rows: compression to 0.6 at 100 1/s then hold
    lam = np.maximum(1 - 100 * t, 0.6)
    F = np.zeros((t.size, 3, 3))
    F[:, 0, 0] = lam
    F[:, 1, 1] = F[:, 2, 2] = 1 / np.sqrt(lam) * 1.01
    F[:, 0, 1] = 0.05 * t / t[-1]
    got = ref.stress_history(mat, t, F)
    truth = convolution_reference(mat, t, F, sub=400)
    peak = np.abs(truth).max()
    assert np.abs(got - truth).max() / peak < 1e-3
