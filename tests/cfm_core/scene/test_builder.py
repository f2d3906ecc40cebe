"""Tests of cfm_core.scene.builder: scene -> Model geometry, node sets, symmetry, prescribed motion.

Geometry tests pass a stand-in material (build_model(scene, material=...)) so that they do not
depend on the material registry; two tests at the end use the real cfm_core.material.
"""

import meshio
import numpy as np
import pytest

from cfm_core.scene.builder import build_model
from cfm_core.scene.mesh import element_volumes, hex_jacobians, structured_hex_mesh
from cfm_core.scene.model import Model, RigidPlane
from cfm_core.scene.scene import builtin_scene

MAT = object()  # stand-in: the builder only stores it


def drop(**kw):
    return build_model(builtin_scene("drop-test").with_overrides(**kw), material=MAT)


def test_quarter_drop_test_geometry():
    m = drop()
    assert isinstance(m, Model) and m.material is MAT
    assert m.n_elements == 25 * 25 * 8 and m.n_nodes == 26 * 26 * 9
    assert m.nodes.min(axis=0).tolist() == [0.0, 0.0, 0.0]
    np.testing.assert_allclose(m.nodes.max(axis=0), [0.025, 0.025, 0.008], rtol=1e-15)
    assert np.all(hex_jacobians(m.nodes, m.hexes) > 0)
    assert element_volumes(m.nodes, m.hexes).sum() == pytest.approx(0.025 * 0.025 * 0.008, rel=1e-12)
    assert m.density == 950.0 and m.prescribed is None


def test_quarter_node_sets_and_symmetry():
    m = drop()
    top, bottom = m.sphere_nodes, m.plane_nodes
    assert len(top) == 26 * 26 and np.all(m.nodes[top, 2] == 0.008)
    assert len(bottom) == 26 * 26 and np.all(m.nodes[bottom, 2] == 0.0)
    assert np.sum(np.isclose(m.nodes[:, 2], 0.008)) == len(top)
    fixed = m.fixed_dofs
    assert fixed.shape == (2 * 26 * 9, 2) and fixed.dtype == np.int64
    xs, ys = fixed[fixed[:, 1] == 0, 0], fixed[fixed[:, 1] == 1, 0]
    assert set(fixed[:, 1]) == {0, 1}  # no z constraint: the plate is a contact
    assert np.all(m.nodes[xs, 0] == 0.0) and len(xs) == 26 * 9
    assert np.all(m.nodes[ys, 1] == 0.0) and len(ys) == 26 * 9
    assert m.symmetry_factor == 4.0


def test_sphere_touches_and_carries_quarter_mass():
    m = drop(thickness=0.006, velocity=1.5)
    s = m.sphere
    assert s.center == (0.0, 0.0, 0.006 + 0.055) and s.radius == 0.055
    assert s.velocity == -1.5 and s.mass == pytest.approx(0.22 / 4) and m.mass_full == 0.22
    dist = np.linalg.norm(m.nodes[m.sphere_nodes] - np.array(s.center), axis=1)
    assert dist.min() == pytest.approx(0.055, abs=1e-15)  # touching at the origin node
    assert np.all(dist >= 0.055 - 1e-15)  # no node inside the sphere at t = 0
    assert m.plane == RigidPlane(0.0)
    assert m.end_time == pytest.approx(10 * 0.006 / 1.5 + 5e-3)
    assert m.output_interval == pytest.approx(1 / 50_000) and m.stop_after_separation


def test_full_model_is_four_quarters():
    for kw in [{}, {"thickness": 0.0048, "width": 0.05}, {"width": 0.025, "element_size": 0.002}]:
        q, f = drop(**kw), drop(symmetry="none", **kw)
        assert f.n_elements == 4 * q.n_elements
        assert f.symmetry_factor == 1.0 and f.sphere.mass == f.mass_full == 0.22
        assert len(f.fixed_dofs) == 0
        vq, vf = element_volumes(q.nodes, q.hexes).sum(), element_volumes(f.nodes, f.hexes).sum()
        assert vf == pytest.approx(4 * vq, rel=1e-12)
        # the full grid is the mirrored quarter grid: same x >= 0, y >= 0 nodes, centre lines at 0
        sel = (f.nodes[:, 0] >= 0) & (f.nodes[:, 1] >= 0)
        assert set(map(tuple, f.nodes[sel])) == set(map(tuple, q.nodes))
        np.testing.assert_array_equal(np.sort(f.nodes[:, 0]), np.sort(-f.nodes[:, 0]))
        assert np.all(hex_jacobians(f.nodes, f.hexes) > 0)


def test_thickness_layers_and_meta():
    m = drop(thickness=0.0048)
    assert len(np.unique(m.nodes[:, 2])) == 6  # round(4.8) = 5 layers
    meta = m.meta
    assert meta["thickness"] == 0.0048 and meta["width"] == 0.05 and meta["element_size"] == 0.001
    assert meta["velocity"] == 1.0 and meta["impactor_mass"] == 0.22
    assert meta["impactor_radius"] == 0.055
    assert meta["scene_type"] == "drop-test" and meta["symmetry"] == "quarter"
    assert m.name == "drop-test"


def test_friction_and_end_time_passed_through():
    m = drop(friction=0.3, end_time=0.02, output_rate=10_000.0)
    assert m.friction == 0.3 and m.end_time == 0.02 and m.output_interval == pytest.approx(1e-4)


def test_user_mesh(tmp_path):
    nodes, hexes = structured_hex_mesh(0.03, 0.03, 0.005, 6, 6, 3, origin=(-0.015, -0.015, 0))
    path = tmp_path / "full.vtu"
    meshio.write(path, meshio.Mesh(nodes, [("hexahedron", hexes)]))
    m = drop(mesh=str(path), symmetry="none")
    np.testing.assert_allclose(m.nodes, nodes)
    np.testing.assert_array_equal(m.hexes, hexes)
    assert len(m.sphere_nodes) == 49 and len(m.plane_nodes) == 49
    assert m.sphere.center[2] == pytest.approx(0.005 + 0.055)
    m.nodes[0, 0] = 1.0  # the model owns a copy; the cached mesh is unchanged
    assert drop(mesh=str(path), symmetry="none").nodes[0, 0] == nodes[0, 0]


def single(**kw):
    return build_model(builtin_scene("single-element").with_overrides(**kw), material=MAT)


def test_single_element():
    m = single(size=0.002, stretch=0.5, rate=50.0)
    assert m.n_elements == 1 and m.n_nodes == 8
    assert m.sphere is None and m.plane is None and len(m.sphere_nodes) == 0
    assert np.all(hex_jacobians(m.nodes, m.hexes) > 0)
    fixed = {tuple(r) for r in m.fixed_dofs.tolist()}
    bottom = {n for n in range(8) if m.nodes[n, 2] == 0}
    assert {(n, 2) for n in bottom} <= fixed
    assert {(n, 0) for n in range(8) if m.nodes[n, 0] == 0} <= fixed
    assert {(n, 1) for n in range(8) if m.nodes[n, 1] == 0} <= fixed
    assert len(fixed) == 4 + 4 + 4  # nothing else: lateral faces free, top moves
    p = m.prescribed
    assert p.dof == 2 and sorted(p.nodes.tolist()) == [n for n in range(8) if m.nodes[n, 2] == 0.002]
    t_load = 0.5 / 50.0
    np.testing.assert_allclose(p.times, [0.0, t_load])
    np.testing.assert_allclose(p.values, [0.0, -0.001])
    assert m.end_time == pytest.approx(t_load)
    assert p.velocity(t_load / 2) == pytest.approx(-0.001 / t_load)


def test_single_element_hold_and_tension():
    m = single(stretch=1.2, rate=10.0, hold=0.5)
    p = m.prescribed
    np.testing.assert_allclose(p.times, [0.0, 0.02, 0.52])
    np.testing.assert_allclose(p.values, [0.0, 0.0002, 0.0002])
    assert m.end_time == pytest.approx(0.52) and p.velocity(0.3) == 0.0
    assert m.meta["scene_type"] == "single-element" and m.meta["stretch"] == 1.2


def test_builder_calls_make_material(monkeypatch):
    from cfm_core.scene import builder

    calls = []
    monkeypatch.setattr(builder, "make_material", lambda *a: calls.append(a) or "bound")
    scene = builtin_scene("drop-test").with_overrides(material="neo-hookean", elastic=True,
                                                      moduli="instantaneous", parameters={"c": 5.0})
    assert build_model(scene).material == "bound"
    assert calls == [("neo-hookean", {"c": 5.0}, "instantaneous", True)]


def test_builder_with_registered_cfm():
    m = build_model(builtin_scene("single-element"))
    assert m.material is not None and m.n_elements == 1
