"""skfem backend: registration, options, single-element and relaxation scenes, errors."""

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("skfem")

from cfm_core.material import reference as ref
from cfm_core.scene.builder import build_model
from cfm_core.errors import InputError, NumericalError
from cfm_core.simulation.point import uniaxial
from cfm_core.simulation.registry import get_backend
from cfm_core.plugins import names
from cfm_core.scene.scene import builtin_scene


def test_registered_with_capabilities():
    assert "skfem" in names("backends")
    b = get_backend("skfem")
    assert (b.name, b.kind, b.needs_tangent, b.requires) == ("skfem", "implicit", True, ("skfem",))
    assert b.available() == (True, "")


def test_import_does_not_import_skfem():
    code = ("import sys, cfm_backends.skfem_implicit as m; from cfm_core.simulation.registry import get_backend; "
            "get_backend('skfem'); assert 'skfem' not in sys.modules, 'skfem imported'")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_bad_options():
    m = build_model(builtin_scene("single-element"))
    b = get_backend("skfem")
    with pytest.raises(InputError, match="unknown option.*dtmax"):
        b.run(m, dtmax=1.0)
    with pytest.raises(InputError, match="rho_inf"):
        b.run(m, rho_inf=2.0)
    with pytest.raises(InputError, match="linear_solver"):
        b.run(m, linear_solver="lu")


def test_single_element_matches_uniaxial_driver():
    """Free lateral faces: uniaxial stress; same steps as the driver -> Newton-tolerance agreement."""
    sc = builtin_scene("single-element").with_overrides(output_rate=10_000.0)
    m = build_model(sc)
    el = sc.element
    tu, _, P, _ = uniaxial(m.material, el.rate, el.stretch, steps=round(el.load_time / m.output_interval))
    refF = P * el.size ** 2
    b = get_backend("skfem")
    r = b.run(m, quasi_static=True)
    np.testing.assert_allclose(r.t, tu, rtol=0, atol=1e-12)
    err = np.abs(r.reaction_force - refF).max() / np.abs(refF).max()
    rd = b.run(m)  # dynamic (Newmark-type with inertia): inertia of a 1 mm cube is negligible
    err_dyn = np.abs(np.interp(tu, rd.t, rd.reaction_force) - refF).max() / np.abs(refF).max()
    print(f"single element: quasi-static error {err:.2e}, dynamic error {err_dyn:.2e}")
    assert err < 1e-7 and err_dyn < 5e-3
    assert r.reaction_force[-1] < 0  # compression: negative (tension positive)
    assert np.isfinite(r.energies["internal"]).all() and r.contact_force is None


def test_relaxation_scene_model():
    m = build_model(builtin_scene("relaxation"))
    assert m.meta["quasi_static"] and m.density == 0.0 and m.n_elements == 1
    np.testing.assert_allclose(m.prescribed.times, [0.0, 1e-3, 30.001])
    np.testing.assert_allclose(m.prescribed.values, [0.0, -3e-4, -3e-4])
    assert m.end_time == pytest.approx(30.001)
    c = build_model(builtin_scene("relaxation").with_overrides(lateral="confined"))
    assert len(c.fixed_dofs) == len(m.fixed_dofs) + 8  # x = size (dof 0) and y = size (dof 1)
    with pytest.raises(InputError, match=r"\[relaxation\] lateral"):
        builtin_scene("relaxation").with_overrides(lateral="open")
    with pytest.raises(InputError, match=r"\[relaxation\] hold = -1"):
        builtin_scene("relaxation").with_overrides(hold=-1.0)


def test_relaxation_against_reference():
    """Hold 30 s (tau3 = 10 s): the reaction force against the uniaxial driver and stress_history."""
    sc = builtin_scene("relaxation").with_overrides(output_rate=10.0)
    m = build_model(sc)
    rx = sc.relaxation
    r = get_backend("skfem").run(m, frame_interval=1e-9)  # a frame every step
    assert r.t[-1] == pytest.approx(rx.load_time + rx.hold) and r.steps < 1000
    # 1) the uniaxial driver (independent lateral solution) at the common times
    tu, _, P, _ = uniaxial(m.material, abs(rx.stretch - 1) / rx.load_time, rx.stretch, steps=50, hold=rx.hold)
    Ru = P * rx.size ** 2
    for tc in (rx.load_time, rx.load_time + rx.hold / 2, rx.load_time + rx.hold):
        i, j = np.argmin(np.abs(r.t - tc)), np.argmin(np.abs(tu - tc))
        if abs(r.t[i] - tu[j]) < 1e-12:
            assert abs(r.reaction_force[i] - Ru[j]) < 1e-3 * np.abs(Ru).max()
    # 2) stress_history along the element's own (homogeneous) deformation, every recorded time
    t = np.array([f[0] for f in r.frames])
    u = np.array([f[1] for f in r.frames])
    top_corner = int(np.argmax(m.nodes.sum(axis=1)))
    F = np.zeros((t.size, 3, 3))
    for k in range(3):
        F[:, k, k] = 1.0 + u[:, top_corner, k] / rx.size
    sig = ref.stress_history(m.material, t, F)
    force = sig[:, 2, 2] * F[:, 0, 0] * F[:, 1, 1] * rx.size ** 2
    R = np.interp(t, r.t, r.reaction_force)
    assert np.abs(R - force).max() < 1e-3 * np.abs(force).max()
    assert np.abs(sig[:, 0, 0]).max() < 1e-6 * np.abs(sig[:, 2, 2]).max()  # lateral faces free
    peak = r.reaction_force[np.argmin(np.abs(r.t - rx.load_time))]
    assert 0.02 < r.reaction_force[-1] / peak < 0.05  # relaxes towards gamma_inf ~ 0.021


def test_newton_failure_is_a_numerical_error():
    m = build_model(builtin_scene("single-element"))
    with pytest.raises(NumericalError) as err:
        get_backend("skfem").run(m, quasi_static=True, max_iterations=1, dt=m.end_time,
                                 dt_min=m.end_time / 4, segment_steps=1)
    e = err.value
    assert e.time is not None and 0 < e.time <= m.end_time and e.quantity
    assert "t = " in str(e) and "dt" in str(e)


def test_inversion_is_a_numerical_error():
    from cfm_core.scene.model import Model, Prescribed

    m0 = build_model(builtin_scene("single-element"))
    m = Model(name="crush", nodes=m0.nodes, hexes=m0.hexes, density=0.0, material=m0.material,
              end_time=1e-3, output_interval=1e-3, fixed_dofs=m0.fixed_dofs,
              prescribed=Prescribed(m0.prescribed.nodes, 2, np.array([0.0, 1e-3]), np.array([0.0, -1.2e-3])),
              meta={"quasi_static": True})
    with pytest.raises(NumericalError) as err:
        get_backend("skfem").run(m, segment_steps=1, dt_min=1e-4)
    e = err.value  # the CFM stiffens without bound: Newton diverges (or J <= 0) at the smallest step
    assert e.time is not None and e.element == 0 and "element 0" in str(e) and e.quantity in ("J", "Newton residual")


def test_an_overflowing_fibre_term_is_named_when_the_step_fails():
    """k2 = 1e12 (relaxation, 30 % compression): the fibre exponential overflows at the first trial steps and
    the forces of the steps after reach 1e167 N; the run stopped with "non-finite residual" alone. Now the
    failure names the overflow of the forces and the term that overflowed, with its time, and the error's
    element and quantity are those of the overflow (as the numba backend reports it)."""
    m = build_model(builtin_scene("relaxation").with_overrides(parameters={"k2": 1e12}))
    with pytest.raises(NumericalError) as err:
        get_backend("skfem").run(m)
    text, e = str(err.value), err.value
    assert "the forces overflow float64" in text and "The cause: the material's energy overflows" in text
    assert "isochoric term 'circular-fibers' of material 'cfm' has a non-finite energy" in text and "k2 = 1e+12" in text
    assert "exp overflows above an argument of 709" in text
    assert e.quantity == "non-finite energy derivative of material 'cfm'" and e.element == 0 and 0.0 < e.time < 1e-6


def test_a_collapsed_time_step_names_the_overflowing_term():
    """k2 = 1e9 on the coarse drop test: 240 rejected steps, 14 of them on the fibre exponential beyond
    exp(709), and the run stopped with "the time step collapsed ... (an element folding, contact chattering,
    or a material far out of its range)". numba names the term; so does skfem now."""
    sc = builtin_scene("drop-test").with_overrides(thickness=0.005, width=0.02, element_size=0.0025,
                                                   parameters={"k2": 1e9})
    with pytest.raises(NumericalError, match=r"the time step collapsed at t = .*the material's energy overflows: "
                                             r"\d+ step\(s\) were rejected") as err:
        get_backend("skfem").run(build_model(sc))
    text = str(err.value)
    assert "isochoric term 'circular-fibers'" in text and "k2 = 1e+09" in text and "element folding" not in text
    assert err.value.quantity == "non-finite energy derivative of material 'cfm'" and err.value.element is not None


def test_forces_whose_squares_overflow_are_named_not_a_bare_non_finite_residual():
    """neo-Hookean mu = 1e306 Pa: forces of 7e291 N, finite, but the residual norm (their squares) is inf."""
    m = build_model(builtin_scene("single-element").with_overrides(material="neo-hookean", parameters={"mu": 1e306}))
    with pytest.raises(NumericalError, match=r"non-finite residual: the forces overflow float64 \(the largest "
                                             r"residual .* N in element 0, internal forces up to .*e\+291 N") as err:
        get_backend("skfem").run(m)
    assert err.value.quantity == "residual overflow" and err.value.element == 0


def test_stiff_fibres_in_compression_complete_and_match_the_uniaxial_truth():
    """k2 = 1e5 at stretch 0.5: numba's explicit step collapses (the stable step falls 1e4-fold as the fibres
    lock), while skfem completes. Its result is the model's: the fibres hold the isochoric stretches, the
    volume goes (J = 0.13) and the Ogden term carries -3.9e13 Pa, which the independent uniaxial-stress
    solution of the point driver gives too (the rest: the element's inertia at 100 1/s)."""
    sc = builtin_scene("single-element").with_overrides(parameters={"k2": 1e5})
    m = build_model(sc)
    r = get_backend("skfem").run(m)
    _, lam, P, lat = uniaxial(m.material, sc.element.rate, sc.element.stretch, steps=200)
    assert (lam * lat**2)[-1] == pytest.approx(0.131, abs=1e-3)
    nominal = r.reaction_force / sc.element.size ** 2
    assert nominal[-1] == pytest.approx(P[-1], rel=1e-5)
    for s in (0.9, 0.7, 0.6):
        i, j = np.argmin(np.abs(lam - s)), np.argmin(np.abs(1.0 + (r.t / m.end_time) * (sc.element.stretch - 1) - s))
        assert nominal[j] == pytest.approx(P[i], rel=2e-2)
