"""cfm point --uniaxial follows the lateral-stretch branch that starts at J = 1 (continuation from
the previous step) and warns where that branch enters the non-convex part of the volumetric
energy (k2 = 500 pulled to stretch 3: J ~ 18), checked against independent solutions: the root of a
finite difference of the strain energy in the lateral stretch, and the Ogden term's analytic
convexity limit J = 10^(1/9)."""

import math
import subprocess
import sys
import warnings

import numpy as np
import pytest
from scipy.optimize import brentq

from cfm_core.material import reference as ref
from cfm_core.material.registry import make_material
from cfm_core.simulation.point import nearest_root, uniaxial, volumetric_convex

J_LIMIT = 10.0 ** (1.0 / 9.0)  # kappa/81 (9 ln J + J^-9 - 1): U'' = kappa/9 (10 J^-11 - J^-2) < 0 beyond


def _dW(material, lam, lt, h=1e-7):
    """dW/dlt of the strain energy at F = diag(lam, lt, lt) by a central difference (2 P22 lt-free)."""
    F = np.array([np.diag([lam, lt * (1 + h), lt * (1 + h)]), np.diag([lam, lt * (1 - h), lt * (1 - h)])])
    e = ref.energy(material, F)
    return (e[0] - e[1]) / (2 * h * lt)


def _energy_root(material, lam, lo, hi):
    return brentq(lambda x: _dW(material, lam, x), lo, hi, xtol=1e-14)


@pytest.mark.parametrize("stretch", [0.5, 1.5])
def test_lateral_stretch_is_the_energy_stationary_point_and_no_warning(stretch):
    mat = make_material("cfm", elastic=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        t, lam, P, lat = uniaxial(mat, 100.0, stretch, steps=20)
    truth = _energy_root(mat, stretch, 0.5, 2.0)  # a single root: the convex branch, J near 1
    assert abs(lat[-1] - truth) < 1e-6
    assert abs(stretch * lat[-1] ** 2 - 1.0) < 1e-2


def test_stiff_fibres_pulled_far_warn_naming_stretch_and_J():
    mat = make_material("cfm", {"k2": 500.0}, elastic=True)
    with pytest.warns(RuntimeWarning, match=r"from stretch 1\.\d+ .* makes J = 1\.\d+.*not convex") as rec:
        t, lam, P, lat = uniaxial(mat, 100.0, 3.0, steps=40)
    J = lam * lat**2
    first = int(np.argmax(J > J_LIMIT))  # the analytic convexity limit of the Ogden term
    assert f"from stretch {lam[first]:.4g} " in str(rec[0].message)
    assert f"J reaches {J.max():.4g}" in str(rec[0].message) and J.max() > 10
    # the continued branch is the energy's stationary point found independently near the result
    assert abs(lat[-1] - _energy_root(mat, 3.0, 0.99 * lat[-1], 1.01 * lat[-1])) < 1e-6
    assert volumetric_convex(mat, 1.0, 1.0) and not volumetric_convex(mat, 3.0, lat[-1])


def test_continuation_takes_the_root_nearest_the_previous_step():
    f = lambda x: (x - 0.5) * (x - 1.1) * (x - 3.0)  # noqa: E731
    lo, hi = nearest_root(f, 1.0)
    assert lo <= 1.1 <= hi and hi < 1.2  # not 0.5 (10 % further) nor 3
    lo, hi = nearest_root(f, 2.5)
    assert lo <= 3.0 <= hi and lo > 2.5
    assert nearest_root(lambda x: x * x + 1.0, 1.0) == (None, None)
    assert math.isclose(brentq(f, *nearest_root(f, 0.6)), 0.5)


def test_cli_prints_the_warning_and_writes_units(tmp_path):
    out = tmp_path / "u.csv"
    run = subprocess.run([sys.executable, "-m", "cfm_core.cli", "point", "--uniaxial", "--rate", "100", "--stretch",
                          "3", "--steps", "40", "--param", "k2=500", "--elastic", "--no-plot", "--out", str(out)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    lines = run.stderr.splitlines()
    assert lines[0].startswith("warning: [material] k2 = 500 (-, fibre stiffening exponent) is 301x the typical")
    assert lines[1].startswith("warning: uniaxial: from stretch") and "Traceback" not in run.stderr
    assert out.read_text().splitlines()[0] == "t [s],stretch [-],nominal_stress [Pa],lateral_stretch [-]"


def test_volumetric_convexity_at_j_is_the_ogden_terms_analytic_limit():
    """volumetric_convex_at (pure dilatation, vectorised; the check the run monitor of the single-element
    and relaxation scenes shares) against U'' = kappa/9 (10 J^-11 - J^-2): convex for J <= 10^(1/9), also
    in strong compression (J = 0.09)."""
    from cfm_core.simulation.point import volumetric_convex_at

    mat = make_material("cfm", {"k2": 500.0}, elastic=True)
    J = np.array([0.09, 0.5, 1.0, 0.999 * J_LIMIT, 1.001 * J_LIMIT, 2.6, 18.0])
    np.testing.assert_array_equal(volumetric_convex_at(mat, J), 10.0 / J**11 - 1.0 / J**2 >= 0.0)
    assert volumetric_convex_at(mat, [0.0, np.nan]).all()   # nothing to judge


def test_uniaxial_compression_that_crushes_the_volume_warns_and_moderate_compression_does_not():
    """Stretch 0.05 at 100/s: the lateral stretch that frees the sides leaves J = 0.02 and a nominal stress of
    -7e21 Pa, written with exit 0 and no word. Below J = 0.5 the driver warns, naming the stretch."""
    from cfm_core.simulation.point import CRUSHED_J, run_history

    mat = make_material("cfm")
    with pytest.warns(RuntimeWarning, match=r"uniaxial: from stretch 0\.2\d+ .* leaves J below 0\.5 .*volume gone"):
        _, lam, _, lat = uniaxial(mat, 100.0, 0.05, steps=200)
    J = lam * lat**2
    assert J.min() < 0.03 and J[0] == 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _, lam, _, lat = uniaxial(mat, 100.0, 0.5, steps=50)
    assert (lam * lat**2).min() > CRUSHED_J
    F = np.array([np.eye(3), np.diag([0.3, 1.0, 1.0])])
    with pytest.warns(RuntimeWarning, match=r"history: row 1 \(t = 0\.002 s\) has J = det F below 0\.5 \(0\.3\)"):
        run_history(mat, np.array([0.001, 0.002]), F)
