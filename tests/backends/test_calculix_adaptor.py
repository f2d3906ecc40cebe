"""The Fortran linked into ccx (adaptor + generated UMATs) through ccx's ABAQUS calling convention.

ccx's ``umat_abaqus.f`` passes and expects the second Piola-Kirchhoff stress and the tangent
dS/dE; the adaptor converts the generated UMAT's Cauchy stress and Jaumann tangent. Checked here
without ccx (gfortran only): S against the numpy reference pulled back (S = J F^-1 sigma F^-T), and
the tangent against central differences of S in the Green-Lagrange strain, on a rotated,
stretched and sheared F, for the CFM (with its Prony series) and the neo-Hookean material.
"""

import numpy as np
import pytest
from scipy.linalg import expm, sqrtm

from cfm_backends.calculix.build import linked_source
from cfm_core.export.expected import history
from cfm_core.export.generate import sizes
from cfm_core.export.harness import compile_library, gfortran, run_umat
from cfm_core.export.layout import props
from cfm_core.material import make_material

ORDER = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


@pytest.fixture(scope="module")
def setup():
    if gfortran() is None:
        pytest.skip("gfortran is not installed (apt-get install gfortran)")
    mats = [make_material("cfm"), make_material("neo-hookean")]
    text, names = linked_source(mats)
    return mats, compile_library(text, "calculix-adaptor"), names


def _F(s):
    R = expm(np.array([[0.0, -0.3, 0.1], [0.3, 0.0, -0.2], [-0.1, 0.2, 0.0]]))
    U = np.array([[1.0 - 0.25 * s, 0.04 * s, 0.0], [0.04 * s, 1.0 + 0.1 * s, 0.03 * s],
                  [0.0, 0.03 * s, 1.0 + 0.12 * s]])
    return R @ U


def _call(lib, mat, tag, t, F, statev=None):
    return run_umat(lib, props(mat), t, F, sizes(mat.spec)["NS"], statev=statev, cmname=tag)


@pytest.mark.parametrize("which", [0, 1])
def test_pk2_and_material_tangent(setup, which):
    mats, lib, names = setup
    mat = mats[which]
    tag = names[mat.spec.name]["tag"]
    t = np.linspace(0.0, 2e-3, 9)
    F = np.array([_F(s) for s in np.linspace(0.0, 1.0, t.size)])
    out = _call(lib, mat, tag, t, F)
    sigma, _ = history(mat, t, F)
    for k in range(1, t.size):
        J = np.linalg.det(F[k])
        Fi = np.linalg.inv(F[k])
        S = J * Fi @ sigma[k] @ Fi.T
        want = np.array([S[a, b] for a, b in ORDER])
        assert np.allclose(out["stress"][k], want, rtol=1e-9, atol=1e-9 * np.abs(want).max())
    # tangent of the last increment: central differences of S in E at the same start state and dt
    k = t.size - 1
    C = F[k].T @ F[k]
    R = F[k] @ np.linalg.inv(np.real(sqrtm(C)))
    h = 1e-6
    num = np.zeros((6, 6))
    for b, (i, j) in enumerate(ORDER):
        dE = np.zeros((3, 3))
        dE[i, j] = dE[j, i] = h
        cols = []
        for sgn in (1.0, -1.0):
            Fp = R @ np.real(sqrtm(C + 2.0 * sgn * dE))
            o = _call(lib, mat, tag, t[k - 1:k + 1], np.array([F[k - 1], Fp]), statev=out["statev"][k - 1])
            cols.append(o["stress"][1])
        num[:, b] = (cols[0] - cols[1]) / (2.0 * h) / (1.0 if i == j else 2.0)
    scale = np.abs(num).max()
    assert np.allclose(out["ddsdde"][k], num, atol=1e-6 * scale), (out["ddsdde"][k], num)
    # and the tangent is not trivially zero
    assert scale > 0.0


def test_a_refused_iterate_halves_the_increment(setup):
    """An iterate that inverts the element (J < 0): the UMAT refuses it, the adaptor leaves the
    stress as it came in and asks ccx for half the increment (PNEWDT = 0.5; the UMAT's own 0.25
    made ccx crawl back at 10 % per increment after each such cut in the drop test)."""
    mats, lib, names = setup
    mat = mats[0]
    F = np.array([np.eye(3), np.diag([1.0, 1.0, -0.5])])
    out = _call(lib, mat, names[mat.spec.name]["tag"], np.array([0.0, 1e-4]), F)
    assert out["pnewdt"][1] == 0.5
    assert np.array_equal(out["stress"][1], out["stress"][0])


def test_a_relayed_refusal_names_the_cut_ccx_got_not_the_umats():
    """ccx's log carries the UMAT's own line (Abaqus's PNEWDT = 0.25) and the adaptor's; the error
    relayed to the user names the adaptor's cut and the time, from the lines as the Fortran
    writes them (the UMAT template's text, adaptor.f's cut)."""
    import re
    from pathlib import Path

    from cfm_backends.calculix import runner
    from cfm_core.export import abaqus

    clause = "; PNEWDT = 0.25'"
    assert clause in Path(abaqus.__file__).read_text()          # the text the relay replaces
    adaptor = (Path(runner.__file__).parent / "adaptor.f").read_text()
    cuts = set(re.findall(r"pnewdt = ([0-9.]+)d0", adaptor))
    assert cuts == {f"{runner.ADAPTOR_PNEWDT:.1f}"}

    def umat_line(e):
        return f" umat cfm: error  1 at element {e} point 1 (see the error codes in the file header){clause[:-1]}"

    log = "\n".join([umat_line(12), " CFM-UMAT-CUTBACK element 12 point 1 time 1.2300000000000000E-4",
                     umat_line(40), " CFM-UMAT-CUTBACK element 40 point 3 time 2.5000000000000001E-4",
                     " *ERROR: too many cutbacks"])
    msg = runner.umat_refusals(log)
    assert msg.startswith("the UMAT refused 2 iterate(s); ccx cut each increment back by PNEWDT = 0.5")
    assert "at t = 0.00025 s" in msg and "at element 40 point 1" in msg
    assert "0.25" not in msg
    assert runner.umat_refusals(" *ERROR: divergence") == ""
