"""Run checks (cfm_core.simulation.checks) on hand-built states: each violation is constructed
geometrically (a node moved behind the plate, into the sphere, across a symmetry plane, a corner
pushed through its element), so the truth is known without running a solver."""

import math

import numpy as np
import pytest

from cfm_core.errors import NumericalError
from cfm_core.scene.mesh import structured_hex_mesh
from cfm_core.scene.model import Model, Prescribed, RigidPlane, RigidSphere
from cfm_core.simulation import checks
from cfm_core.simulation.result import Result

H = 1e-3  # element edge (m)


def quarter_block(n=2, **meta):
    """2 x 2 x 2 block of 1 mm cubes on the plate z = 0, symmetry planes x = 0 and y = 0, sphere touching."""
    nodes, hexes = structured_hex_mesh(n * H, n * H, n * H, n, n, n)
    fixed = [(i, 0) for i in np.flatnonzero(nodes[:, 0] == 0)] + [(i, 1) for i in np.flatnonzero(nodes[:, 1] == 0)]
    R = 0.05
    return Model(name="block", nodes=nodes, hexes=hexes, density=950.0, material=None, end_time=1e-2,
                 output_interval=2e-5, fixed_dofs=np.array(fixed), plane=RigidPlane(0.0),
                 sphere=RigidSphere(R, 0.055, (0.0, 0.0, n * H + R), -1.0), meta=dict(meta))


def test_the_reference_state_passes_and_the_tolerance_is_5_percent_of_the_smallest_edge():
    m = quarter_block()
    mon = checks.Monitor(m)
    assert mon.tol == pytest.approx(0.05 * H)
    assert mon.planes == [(0, 0.0, 1.0), (1, 0.0, 1.0)]
    mon.final(0.0, m.nodes.copy(), m.sphere.center[2])
    assert mon.report()["worst_corner_jacobian_ratio"] == pytest.approx(1.0)


@pytest.mark.parametrize("axis, shift, quantity", [
    (2, -0.2 * H, "penetration of the rigid plate"),      # a bottom node 0.2 mm below z = 0
    (0, -0.2 * H, "symmetry plane crossed"),              # a node on x = 0 moved to x = -0.2 mm
    (1, -0.2 * H, "symmetry plane crossed"),
])
def test_a_node_behind_a_surface_stops_the_run_naming_node_time_and_quantity(axis, shift, quantity):
    m = quarter_block()
    x = m.nodes.copy()
    node = int(np.flatnonzero((m.nodes == 0).all(axis=1))[0])  # the corner node at the origin
    x[node, axis] += shift
    with pytest.raises(NumericalError, match=f"node {node} ") as err:
        checks.Monitor(m).check(1.5e-3, x, m.sphere.center[2])
    assert err.value.quantity == quantity and err.value.time == 1.5e-3 and err.value.node == node


def test_within_the_tolerance_passes():
    m = quarter_block()
    x = m.nodes.copy()
    x[0, 2] -= 0.04 * H  # 4 % of the edge: inside the 5 % tolerance (skfem's penalty contact)
    checks.Monitor(m).check(1e-3, x, m.sphere.center[2])


def test_a_node_inside_the_sphere_stops_the_run():
    m = quarter_block()
    x = m.nodes.copy()
    top = int(np.argmax(m.nodes[:, 2] - 1e-3 * np.linalg.norm(m.nodes[:, :2], axis=1)))  # top node on the axis
    x[top, 2] += 0.3 * H  # 0.3 mm above the top: inside the touching sphere
    with pytest.raises(NumericalError, match="inside the rigid impactor") as err:
        checks.Monitor(m).check(2e-3, x, m.sphere.center[2])
    assert err.value.node == top


def test_the_impactor_reaching_the_plate_is_bottoming_out():
    m = quarter_block()
    x = m.nodes.copy()
    x[:, 2] *= 0.01  # specimen squashed flat (no node inside the sphere below)
    z = m.sphere.radius + 0.02 * H  # sphere's lowest point 0.02 mm above the plate
    with pytest.raises(NumericalError, match="reached the rigid plate") as err:
        checks.Monitor(m).check(3e-3, x, z)
    assert err.value.quantity == "bottoming out"


def test_a_folded_corner_is_found_although_the_centre_jacobian_is_positive():
    nodes, hexes = structured_hex_mesh(H, H, H, 1, 1, 1)
    m = Model(name="one", nodes=nodes, hexes=hexes, density=950.0, material=None, end_time=1e-3,
              output_interval=1e-4)
    x = nodes.copy()
    top_corner = hexes[0, 6]  # local corner 6 = (+1, +1, +1)
    x[top_corner] = [0.3 * H, 0.3 * H, 0.3 * H]  # pushed through the element towards corner 0
    from cfm_core.scene.mesh import hex_jacobians
    centre = hex_jacobians(x, hexes, np.zeros((1, 3)))[0, 0]
    assert centre > 0  # the explicit solvers' one-point check sees nothing
    with pytest.raises(NumericalError, match="element 0 is folded") as err:
        checks.Monitor(m).check(5e-4, x)
    assert err.value.element == 0 and err.value.quantity == "corner Jacobian"


def test_the_monitor_is_due_about_every_percent_of_the_end_time():
    mon = checks.Monitor(quarter_block())
    seen = []
    for t in np.arange(0.0, 1e-2, 1e-5):
        if mon.due(t):
            seen.append(t)
            mon.check(t, mon.model.nodes, mon.model.sphere.center[2])
    assert 95 <= len(seen) <= 100


def _result(t, force, ke, ie, hg=None, ext=None, z=None):
    n = t.size
    zeros = np.zeros(n)
    return Result(t=t, backend="test", steps=n, wall_time=0.0, contact_force=force,
                  impactor_z=z if z is not None else np.full(n, 1.0),
                  energies={"kinetic": ke, "internal": ie, "hourglass": zeros if hg is None else hg,
                            "contact": zeros, "external": zeros if ext is None else ext})


def test_hourglass_and_energy_balance_warn_above_10_and_1_percent_and_stop_above_their_limits():
    m = quarter_block()
    t = np.linspace(0.0, 5e-3, 51)
    ke = 0.11 * np.cos(np.pi * t / 1e-2) ** 2
    ie = 0.11 - ke
    force = np.where(t < 4e-3, 1.0, 0.0)
    ok = _result(t, force, ke, 0.95 * ie, hg=0.05 * ie)  # hourglass 5.3 % of internal, balanced
    assert checks.check_result(m, ok) == []
    bad = _result(t, force, ke, 0.8 * ie, hg=0.2 * ie)  # hourglass 25 % of internal, balanced
    w = checks.check_result(m, bad)
    assert len(w) == 1 and "hourglass energy is 25 %" in w[0]
    leak = _result(t, force, ke, 0.97 * ie)  # 3 % of the energy lost
    w = checks.check_result(m, leak)
    assert len(w) == 1 and "energy-balance error is 3" in w[0]
    strict = quarter_block(checks={"hourglass_limit": 0.2, "energy_limit": 0.02})
    with pytest.raises(NumericalError, match="hourglass_limit"):
        checks.check_result(strict, bad)
    with pytest.raises(NumericalError, match="energy_limit"):
        checks.check_result(strict, leak)


def test_ending_in_contact_stops_with_an_automatic_end_time_and_warns_with_a_chosen_one():
    t = np.linspace(0.0, 1e-2, 101)  # up to the model's end time
    ke = np.full(t.size, 0.1)
    res = _result(t, np.linspace(1.0, 5.0, t.size), ke, np.zeros(t.size))
    with pytest.raises(NumericalError, match="still in contact") as err:
        checks.check_result(quarter_block(end_time_automatic=True), res)
    assert err.value.quantity == "contact at the end time" and err.value.time == pytest.approx(1e-2)
    w = checks.check_result(quarter_block(end_time_automatic=False), res)
    assert len(w) == 1 and "still in contact" in w[0]
    separated = _result(t, np.where(t < 5e-3, 1.0, 0.0), ke, np.zeros(t.size))
    assert checks.check_result(quarter_block(end_time_automatic=True), separated) == []


def test_an_impact_whose_contact_spans_too_few_time_steps_is_warned():
    """A 10 ug impactor on a 4 mm specimen: 17 steps of 35 us for the whole run, and a contact of 0.42 ms
    (0.20 ms with 1 us steps) reported with exit 0. Fewer than 20 steps over the contact warn, naming both."""
    t = np.linspace(0.0, 6e-4, 31)                 # output samples, 20 us apart
    force = np.where(t <= 4.2e-4, 1.0 + t, 0.0)
    ke = np.full(t.size, 0.1)
    few = _result(t, force, ke, np.zeros(t.size))
    few.steps = 17                                 # 35.3 us per step: 11.9 steps over 0.42 ms of contact
    (w,) = checks.check_result(quarter_block(), few)
    assert "the impact is not resolved in time: its contact (0.42 ms) spans about 11.9 time steps of 3.53e-05 s" in w
    assert "dt_max" in w and "4.2e-06 s" in w
    fine = _result(t, force, ke, np.zeros(t.size))
    fine.steps = 600                               # 1 us per step
    assert checks.check_result(quarter_block(), fine) == []


def test_the_impactor_history_reaching_the_plate_stops_the_run():
    m = quarter_block()
    t = np.linspace(0.0, 5e-3, 51)
    z = m.sphere.radius + 2 * H - 1.0 * t  # 1 m/s through the 2 mm specimen: at the plate at 2 ms
    res = _result(t, np.where(t < 4e-3, 1.0, 0.0), np.full(t.size, 0.1), np.zeros(t.size), z=z)
    with pytest.raises(NumericalError, match="reached the rigid plate") as err:
        checks.check_result(m, res)
    assert err.value.time == pytest.approx(5e-3)  # the lowest point of the history


def test_single_element_inertia_warning():
    nodes, hexes = structured_hex_mesh(H, H, H, 1, 1, 1)
    top = np.flatnonzero(nodes[:, 2] > 0.5 * H)
    m = Model(name="se", nodes=nodes, hexes=hexes, density=950.0, material=None, end_time=5e-3,
              output_interval=1e-4, prescribed=Prescribed(top, 2, np.array([0.0, 5e-3]), np.array([0.0, -5e-4])),
              meta={"scene_type": "single-element"})
    t = np.linspace(0.0, 5e-3, 51)
    ie = 1e-3 * (t / 5e-3) ** 2
    quasi = _result(t, None, 1e-7 * np.ones(t.size), ie, ext=ie)  # the work done goes into internal energy
    assert checks.check_result(m, quasi) == []
    inertial = _result(t, None, 5e-6 * np.ones(t.size), ie, ext=ie)  # KE 0.5 % of IE
    w = checks.check_result(m, inertial)
    assert len(w) == 1 and "inertia matters" in w[0]


def test_too_low_output_rate_is_refused_before_running(monkeypatch):
    from cfm_core.errors import InputError
    from cfm_core.runs import drop_test, pipeline
    from cfm_core.scene import builtin_scene

    def never(*a, **k):
        raise AssertionError("the backend must not be started")

    monkeypatch.setattr(pipeline, "run_model", never)
    with pytest.raises(InputError, match=r"\[scene\] output_rate = 5000 Hz is too low.*6000 Hz"):
        drop_test(builtin_scene("drop-test").with_overrides(output_rate=5000.0), "numba")


SCENE_TOML = """[scene]
type = "drop-test"
{tolerance}
[specimen]
width = 0.005
thickness = 0.005
element_size = 0.0025
"""


def _scene_model(tmp_path, tolerance_line):
    """A drop-test model read from a scene file (2.5 mm elements: default tolerance 0.125 mm)."""
    from cfm_core.scene.builder import build_model
    from cfm_core.scene.scene import load_scene

    path = tmp_path / "scene.toml"
    path.write_text(SCENE_TOML.format(tolerance=tolerance_line), encoding="utf-8")
    return build_model(load_scene(path))


@pytest.mark.parametrize("line, verdict", [
    ("", "stop"),                                   # default: 5 % of 2.5 mm = 0.125 mm < 0.2 mm
    ("penetration_tolerance = 0.0003", "pass"),     # 0.3 mm from the scene: lets the 0.2 mm pass
    ("penetration_tolerance = 0.00025", "pass"),
    ("penetration_tolerance = 0.00015", "stop"),    # tighter than the depth: stops it
])
def test_the_scenes_penetration_tolerance_decides_the_verdict(tmp_path, line, verdict):
    """A bottom node 0.2 mm behind the plate: the [scene] penetration_tolerance read from the file,
    not the default, sets whether the monitor passes the state or stops the run."""
    m = _scene_model(tmp_path, line)
    x = m.nodes.copy()
    node = int(np.flatnonzero(np.isclose(m.nodes[:, 2], m.plane.z))[0])
    x[node, 2] -= 0.2e-3
    mon = checks.Monitor(m)
    expected = float(line.split("=")[1]) if line else 0.05 * 0.0025
    assert mon.tol == pytest.approx(expected) and mon.report()["tolerance"] == pytest.approx(expected)
    if verdict == "pass":
        mon.check(1e-3, x, m.sphere.center[2])
        assert mon.report()["worst_plate"] == pytest.approx(0.2e-3)
    else:
        with pytest.raises(NumericalError, match=f"tolerance {1e3 * expected:.4g} mm") as err:
            mon.check(1e-3, x, m.sphere.center[2])
        assert err.value.quantity == "penetration of the rigid plate" and err.value.node == node


@pytest.mark.parametrize("line, stops", [("", False), ("penetration_tolerance = 0.0024", True)])
def test_the_scenes_penetration_tolerance_sets_the_bottoming_out_gap(tmp_path, line, stops):
    """The end-of-run check reads the same tolerance: an impactor history whose lowest point comes down to
    2 mm above the plate passes by default and is bottoming out with a 2.4 mm tolerance."""
    m = _scene_model(tmp_path, line)
    t = np.linspace(0.0, 5e-3, 51)
    z = np.full(t.size, m.sphere.radius + m.plane.z + 0.002)
    res = _result(t, np.where(t < 4e-3, 1.0, 0.0), np.full(t.size, 0.1), np.zeros(t.size), z=z)
    if stops:
        with pytest.raises(NumericalError, match="reached the rigid plate"):
            checks.check_result(m, res)
    else:
        assert checks.check_result(m, res) == []


@pytest.mark.parametrize("shape,edge", [("hemisphere", 0.0), ("sphere", 0.0), ("flat", 2e-3), ("plane", 0.0)])
def test_the_box_the_monitor_searches_holds_every_point_inside_the_impactor(shape, edge):
    """impactor.bounds: every sampled point with a negative gap lies in the box, and the box is
    not loose (points inside the shape come within a fifth of the radius of each bounded face)."""
    from cfm_core.scene.impactor import bounds, gap

    rng = np.random.default_rng(7)
    c = np.array([1e-3, -2e-3, 5e-3])
    R = 10e-3
    pts = c + rng.uniform(-2.5 * R, 2.5 * R, size=(200_000, 3))
    g = gap(shape, R, edge, c, pts)[0]
    lo, hi = bounds(shape, R, c)
    inside = pts[g < 0.0]
    assert inside.shape[0] > 1000
    assert np.all((inside >= lo) & (inside <= hi))
    finite = np.isfinite(lo)
    assert np.allclose(inside.min(axis=0)[finite], lo[finite], atol=0.2 * R)
    finite = np.isfinite(hi)
    assert np.allclose(inside.max(axis=0)[finite], hi[finite], atol=0.2 * R)


def test_a_node_inside_the_impactor_far_from_the_others_is_found_by_the_searched_box():
    """The monitor searches only the impactor's box: a node moved into the sphere is still named."""
    nodes, hexes = structured_hex_mesh(0.02, 0.02, 0.008, 10, 10, 4)
    sph = RigidSphere(0.01, 0.22, (0.0, 0.0, 0.018), -1.0, shape="sphere")
    model = Model(name="box", nodes=nodes, hexes=hexes, density=950.0, material=None, end_time=1e-3,
                  output_interval=1e-4, sphere=sph)
    mon = checks.Monitor(model)
    x = nodes.copy()
    far = int(np.argmax(np.linalg.norm(nodes - np.array(sph.center), axis=1)))
    x[far] = np.array(sph.center) + np.array([0.0, 0.0, -0.009])   # 1 mm inside the sphere's surface
    with pytest.raises(NumericalError, match=rf"node {far} is 1 mm inside the rigid impactor"):
        mon.inspect(1e-4, x, sph.center[2])


def _one_element(scene_type="relaxation", material="cfm", **params):
    """A 1 mm cube with a 1 ms ramp then a 30 s hold (the relaxation scene's schedule) and a real material."""
    from cfm_core.material.registry import make_material

    nodes, hexes = structured_hex_mesh(H, H, H, 1, 1, 1)
    top = np.flatnonzero(nodes[:, 2] > 0.5 * H)
    return Model(name="one", nodes=nodes, hexes=hexes, density=0.0,
                 material=make_material(material, params, "long-term", True), end_time=30.001, output_interval=0.01,
                 prescribed=Prescribed(top, 2, np.array([0.0, 1e-3, 30.001]), np.array([0.0, 1.5 * H, 1.5 * H])),
                 meta={"scene_type": scene_type})


def _stretched(model, J, axial=2.5):
    """The reference nodes under F = diag(lt, lt, axial) with lt^2 axial = J (homogeneous)."""
    lt = math.sqrt(J / axial)
    return model.nodes @ np.diag([lt, lt, axial])


J_LIMIT = 10.0 ** (1.0 / 9.0)  # the Ogden term kappa/81 (9 ln J + J^-9 - 1): U'' = kappa/9 (10 J^-11 - J^-2) < 0 beyond


@pytest.mark.parametrize("scene_type", ["relaxation", "single-element"])
def test_a_homogeneous_scene_whose_j_leaves_the_convex_volumetric_range_warns_naming_time_and_j(scene_type):
    """A relaxation run of k2 = 10 pulled to stretch 2.5 ended at J = 3.6 (the point driver warns there:
    the Ogden term is not convex beyond J = 10^(1/9) = 1.29) with a summary and no warning. The monitor
    sees J at the element's centre; the threshold is the analytic one."""
    m = _one_element(scene_type)
    mon = checks.Monitor(m)
    for t, J in [(2e-4, 1.0), (4e-4, 0.999 * J_LIMIT), (6e-4, 1.001 * J_LIMIT), (1e-3, 2.6), (10.0, 2.4)]:
        mon.check(t, _stretched(m, J))
    rep = mon.report()["volume_ratio"]
    assert rep["max"] == pytest.approx(2.6, rel=1e-12)
    first = rep["nonconvex"]
    assert first["t"] == 6e-4 and first["t_before"] == 4e-4 and first["J"] == pytest.approx(1.001 * J_LIMIT)
    res = Result(t=np.array([0.0, 10.0]), backend="test", steps=2, wall_time=0.0, info={"checks": mon.report()})
    (w,) = checks.check_result(m, res)
    assert "element 0 reached J = 1.293 by t = 0.0006 s (the check before, at t = 0.0004 s, found none)" in w
    assert "volumetric energy of material 'cfm' is not convex" in w and "J reaches 2.6 in element 0 at t = 0.001 s" in w


def test_compression_to_j_0_09_is_convex_and_not_warned_about():
    """J = 0.09 in confined compression: U'' = kappa/9 (10 J^-11 - J^-2) > 0, the Ogden term is convex there
    (as everywhere below 1.29): no warning. A drop test (no homogeneous scene) is not followed."""
    m = _one_element()
    mon = checks.Monitor(m)
    mon.check(1e-3, m.nodes @ np.diag([1.0, 1.0, 0.09]))
    rep = mon.report()["volume_ratio"]
    assert rep["min"] == pytest.approx(0.09) and rep["max"] == 1.0 and rep["nonconvex"] is None
    assert "J = 0.09 (91 % of the volume gone)" in rep["crushed"]   # crushed, though convex
    assert "volume_ratio" not in checks.Monitor(quarter_block()).report()


def test_a_homogeneous_scene_crushed_below_half_its_volume_warns_naming_element_time_and_j():
    """Uniaxial compression to a stretch of 0.05 (relaxation on skfem) came out at J = 0.02 and 7e15 N on a
    1 mm element with no warning. The monitor names the first check below J = 0.5 and the smallest J."""
    m = _one_element("relaxation")
    mon = checks.Monitor(m)
    for t, J in [(2e-4, 0.9), (4e-4, 0.6), (6e-4, 0.45), (8e-4, 0.2), (1e-3, 0.3)]:
        mon.check(t, _stretched(m, J, axial=0.5))
    rep = mon.report()["volume_ratio"]
    assert rep["min"] == pytest.approx(0.2, rel=1e-12)
    res = Result(t=np.array([0.0, 10.0]), backend="test", steps=2, wall_time=0.0, info={"checks": mon.report()})
    (w,) = checks.check_result(m, res)
    assert "element 0 reached J = 0.45 by t = 0.0006 s (below 0.5)" in w
    assert "in element 0 at t = 0.0008 s, is J = 0.2 (80 % of the volume gone)" in w
    ok = checks.Monitor(m)
    ok.check(1e-3, _stretched(m, 0.55, axial=0.5))
    assert ok.report()["volume_ratio"]["crushed"] is None


def test_the_ramp_of_a_relaxation_is_checked_100_times():
    """The relaxation scene's 1 ms ramp lies before a 30 s hold: checks every 0.25 s (25 output intervals)
    would first see the ramp's end state at t = 0.25 s; during the ramp they come every 10 us."""
    mon = checks.Monitor(_one_element())
    seen = []
    for t in np.arange(0.0, 2e-3, 1e-6):
        if mon.due(t):
            seen.append(t)
            mon.check(t, mon.model.nodes)
    assert 95 <= len(seen) <= 110 and seen[0] == pytest.approx(1e-5, rel=0.2) and seen[-1] == pytest.approx(1e-3)
    assert mon.next == pytest.approx(0.25)   # after the ramp: the usual grid
