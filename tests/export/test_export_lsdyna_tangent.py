"""The generated LS-DYNA tangent routine utan41 (implicit runs), called after umat41 at each step
through its calling convention: es = c / J (the push-forward of dS/dE over J, the Truesdell rate
of the Kirchhoff stress over J) within 1e-6 of the perturbation formula with the numpy reference,
the consistent tangent of the step with the Prony series; the neo-Hookean against its closed form;
symmetric; equal to the UMAT's DDSDDE less its Jaumann stress terms (a cross-check of the shared
code, not the truth); a zero es and a message, not a NaN, on an error."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import HISTORIES, uniaxial

from cfm_core.export import expected, layout
from cfm_core.export.generate import generate
from cfm_core.export.harness import ABAQUS_STANDARD, LSDYNA, run_lsdyna, run_umat
from cfm_core.material import make_material

MATERIALS = {"table 1": {}, "kappa 2 kPa": {"kappa": 2e3}, "stiff k2 and kappa": {"k2": 20.0, "kappa": 5e8}}


def _steps(n):
    return sorted({1, 2, n // 3, n // 2, (3 * n) // 4, n - 1})


def _worst(material, lib, t, F, nhv, steps, eps=1e-6):
    """Largest |es - truth| / max |truth| over the steps, against two perturbation truths:

    - from the step's own Prony state, where that is well conditioned: its round-off,
      1e-16 |tau| / eps, below 1e-8 of the tangent (after a 1e17 Pa peak of the stiff material
      the held history stress is 1e7 times the tangent and the difference loses those digits);
    - from a relaxed start (state None), at every step: the Truesdell tangent of a step does not
      depend on the state (the recurrence is affine in it, and the push-forward of an
      F-independent S has no Lie derivative), so both truths are the same tangent.

    Returns the two errors, the number of steps checked against the first, and the run.
    """
    sigma, states = expected.history(material, t, F)
    out = run_lsdyna(lib, layout.props(material, lsdyna=True), t, F, nhv, tangent=True)
    held, relaxed, checked = 0.0, 0.0, 0
    for k in steps:
        dt = t[k] - t[k - 1]
        ref = expected.rate_tangent(material, F[k], None, dt, "truesdell", LSDYNA, eps)
        relaxed = max(relaxed, np.abs(out["es"][k] - ref).max() / np.abs(ref).max())
        tau = np.linalg.det(F[k]) * np.abs(sigma[k]).max()
        if 1e-16 * tau / eps <= 1e-8 * np.abs(ref).max():
            ref = expected.rate_tangent(material, F[k], states[k - 1], dt, "truesdell", LSDYNA, eps)
            held = max(held, np.abs(out["es"][k] - ref).max() / np.abs(ref).max())
            checked += 1
    return held, relaxed, checked, out


@pytest.mark.parametrize("values", list(MATERIALS))
@pytest.mark.parametrize("name", list(HISTORIES))
def test_utan_is_the_spatial_tangent_of_the_step(libs, nstate, name, values):
    """Every history of the harness (compression and tension at several rates, relaxation, simple
    shear, random); kappa = 2 kPa so that the shear part is not hidden behind the bulk modulus."""
    material = make_material("cfm", MATERIALS[values])
    t, F = HISTORIES[name]()
    steps = _steps(len(t))
    held, relaxed, checked, out = _worst(material, libs["lsdyna-umat"], t, F, nstate, steps)
    assert held <= 1e-6 and relaxed <= 1e-6, (held, relaxed)
    assert checked >= len(steps) - 1
    assert not out["reject"].any() and not out["unsym"][1:].any()
    es = out["es"][1:]
    assert np.abs(es - np.swapaxes(es, 1, 2)).max() <= 1e-12 * np.abs(es).max()


def test_prony_tangent_is_the_one_of_its_step(libs, nstate):
    """The same F after a short and a long step: two consistent tangents (gain_i falls with dt),
    each the perturbation's of its own step, the long step's softer in shear."""
    material = make_material("cfm", {"kappa": 2e3})
    lib, cm = libs["lsdyna-umat"], layout.props(material, lsdyna=True)
    F1 = np.diag([0.7, 0.7 ** -0.45, 0.7 ** -0.45])
    shear = []
    for dt in (1e-5, 100.0):
        t, F = np.array([0.0, dt]), np.stack([np.eye(3), F1])
        out = run_lsdyna(lib, cm, t, F, nstate, tangent=True)
        ref = expected.rate_tangent(material, F1, None, dt, "truesdell", LSDYNA)
        assert np.abs(out["es"][1] - ref).max() <= 1e-6 * np.abs(ref).max()
        shear.append(out["es"][1, 3, 3])
    assert shear[1] < 0.5 * shear[0], shear


def _neo_hookean_es(mu, kappa, F):
    """Closed form of c / J for psi = mu/2 (I1bar - 3) + kappa/2 (J - 1)^2 (Holzapfel 2000, 6.6):
    c = 2/3 mu tr(bbar) P - 2/3 mu (I (x) dev bbar + dev bbar (x) I) + J (p + J p') I (x) I - 2 J p I4,
    p = kappa (J - 1), P = I4 - 1/3 I (x) I; LS-DYNA order."""
    J = np.linalg.det(F)
    b = J ** (-2.0 / 3.0) * F @ F.T
    I = np.eye(3)
    dev = b - np.trace(b) / 3.0 * I
    II = np.einsum("ij,kl->ijkl", I, I)
    I4 = 0.5 * (np.einsum("ik,jl->ijkl", I, I) + np.einsum("il,jk->ijkl", I, I))
    p = kappa * (J - 1.0)
    c = (2.0 / 3.0 * mu * np.trace(b) * (I4 - II / 3.0)
         - 2.0 / 3.0 * mu * (np.einsum("ij,kl->ijkl", I, dev) + np.einsum("ij,kl->ijkl", dev, I))
         + J * (p + J * kappa) * II - 2.0 * J * p * I4)
    return np.array([[c[i, j, k, l] for k, l in LSDYNA] for i, j in LSDYNA]) / J


@pytest.mark.parametrize("path", ["compression", "random"])
def test_neo_hookean_against_its_closed_form(compiled, path):
    material = make_material("neo-hookean", {"kappa": 5e3})
    lib = compiled(material, "lsdyna-umat")
    assert lib.warnings == ""
    t, F = uniaxial(100.0, 0.5, n=20) if path == "compression" else HISTORIES["random 1"]()
    nhv = len(layout.state_variables(material.spec))
    out = run_lsdyna(lib, layout.props(material, lsdyna=True), t, F, nhv, tangent=True)
    mu, kappa = material.values["mu"], material.values["kappa"]
    for k in range(1, len(t)):
        ref = _neo_hookean_es(mu, kappa, F[k])
        assert np.abs(out["es"][k] - ref).max() <= 1e-9 * np.abs(ref).max(), k
    # the closed form is the truth the perturbation formula must meet too (a check of the formula)
    k = len(t) // 2
    fd = expected.rate_tangent(material, F[k], None, t[k] - t[k - 1], "truesdell", LSDYNA)
    assert np.abs(fd - _neo_hookean_es(mu, kappa, F[k])).max() <= 1e-6 * np.abs(fd).max()


def test_utan_is_the_umat_tangent_without_the_jaumann_terms(libs, nstate):
    """DDSDDE - 1/2 (d_ik s_jl + d_il s_jk + d_jk s_il + d_jl s_ik), reordered 11, 22, 33, 12, 23, 31:
    the same generated code (cmj) through both interfaces."""
    material = make_material("cfm", {"kappa": 2e3})
    t, F = HISTORIES["random 2"]()
    umat = run_umat(libs["abaqus-umat"], layout.props(material), t, F, nstate)
    dyna = run_lsdyna(libs["lsdyna-umat"], layout.props(material, lsdyna=True), t, F, nstate, tangent=True)
    d = np.eye(3)
    perm = [ABAQUS_STANDARD.index(tuple(sorted(pair))) for pair in LSDYNA]
    for k in range(1, len(t)):
        sig = np.zeros((3, 3))
        for m, (a, b) in enumerate(ABAQUS_STANDARD):
            sig[a, b] = sig[b, a] = umat["stress"][k, m]
        term = np.array([[0.5 * (d[i, p] * sig[j, q] + d[i, q] * sig[j, p] + d[j, p] * sig[i, q]
                                 + d[j, q] * sig[i, p]) for p, q in ABAQUS_STANDARD] for i, j in ABAQUS_STANDARD])
        want = (umat["ddsdde"][k] - term)[np.ix_(perm, perm)]
        assert np.abs(dyna["es"][k] - want).max() <= 1e-12 * np.abs(want).max(), k


@pytest.mark.parametrize("case", ["J <= 0", "overflow", "constants", "shell"])
def test_errors_give_zero_tangent_not_nan(libs, nstate, case):
    material = make_material("cfm", {"k2": 2000.0} if case == "overflow" else {})
    cm = layout.props(material, lsdyna=True)
    F1 = {"J <= 0": np.diag([-0.5, 1.0, 1.0]), "overflow": np.diag([2.0, 2.0 ** -0.5, 2.0 ** -0.5])}.get(
        case, np.diag([0.9, 1.0, 1.0]))
    if case == "constants":
        cm[[4, 6, 8]] = [0.5, 0.4, 0.2]  # g1 + g2 + g3 >= 1
    out = run_lsdyna(libs["lsdyna-umat"], cm, np.array([0.0, 1e-3]), np.stack([np.eye(3), F1]), nstate,
                     etype="shell" if case == "shell" else "solid", tangent=True)
    assert out["reject"][1]  # umat41 rejects the step
    assert np.array_equal(out["es"][1], np.zeros((6, 6))) and not out["unsym"][1]


def test_error_message_on_unit_6(libs, nstate):
    """The line utan41 writes (unit 6, unbuffered in a fresh process so that it can be read)."""
    code = ("import numpy as np; from cfm_core.export.harness import Library, run_lsdyna; "
            "from cfm_core.export import layout; from cfm_core.material import make_material; "
            f"lib = Library(__import__('pathlib').Path({str(libs['lsdyna-umat'].path)!r}), ''); "
            "cm = layout.props(make_material('cfm'), lsdyna=True); "
            f"run_lsdyna(lib, cm, np.array([0.0, 1e-3]), np.stack([np.eye(3), np.diag([-0.5, 1.0, 1.0])]), "
            f"{nstate}, tangent=True)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "GFORTRAN_UNBUFFERED_ALL": "y"})
    assert done.returncode == 0, done.stderr
    assert "utan41 cfm: error  1 at time" in done.stdout and "es = 0" in done.stdout, done.stdout


def test_manifest_header_and_card_name_the_tangent(cfm):
    ex = generate(cfm, "lsdyna-umat")
    routines = {r["name"]: r for r in ex.manifest["routines"]}
    assert list(routines) == ["umat41", "utan41"]
    assert "implicit" in routines["utan41"]["role"] and "es(6,6)" in routines["utan41"]["calling_convention"]
    assert json.loads(ex.files["manifest.json"])["routines"] == ex.manifest["routines"]
    source = ex.files["umat41.f"]
    header = source[:source.index("      subroutine")]
    assert "utan41" in header and "implicit" in header and "not run in the commercial solver" in header
    assert "subroutine utan41(" in source
    assert "utan41" in ex.files["material.k"] and "not run in LS-DYNA" in ex.files["material.k"]
    assert [r["name"] for r in generate(cfm, "abaqus-umat").manifest["routines"]] == ["umat"]
