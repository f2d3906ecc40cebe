"""calculix backend: the project's scenes run in CalculiX (ccx 2.20) through the generated UMAT.

Needs a build (``cfm calculix build``): without one the tests skip, saying so; with
``CFM_REQUIRE_CALCULIX=1`` (CI) a missing build fails them instead. Independent truth: the
uniaxial material-point driver (its own lateral solution) and the skfem backend; CalculiX's own
``*HYPERELASTIC, NEO HOOKE`` against the generated neo-Hookean UMAT.
"""


import numpy as np
import pytest

from cfm_core.errors import InputError
from cfm_core.scene.builder import build_model
from cfm_core.scene.scene import builtin_scene
from cfm_core.simulation.point import uniaxial
from cfm_core.simulation.registry import get_backend


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def test_single_element_against_uniaxial_driver_and_skfem(ccx):
    sc = builtin_scene("single-element").with_overrides(output_rate=10_000.0)
    m = build_model(sc)
    el = sc.element
    r = ccx.run(m)
    assert r.backend == "calculix" and r.reaction_force is not None
    tu, _, P, _ = uniaxial(m.material, el.rate, el.stretch, steps=round(el.load_time / m.output_interval))
    ref = P * el.size ** 2
    err = _rel(np.interp(tu, r.t, r.reaction_force), ref)
    print(f"calculix single element: {r.steps} increments in {r.wall_time:.2f} s; max deviation from the "
          f"uniaxial driver {100 * err:.3g} % of the peak")
    assert err < 5e-3
    s = get_backend("skfem").run(m, quasi_static=True)
    err_s = _rel(np.interp(s.t, r.t, r.reaction_force), s.reaction_force)
    print(f"... from skfem {100 * err_s:.3g} %")
    assert err_s < 5e-3


def test_relaxation_against_uniaxial_driver(ccx):
    sc = builtin_scene("relaxation").with_overrides(hold=0.5, output_rate=200.0)
    m = build_model(sc)
    rx = sc.relaxation
    r = ccx.run(m)
    tu, _, P, _ = uniaxial(m.material, abs(rx.stretch - 1) / rx.load_time, rx.stretch, steps=50, hold=rx.hold)
    ref = P * rx.size ** 2
    got = np.interp(tu, r.t, r.reaction_force)
    hold = tu >= rx.load_time
    err = _rel(got[hold], ref[hold])
    print(f"calculix relaxation: {r.steps} increments in {r.wall_time:.2f} s; hold deviation {100 * err:.3g} %")
    assert err < 5e-3
    # it relaxes: the force at the end of the hold is well below the peak
    assert abs(r.reaction_force[-1]) < 0.8 * np.max(np.abs(r.reaction_force))


def test_native_neo_hooke_equals_generated_umat(ccx):
    """CalculiX's own NEO HOOKE and the generated UMAT of the same energy, one element (homogeneous: a point)."""
    sc = builtin_scene("single-element").with_overrides(material="neo-hookean", output_rate=10_000.0)
    m = build_model(sc)
    umat = ccx.run(m)
    native = ccx.run(m, native=True)
    np.testing.assert_allclose(native.t, umat.t, rtol=0, atol=1e-12)
    assert np.max(np.abs(native.reaction_force)) > 1e-4  # mu = 1 kPa on 1 mm^2 at 50 % compression: mN
    # ccx prints 7 significant digits (.dat): equal to that precision
    err = _rel(umat.reaction_force, native.reaction_force)
    print(f"native NEO HOOKE vs generated UMAT: {err:.3g} relative")
    assert err < 1e-6


def test_native_refuses_other_materials(ccx):
    m = build_model(builtin_scene("single-element"))
    with pytest.raises(InputError, match="NEO HOOKE"):
        ccx.run(m, native=True)


def test_drop_test_deck_is_written(tmp_path):
    """The drop test goes through the same deck writer (tests/backends/test_calculix_drop.py checks it)."""
    from cfm_backends.calculix.deck import write_deck

    m = build_model(builtin_scene("drop-test").with_overrides(element_size=0.002))
    write_deck(m, tmp_path / "job.inp")
    text = (tmp_path / "job.inp").read_text()
    assert "*RIGID BODY" in text and "*DYNAMIC\n5e-05," in text
