"""`cfm point --uniaxial` near the incompressible limit: the nominal stress stays right as kappa grows.

Truth: the elastic CFM's uniaxial closed form from the paper's equations (``fixtures.uniaxial_truth``).
Before: P11 = l S11 at the lateral stretch that zeroes S22 carried the pressure's round-off, kappa
times the last bit of J: at stretch 0.7, 4.5e-10 relative at kappa x 1e3, 5.6e-4 at x 1e9 and 47 %
at x 1e12 (-2320.7 against -1579.5 Pa), exit 0. Now P11 = (tau11 - tau22) / l, in which the
pressure cancels.
"""

import numpy as np
import pytest

from cfm_core import make_material
from cfm_core.simulation import point as pt
from fixtures import uniaxial_truth as truth

STRETCH = 0.7


@pytest.mark.parametrize("factor", [1.0, 1e3, 1e6, 1e9, 1e12])
def test_uniaxial_nominal_stress_matches_the_closed_form_up_to_huge_kappa(factor):
    kappa = truth.KAPPA * factor
    mat = make_material("cfm", {"kappa": kappa}, elastic=True)
    _, lam, P, lat = pt.uniaxial(mat, 1e-6, STRETCH, steps=20)
    exact = truth.nominal_stress(truth.C, truth.K1, kappa, STRETCH)
    print(f"kappa x {factor:g}: P11 = {P[-1]:.12g} Pa, closed form {exact:.12g} Pa")
    assert lam[-1] == STRETCH
    assert P[-1] == pytest.approx(exact, rel=1e-9)


def test_a_backend_along_the_path_carries_no_pressure_round_off():
    """numba's stress along the reference's path at kappa x 1e12: the same nominal stress, although its
    lateral stress (pressure round-off) is no longer small next to the axial one."""
    pytest.importorskip("numba")
    from cfm_core.simulation.registry import get_backend

    mat = make_material("cfm", {"kappa": truth.KAPPA * 1e12}, elastic=True)
    t, lam, P, lat = pt.uniaxial(mat, 1e-6, STRETCH, steps=20)
    nominal, residual = pt.uniaxial_on_backend(mat, get_backend("numba"), t, lam, lat)
    exact = truth.nominal_stress(truth.C, truth.K1, truth.KAPPA * 1e12, STRETCH)
    assert nominal[-1] == pytest.approx(exact, rel=1e-9)
    assert np.all(np.isfinite(nominal)) and residual > 1e-6   # the pressure's round-off, cancelled in P11


def test_nominal_uniaxial_is_tau11_over_l_where_the_lateral_stress_is_zero():
    assert pt.nominal_uniaxial(0.5, -100.0, 0.0) == -200.0
    tau_dev = np.array([-300.0, 150.0])            # deviatoric Kirchhoff stresses along and across
    for p in (0.0, 1e3, 1e12):                     # any pressure term -p J, the same P11
        assert pt.nominal_uniaxial(0.5, tau_dev[0] - p, tau_dev[1] - p) == pytest.approx(-900.0, rel=1e-3 if p > 1e9 else 1e-15)


@pytest.mark.parametrize("equibiaxial", [False, True])
@pytest.mark.parametrize("factor", [1.0, 1e3, 1e6, 1e9, 1e12])
def test_lab_tests_converge_and_match_the_closed_form_up_to_huge_kappa(factor, equibiaxial):
    """The fits' test simulator (``cfm fit``): its Newton on the lateral stretch stopped only below 1e-11 of
    the stresses, which kappa's round-off forbids from kappa x 1e3 (6.7e8 Pa, below water's 2.2e9): every
    uniaxial fit of a nearly incompressible material failed with "did not converge". Now it converges when the
    stretch stops moving, and the nominal stress carries no pressure round-off."""
    from cfm_core.studies.lab_tests import LabTest, simulate

    kappa = truth.KAPPA * factor
    mat = make_material("cfm", {"kappa": kappa}, elastic=True)
    t = np.linspace(0.0, 0.3, 31)
    kind = "equibiaxial" if equibiaxial else "uniaxial"
    test = LabTest(name=kind, path="-", kind=kind, rate=1.0, weight=1.0, t=t, x=1.0 - t, P=np.ones_like(t))
    P = simulate(mat, test)
    exact = truth.nominal_stress(truth.C, truth.K1, kappa, STRETCH, equibiaxial=equibiaxial)
    print(f"{kind} kappa x {factor:g}: P11 = {P[-1]:.12g} Pa, closed form {exact:.12g} Pa")
    assert P[-1] == pytest.approx(exact, rel=1e-9)
