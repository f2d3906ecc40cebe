"""The generated Abaqus UMAT, called through its calling convention, against the numpy reference:
Cauchy stress within 1e-10 relative along every history, DDSDDE within 1e-6 of the Jaumann-rate
perturbation formula, state carried between increments (a restart equals the continuous run),
and PNEWDT < 1 with an error code where the reference raises."""

import numpy as np
import pytest
from conftest import HISTORIES, uniaxial

from cfm_core.errors import NumericalError
from cfm_core.export import expected, layout
from cfm_core.export.harness import ABAQUS_STANDARD, run_umat
from cfm_core.material import make_material, reference

MATERIALS = {
    "table 1": {},
    "stiff k2 and kappa": {"k2": 20.0, "kappa": 5e8},
}


def _close(got, ref, kappa=666.1e3, rtol=1e-10):
    """Each step's components within rtol of that step's largest reference component, plus the
    round-off floor of the volumetric stress, 1e-14 kappa (Pa): U'(J) ~ kappa (J - 1) with J from
    the eigenvalues of C, which both sides compute to ~1e-16 (simple shear has J = 1 exactly)."""
    err = np.abs(got - ref).max(axis=1)
    bound = rtol * np.abs(ref).max(axis=1) + 1e-14 * kappa
    assert (err <= bound).all(), f"worst step {int(np.argmax(err / bound))}: error {err.max():.3e} Pa"


@pytest.mark.parametrize("values", list(MATERIALS), ids=list(MATERIALS))
@pytest.mark.parametrize("name", list(HISTORIES))
def test_stress_matches_reference(libs, nstate, name, values):
    material = make_material("cfm", MATERIALS[values])
    t, F = HISTORIES[name]()
    sigma, _ = expected.history(material, t, F)
    out = run_umat(libs["abaqus-umat"], layout.props(material), t, F, nstate)
    assert (out["pnewdt"] == 1.0).all() and (out["statev"][:, -1] == 0).all()
    _close(out["stress"], expected.to_order(sigma, ABAQUS_STANDARD), material.values["kappa"])


@pytest.mark.parametrize("moduli", ["instantaneous", "long-term"])
def test_moduli_convention_and_elastic(libs, nstate, moduli):
    t, F = uniaxial(100.0, 0.6)
    for material in (make_material("cfm", moduli=moduli), make_material("cfm", elastic=True)):
        sigma, _ = expected.history(material, t, F)
        out = run_umat(libs["abaqus-umat"], layout.props(material), t, F, nstate)
        _close(out["stress"], expected.to_order(sigma, ABAQUS_STANDARD))


@pytest.mark.parametrize("kappa", [666.1e3, 2e3])
@pytest.mark.parametrize("name", ["compression 100/s", "simple shear", "random 1", "relaxation"])
def test_tangent_is_the_jaumann_rate_tangent(libs, nstate, name, kappa):
    """DDSDDE against the perturbation formula (Miehe; Sun et al.) with the reference, at steps
    along the history (the Prony state of the previous step held); kappa = 2 kPa so that the
    shear part is not hidden behind the bulk modulus."""
    material = make_material("cfm", {"kappa": kappa})
    t, F = HISTORIES[name]()
    _, states = expected.history(material, t, F)
    out = run_umat(libs["abaqus-umat"], layout.props(material), t, F, nstate)
    for k in (1, len(t) // 3, len(t) // 2, len(t) - 1):
        ref = expected.jaumann_tangent(material, F[k], states[k - 1], t[k] - t[k - 1])
        err = np.abs(out["ddsdde"][k] - ref).max()
        assert err <= 1e-6 * np.abs(ref).max(), (k, err, np.abs(ref).max())


def test_restart_from_saved_state_equals_the_continuous_run(libs, cfm, nstate):
    t, F = HISTORIES["relaxation"]()
    lib, props = libs["abaqus-umat"], layout.props(cfm)
    whole = run_umat(lib, props, t, F, nstate)
    m = 30
    first = run_umat(lib, props, t[:m + 1], F[:m + 1], nstate)
    second = run_umat(lib, props, t[m:], F[m:], nstate, statev=first["statev"][-1].copy(),
                      stress=first["stress"][-1].copy())
    assert np.array_equal(second["stress"], whole["stress"][m:])
    assert np.array_equal(second["statev"], whole["statev"][m:])
    assert np.abs(whole["statev"][-1, :18]).max() > 0  # the history is really carried


def test_energies_of_an_elastic_path(libs, nstate):
    """SSE is the strain energy psi (J/m^3) of the reference; SCD (trapezoidal work - SSE) is the
    quadrature error when nothing relaxes: small and second order (a quarter with twice the
    steps); it grows (dissipation) during a relaxation."""
    elastic = make_material("cfm", elastic=True)
    ratio = []
    for n in (100, 200):
        t, F = uniaxial(10.0, 0.6, n=n)
        out = run_umat(libs["abaqus-umat"], layout.props(elastic), t, F, nstate)
        psi = reference.energy(elastic, F)
        assert np.allclose(out["sse"], psi, rtol=1e-10, atol=1e-9)
        ratio.append(abs(out["scd"][-1]) / psi[-1])
    assert ratio[1] < 3e-4 and 3.5 < ratio[0] / ratio[1] < 4.5
    t, F = HISTORIES["relaxation"]()
    visco = run_umat(libs["abaqus-umat"], layout.props(make_material("cfm")), t, F, nstate)
    assert visco["scd"][-1] > 0.1 * visco["sse"][-1]


def _one_step(lib, props, F1, nstate, **kw):
    t = np.array([0.0, 1e-3])
    F = np.stack([np.eye(3), F1])
    return run_umat(lib, props, t, F, nstate, **kw)


def test_inverted_element_asks_for_a_cutback(libs, cfm, nstate):
    F1 = np.diag([-0.5, 1.0, 1.0])
    with pytest.raises(Exception, match="det F"):
        expected.history(cfm, [0, 1e-3], np.stack([np.eye(3), F1]))
    old = np.arange(6.0)
    out = _one_step(libs["abaqus-umat"], layout.props(cfm), F1, nstate, stress=old)
    assert out["pnewdt"][1] == 0.25 and out["statev"][1, -1] == 1.0
    assert np.array_equal(out["stress"][1], old)  # unchanged, no NaN


def test_overflow_asks_for_a_cutback(libs, nstate):
    stiff = make_material("cfm", {"k2": 2000.0})
    F1 = np.diag([2.0, 2.0 ** -0.5, 2.0 ** -0.5])
    with pytest.raises(NumericalError):
        reference.cauchy(stiff, F1)
    out = _one_step(libs["abaqus-umat"], layout.props(stiff), F1, nstate)
    assert out["pnewdt"][1] == 0.25 and out["statev"][1, -1] == 2.0
    assert np.isfinite(out["stress"]).all() and np.isfinite(out["statev"]).all()


@pytest.mark.parametrize("change", ["sum of g >= 1", "sum of g 1 in decimal", "gamma_inf 1e-7", "tau <= 0",
                                    "moduli 2", "nprops"])
def test_invalid_constants_are_refused(libs, cfm, nstate, change):
    props = layout.props(cfm)
    if change == "sum of g >= 1":
        props[[4, 6, 8]] = [0.5, 0.4, 0.2]
    elif change == "sum of g 1 in decimal":           # 1 - sum is 1.1e-16 in floating point: was run,
        props[[4, 6, 8]] = [0.471, 0.435, 0.094]      # at moduli 1e16 times too large (8e17 Pa)
    elif change == "gamma_inf 1e-7":                  # below the floor cfm refuses (prony.GAMMA_INF_MIN)
        props[[4, 6, 8]] = [0.5, 0.4999999, 0.0]
    elif change == "tau <= 0":
        props[5] = 0.0
    elif change == "moduli 2":
        props[10] = 2.0
    else:
        props = props[:-1]
    out = _one_step(libs["abaqus-umat"], props, np.diag([0.9, 1.0, 1.0]), nstate)
    assert out["pnewdt"][1] == 0.25 and out["statev"][1, -1] == 3.0


def test_gamma_inf_at_the_floor_cfm_accepts_runs(libs, nstate):
    """gamma_inf = 1e-6 (the floor, accepted by cfm with a warning) runs, with the moduli 1e6 times
    the long-term ones, as the reference computes them."""
    from cfm_core.material.prony import GAMMA_INF_MIN

    material = make_material("cfm", {"g1": 0.471 - GAMMA_INF_MIN})
    t, F = uniaxial(1.0, 0.95, n=4)
    sigma, _ = expected.history(material, t, F)
    out = run_umat(libs["abaqus-umat"], layout.props(material), t, F, nstate)
    assert (out["pnewdt"] == 1.0).all() and (out["statev"][:, -1] == 0).all()
    _close(out["stress"], expected.to_order(sigma, ABAQUS_STANDARD), material.values["kappa"], rtol=1e-8)
