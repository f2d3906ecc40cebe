"""skfem backend: Newton's convergence test is invariant to the stiffness scale (issue 20, item 6).

Truth: the long-term uniaxial-stress response of the elastic CFM at a held stretch of 0.7, written
from the paper's equations and solved with scipy's brentq (``fixtures.uniaxial_truth``). The
incompressible limit (e = 0) is -1579.4976 Pa (shared case incompressible-newton-tolerance, its
mpmath closed form agrees to 1e-10).

Before: the absolute Newton tolerance 1e-10 kappa h^2 grew with kappa, and at kappa = 6.661e11 Pa
the force was 3 % off with exit 0 (the tolerance was 4 % of the reaction).
"""

import math

import pytest

pytest.importorskip("skfem")

from cfm_core.errors import NumericalError  # noqa: E402
from cfm_core.scene.builder import build_model  # noqa: E402
from cfm_core.scene.scene import builtin_scene  # noqa: E402
from cfm_core.simulation.checks import check_result  # noqa: E402
from cfm_core.simulation.registry import get_backend  # noqa: E402
from fixtures import uniaxial_truth  # noqa: E402

C, K1, KAPPA = uniaxial_truth.C, uniaxial_truth.K1, uniaxial_truth.KAPPA  # Table 1 (Pa)
STRETCH, SIZE = 0.7, 1e-3                         # held stretch (-), element edge (m)
LIMIT = -1579.4976                                # incompressible limit of P1 (Pa), 5 digits of the case


def nominal_stress(c, k1, kappa, stretch=STRETCH):
    """Long-term uniaxial nominal stress P1 (Pa) at the held stretch; kappa = inf: incompressible."""
    return uniaxial_truth.nominal_stress(c, k1, kappa, stretch)


def run(factor_all=1.0, factor_kappa=1.0):
    """skfem quasi-static run of one 1 mm element held at 0.7 (the shared case's scene)."""
    sc = builtin_scene("relaxation").with_overrides(
        stretch=STRETCH, load_time=1e-3, hold=1e-3, output_rate=1000.0, elastic=True,
        parameters={"c": C * factor_all, "k1": K1 * factor_all, "kappa": KAPPA * factor_all * factor_kappa})
    m = build_model(sc)
    r = get_backend("skfem").run(m)
    return m, r, float(r.reaction_force[-1]) / SIZE**2


def test_the_closed_form_reaches_the_incompressible_limit():
    assert nominal_stress(C, K1, KAPPA) == pytest.approx(-1577.66036372, rel=1e-10)  # the case's mpmath value
    assert nominal_stress(C, K1, math.inf) == pytest.approx(LIMIT, abs=1e-4)
    assert nominal_stress(C, K1, KAPPA * 1e9) == pytest.approx(-1579.49762467, rel=1e-10)


@pytest.mark.parametrize("factor", [1.0, 1e6])
def test_the_force_is_invariant_to_the_stiffness_scale(factor):
    """c, k1 and kappa times 1e6: the same problem in other units; the force scales exactly."""
    m, r, P = run(factor_all=factor)
    truth = nominal_stress(C * factor, K1 * factor, KAPPA * factor)
    err = abs(P / truth - 1.0)
    print(f"moduli x {factor:g}: P1 = {P:.10g} Pa, closed form {truth:.10g} Pa, relative error {err:.2e}")
    assert err < 1e-6
    assert check_result(m, r) == [] and r.info["force_balance"]["relative"] <= 1e-9


def test_nearly_incompressible_converges_to_the_limit_or_says_how_far_it_can():
    """kappa x 1e3, 1e6, 1e9 (kappa / c up to 6.7e13): the force approaches the incompressible limit;
    where float64 round-off of kappa (J - 1) keeps Newton above rtol, the run warns with the force
    balance it reached, and that bound holds."""
    runs = {f: run(factor_kappa=f) for f in (1e3, 1e6, 1e9)}
    errors = {f: abs(P / nominal_stress(C, K1, KAPPA * f) - 1.0) for f, (_, _, P) in runs.items()}
    print("relative errors:", {f"x{f:g}": f"{e:.2e}" for f, e in errors.items()})
    assert errors[1e3] < 1e-8 and errors[1e6] < 1e-6 and errors[1e9] < 1e-3  # before: 3 % at x 1e6
    for f, (m, r, P) in runs.items():
        bal = r.info["force_balance"]["relative"]
        warned = check_result(m, r)
        print(f"kappa x {f:g}: P1 = {P:.10g} Pa, error {errors[f]:.2e}, force balance {bal:.2e}, "
              f"warnings {len(warned)}")
        assert errors[f] <= max(1e-6, bal)  # never a wrong force reported as converged
        assert (bal > 1e-8) == bool(warned)  # rtol 1e-9 of a quasi-static run: warned above 10 x rtol
        if warned:
            assert "round-off" in warned[0] and "kappa0" in warned[0]
        assert abs(P / LIMIT - 1.0) < 2e-3 / f + max(bal, 1e-6)  # towards the limit: ~stress / (2 kappa)


def test_a_bulk_modulus_beyond_float64_stops_the_run():
    """kappa x 1e11: the round-off of the volumetric forces is 3 % of the forces: a NumericalError
    naming the force balance, not a result."""
    with pytest.raises(NumericalError) as err:
        run(factor_kappa=1e11)
    assert err.value.quantity in ("force balance", "Newton residual", "linear solve")
    if err.value.quantity == "force balance":
        assert "round-off" in str(err.value) and "cannot be trusted" in str(err.value)
