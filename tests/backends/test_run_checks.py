"""The same physics checks on every backend (cfm_core.simulation.checks): an impactor far too heavy
(the 220 g written as 220, read as kg; warned about before running by cfm_core.scene.plausible)
stops the run with a NumericalError naming node or element, time and
quantity; the paper's kind of drop test passes them without warnings, and the checks do
not change a single number of the result."""

import json

import numpy as np
import pytest

from cfm_core.cli import main
from cfm_core.errors import NumericalError
from cfm_core.runs import drop_test
from cfm_core.runs.pipeline import run_model
from cfm_core.scene.builder import build_model
from cfm_core.scene import builtin_scene
from cfm_core.simulation import checks

BACKENDS = ["numba", "torch", "skfem"]
QUANTITIES = {"penetration of the rigid plate", "penetration of the rigid impactor", "symmetry plane crossed",
              "bottoming out", "corner Jacobian", "contact at the end time"}


def coarse(**kw):
    """Quarter of a 20 x 20 x 5 mm specimen, 2.5 mm hexahedra (32 elements)."""
    return builtin_scene("drop-test").with_overrides(width=0.02, thickness=0.005, element_size=0.0025, **kw)


def _available(name):
    pytest.importorskip({"numba": "numba", "torch": "torch", "skfem": "skfem"}[name])


@pytest.mark.parametrize("backend", [pytest.param(b, marks=pytest.mark.slow) if b == "skfem" else b for b in BACKENDS])
def test_an_impactor_of_220_kg_stops_the_run_on_every_backend(backend):
    """skfem's run (~2 min: the implicit solver bottoming out step by step) is a --runslow study."""
    _available(backend)
    with pytest.raises(NumericalError) as err:
        run_model(build_model(coarse(mass=220.0, end_time=0.006)), backend)
    e = err.value
    assert e.quantity in QUANTITIES, str(e)
    assert e.time is not None and 0.0 < e.time <= 0.006
    assert (getattr(e, "node", None) is not None or e.element is not None or e.quantity == "bottoming out")
    assert "t = " in str(e)


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_checks_pass_a_paper_drop_test_and_change_no_number(backend, monkeypatch):
    _available(backend)
    # the first 2 ms of the 5 mm test (1 ms on the slower implicit backend): still in contact at the end
    scene = coarse(end_time=0.001 if backend == "skfem" else 0.002)
    checked = drop_test(scene, backend)
    assert checked.result.info["checks"]["monitor_calls"] >= 10  # every ~1 % of the end time (or step)
    w = checked.summary["warnings"]
    assert len(w) == 1 and "still in contact" in w[0]  # a chosen end time: warned, not stopped
    monkeypatch.setattr(checks.Monitor, "inspect", lambda self, *a, **k: None)  # same schedule, no checks
    unchecked = drop_test(scene, backend)
    for name in ("t", "contact_force", "impactor_z", "impulse"):
        np.testing.assert_array_equal(getattr(checked.result, name), getattr(unchecked.result, name))
    for name, e in checked.result.energies.items():
        np.testing.assert_array_equal(e, unchecked.result.energies[name])


def test_the_full_coarse_drop_test_passes_every_check_without_warnings():
    pytest.importorskip("numba")
    oc = drop_test(coarse(), "numba")
    assert oc.summary["warnings"] == []
    info = oc.result.info["checks"]
    assert info["worst_plate"] <= 1e-12 and info["worst_symmetry"] == 0.0
    assert 0.5 < info["worst_corner_jacobian_ratio"] < 1.0


def test_cli_exit_3_and_no_summary_for_mass_in_grams(tmp_path, capsys):
    """The 220 g written as 220: a warning naming the likely slip before the run, then the run
    checks stop it (exit 3, no summary.json; shared case units-mass-in-grams: no successful
    non-physical run)."""
    pytest.importorskip("numba")
    scene = tmp_path / "scene.toml"
    scene.write_text('[scene]\ntype = "drop-test"\nend_time = 0.006\n[specimen]\nwidth = 0.02\nthickness = 0.005\n'
                     'element_size = 0.0025\n[impactor]\nmass = 220.0\n')
    out = tmp_path / "out"
    assert main(["drop-test", "--scene", str(scene), "--out", str(out), "--quiet", "--no-plot"]) == 3
    err = capsys.readouterr().err
    assert "warning: [impactor] mass = 220 kg" in err and "did you mean 0.22 kg (220 g)?" in err
    assert "numerical failure" in err and "t = " in err and "Traceback" not in err
    assert not (out / "summary.json").exists()


def test_cli_warnings_reach_summary_json_and_stderr(tmp_path, capsys):
    pytest.importorskip("numba")
    out = tmp_path / "out"
    scene = tmp_path / "scene.toml"
    scene.write_text('[scene]\ntype = "drop-test"\nend_time = 0.002\n[specimen]\nwidth = 0.02\nthickness = 0.005\n'
                     'element_size = 0.0025\n')
    assert main(["drop-test", "--scene", str(scene), "--out", str(out), "--quiet", "--no-plot"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["warnings"]) == 1 and "still in contact" in summary["warnings"][0]
    assert "warning: the run ended at its end time" in capsys.readouterr().err


def test_automatic_end_time_ending_in_contact_is_an_error(monkeypatch):
    """A run whose automatic end time passes while in contact never came back: exit 3, not a summary."""
    pytest.importorskip("numba")
    scene = coarse()
    from cfm_core.scene import builder

    original = builder.build_model

    def short(scene, material=None):  # the automatic end time, made too short to see separation
        m = original(scene, material)
        return type(m)(**{**m.__dict__, "end_time": 0.002})

    monkeypatch.setattr("cfm_core.runs.pipeline.build_model", short)
    with pytest.raises(NumericalError, match="still in contact") as err:
        drop_test(scene, "numba")
    assert err.value.quantity == "contact at the end time"


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_scenes_penetration_tolerance_reaches_every_backends_monitor(backend, tmp_path):
    """[scene] penetration_tolerance read from the file decides the verdict in the run itself: with 2.4 mm an
    impactor that crushes the 5 mm specimen is "bottomed out" once its lowest point comes within 2.4 mm of the
    plate, where the default tolerance (5 % of the edge, 0.125 mm) lets it go on (a tolerance of half the
    specimen's height or more is refused: test_value_edges)."""
    import re

    _available(backend)
    from cfm_core.scene.scene import load_scene

    path = tmp_path / "scene.toml"
    path.write_text('[scene]\ntype = "drop-test"\nend_time = 0.003\npenetration_tolerance = 0.0024\n'
                    '[specimen]\nwidth = 0.02\nthickness = 0.005\nelement_size = 0.0025\n'
                    '[impactor]\nmass = 5.0\nvelocity = 5.0\n', encoding="utf-8")
    scene = load_scene(path)
    assert build_model(scene).meta["checks"]["penetration_tolerance"] == 0.0024
    with pytest.raises(NumericalError, match="reached the rigid plate") as err:
        drop_test(scene, backend)
    assert err.value.quantity == "bottoming out"
    height = float(re.search(r"lowest point (?:is|came within) ([\d.]+) mm", str(err.value)).group(1))
    assert 1.0 < height <= 2.4


def test_a_collapsing_implicit_step_stops_the_run_with_its_time(monkeypatch):
    """skfem accepted ever smaller steps without limit: kappa = 100 Pa (nu = -0.99) on the coarse drop test
    took 1e-8 s steps (1000 in 50 s, 85 ms to go) for as long as anyone waited, with no message. Now a run
    whose last STALL_STEPS steps advanced less than STALL_FRACTION of its end time stops (exit 3) naming
    the time (that case: 26 s, naming the node behind the plate found first). Here the thresholds are
    tightened so that an ordinary run trips them."""
    pytest.importorskip("skfem")
    from cfm_backends.skfem_implicit import solver
    from cfm_core.errors import NumericalError
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import builtin_scene
    from cfm_core.simulation.registry import get_backend

    monkeypatch.setattr(solver, "STALL_STEPS", 5)
    monkeypatch.setattr(solver, "STALL_FRACTION", 0.9)
    model = build_model(builtin_scene("single-element"))
    with pytest.raises(NumericalError, match=r"the time step collapsed at t = .* the last 5 steps advanced") as err:
        get_backend("skfem").run(model)
    assert err.value.quantity == "time step" and err.value.time > 0.0


def test_a_relaxation_crushed_to_two_percent_of_its_volume_warns_with_the_point_drivers_j():
    """Compression to a stretch of 0.05: the circular fibres hold the lateral expansion back and the volume
    goes instead (J = 0.02, 7e15 N on a 1 mm element), which finished with exit 0 and no warning. Now the
    run warns, and its smallest J is the point driver's (independent: the reference's uniaxial solution)."""
    from cfm_core.simulation.point import uniaxial

    _available("skfem")
    sc = builtin_scene("relaxation").with_overrides(stretch=0.05, hold=0.005)
    res = run_model(build_model(sc), "skfem")
    (w,) = [w for w in res.info["warnings"] if "volume gone" in w]
    with pytest.warns(RuntimeWarning, match="volume gone"):
        _, lam, _, lat = uniaxial(build_model(sc).material, 100.0, 0.05, steps=200)
    J_truth = float((lam * lat**2).min())
    J_min = res.info["checks"]["volume_ratio"]["min"]
    assert J_min == pytest.approx(J_truth, rel=1e-2), (J_min, J_truth)
    assert "element 0 reached J = 0.4" in w and "below 0.5" in w


@pytest.mark.parametrize("scene, backend", [("relaxation", "skfem"), ("single-element", "numba"),
                                            ("single-element", "torch")])
def test_a_homogeneous_scene_pulled_into_the_nonconvex_volumetric_range_warns(scene, backend):
    """k2 = 10 pulled to stretch 2.5: the point driver warns from stretch 1.77 (J = 1.29) and reaches J = 3.61;
    the relaxation (skfem) and single-element (numba, torch) runs followed the same state and finished with
    no warning. Now they warn naming element 0, the time and J; J = 3.61 is the point driver's (independent:
    the uniaxial-stress solution of the reference material)."""
    from cfm_core.simulation.point import uniaxial

    _available(backend)
    sc = builtin_scene(scene).with_overrides(stretch=2.5, elastic=True, parameters={"k2": 10.0},
                                             **({"hold": 0.005} if scene == "relaxation" else {}))
    res = run_model(build_model(sc), backend)
    (w,) = [w for w in res.info["warnings"] if "not convex" in w]
    with pytest.warns(RuntimeWarning, match="not convex"):
        _, lam, _, lat = uniaxial(build_model(sc).material, 100.0, 2.5, steps=200)
    J_truth = float((lam * lat**2)[-1])
    assert "element 0 reached J = 1.3" in w and "volumetric energy of material 'cfm' is not convex" in w
    J_end = res.info["checks"]["volume_ratio"]["max"]
    assert J_end == pytest.approx(J_truth, rel=2e-3), (J_end, J_truth)


def test_a_straight_impact_through_a_coarse_mesh_is_told_to_refine_not_to_lower_an_angle(tmp_path, capsys):
    """A 0.4 mm specimen of 10 mm elements: the hemisphere passed between the top nodes to the plate, and the
    stop said "an oblique impact at this angle slides off the specimen; give a smaller angle" with no angle
    given. A straight impact names the node spacing against the radius."""
    import meshio

    from cfm_core.scene.mesh import structured_hex_mesh

    nodes, hexes = structured_hex_mesh(0.05, 0.05, 0.0004, 5, 5, 1)
    nodes[:, :2] -= 0.025
    meshio.write(tmp_path / "thin.vtu", meshio.Mesh(nodes, [("hexahedron", hexes)]))
    assert main(["drop-test", "--mesh", str(tmp_path / "thin.vtu"), "--no-plot", "--quiet",
                 "--out", str(tmp_path / "o")]) == 3
    err = capsys.readouterr().err
    assert "the impactor passed between the specimen's nodes" in err
    assert "top-surface nodes up to 10 mm apart against an impactor radius of 55 mm); refine the mesh" in err
    assert "angle" not in err


def test_a_failure_in_a_run_whose_steps_move_the_impactor_far_advises_a_smaller_step(tmp_path, capsys):
    """30 m/s on 2 mm elements: the first stable step (3.8e-5 s, from the wave speed) moves the impactor 1.1 mm,
    an element inverted at 41 us, and the message said only to refine the mesh."""
    from cfm_backends.explicit.errors import fast_impact

    args = ["drop-test", "--thickness", "0.004", "--element-size", "0.002", "--width", "0.02", "--no-plot",
            "--quiet"]
    assert main([*args, "--velocity", "30", "--out", str(tmp_path / "o")]) == 3
    err = capsys.readouterr().err
    assert "At 30 m/s the impactor moves 1.1" in err and "% of the smallest element (2 mm" in err
    assert "--option dt_max=1.3e-06" in err
    model = build_model(builtin_scene("drop-test").with_overrides(element_size=0.002, thickness=0.004, width=0.02))
    assert fast_impact(model, 1e-5) == ""             # 1 m/s: 10 um per step, 0.5 % of an element
    assert "a fiftieth of an element per step" in fast_impact(model, 2e-4)
    assert fast_impact(model, 0.0) == ""               # the first step not known
