"""Fields, VTU output and mirroring of models with several parts and any impactor shape
(cfm_core.post.fields, part_state, impactor_mesh, vtu): each part's stress against the
material-point driver, the per-part Prony state, a written series read back, mirrored half and
quarter models symmetric to round-off, and the impactor surface of every shape on that shape."""

import dataclasses
import json
import re

import meshio
import numpy as np
import pytest

import cfm_core as cfm
from cfm_core import make_material
from cfm_core.material import kinematics as kin
from cfm_core.material import reference as ref
from cfm_core.material import prony
from cfm_core.post.fields import (DEFAULT_FIELDS, FIELDS, deformation_gradients, mean_gradients,
                                  model_cell_fields, part_prony_state, part_prony_states)
from cfm_core.post.vtu import write_field_series
from cfm_core.scene import build_model
from cfm_core.scene.impactor import gap
from cfm_core.scene.model import Part
from cfm_core.simulation import point as pt
from cfm_core.simulation.result import Result

SHAPES = ("hemisphere", "sphere", "flat", "plane")


def _two_parts(model):
    """The model with a neo-Hookean lower layer (no Prony terms) and a CFM upper layer (3 terms)."""
    zc = model.nodes[model.hexes].mean(axis=1)[:, 2]
    lower, upper = np.flatnonzero(zc < 0.002), np.flatnonzero(zc >= 0.002)
    parts = (Part("muscle", make_material("neo-hookean"), 1050.0, lower),
             Part("fat", make_material("cfm"), 900.0, upper))
    return dataclasses.replace(model, parts=parts, material=parts[0].material, density=parts[0].density)


def _model(symmetry="quarter", **over):
    scene = cfm.builtin_scene("drop-test").with_overrides(thickness=0.004, element_size=2e-3, width=0.012,
                                                          symmetry="quarter" if symmetry == "quarter" else "none",
                                                          **over)
    model = build_model(scene)
    if symmetry == "half":  # keep y >= 0 of the whole specimen: a half model about y = 0
        keep = np.flatnonzero(model.nodes[model.hexes].mean(axis=1)[:, 1] > 0.0)
        used = np.unique(model.hexes[keep])
        index = np.full(len(model.nodes), -1)
        index[used] = np.arange(len(used))
        model = dataclasses.replace(model, nodes=model.nodes[used], hexes=index[model.hexes[keep]],
                                    symmetry_factor=2.0, meta={**model.meta, "symmetry": "half"},
                                    sphere_nodes=np.zeros(0, dtype=np.int64), fixed_dofs=np.zeros((0, 2), np.int64))
    return _two_parts(model)


def _iso_pk2(material, F):
    """Isochoric second Piola-Kirchhoff stress (3, 3) at F (Pa), from the reference energy gradient."""
    m, Q, _ = kin.principal(F[None])
    (g,) = ref.principal_response(material, m, "psi_grad")
    return kin.from_principal(2.0 * g[:, :3], Q)[0]


def test_each_part_stress_equals_the_point_driver_of_its_material():
    model = _model()
    F1, F2, dt = np.diag([1.03, 1.03, 0.94]), np.diag([1.08, 1.07, 0.8]), 2e-4
    fat = model.parts[1].material
    gammas, taus = fat.prony_arrays()
    # the solver's state after the step to F1 (from rest): H1 and the isochoric S0 at F1
    H1, _ = prony.update(np.zeros((len(gammas), 1, 3, 3)), np.zeros((1, 3, 3)), _iso_pk2(fat, F1)[None], dt,
                         gammas, taus)
    ne = [len(p.elements) for p in model.parts]
    state = part_prony_state(model, [None, np.repeat(kin.to_voigt(H1[:, 0])[:, None], ne[1], axis=1)],
                             [None, np.repeat(kin.to_voigt(_iso_pk2(fat, F1)[None]), ne[1], axis=0)], dt)
    B = mean_gradients(model.nodes, model.hexes)
    F = deformation_gradients(B, model.hexes, model.nodes @ F2.T)
    fields, exact = model_cell_fields(model, F, DEFAULT_FIELDS, state)
    assert exact
    for p, part in enumerate(model.parts):
        truth = pt.run_history(part.material, np.array([0.0, dt, 2 * dt]), np.array([np.eye(3), F1, F2]))[2]
        got = fields["cauchy_stress"][part.elements]
        assert np.abs(got - truth).max() <= 1e-10 * np.abs(truth).max(), part.name
        assert (fields["part"][part.elements] == p).all() and (fields["material_id"][part.elements] == p).all()
    # fibre switches only in the CFM part (the neo-Hookean has no fibre families: NaN)
    assert np.isnan(fields["fibre_switch"][model.parts[0].elements]).all()
    assert np.isin(fields["fibre_switch"][model.parts[1].elements], (0.0, 1.0)).all()
    # the one-array structure gives the same where all parts with Prony terms have the same count
    one = {"prony_H": np.zeros((3, model.n_elements, 6)), "prony_S0": np.zeros((model.n_elements, 6)), "prony_dt": dt}
    one["prony_H"][:, model.parts[1].elements] = state["prony_H"][1]
    one["prony_S0"][model.parts[1].elements] = state["prony_S0"][1]
    again, _ = model_cell_fields(model, F, ("cauchy_stress",), one)
    assert np.array_equal(again["cauchy_stress"], fields["cauchy_stress"])
    # without the state the CFM part's stress is only the instantaneous response, and says so
    assert model_cell_fields(model, F, ("cauchy_stress",))[1] is False


def test_part_prony_state_puts_rows_in_part_order_and_refuses_a_mismatch():
    model = _model()
    rng = np.random.default_rng(3)
    e1 = model.parts[1].elements
    H, S0 = rng.normal(size=(3, len(e1), 6)), rng.normal(size=(len(e1), 6))
    perm = rng.permutation(len(e1))
    direct = part_prony_state(model, [None, H], [None, S0], 1e-4)
    shuffled = part_prony_state(model, [None, H[:, perm]], [None, S0[perm]], 1e-4,
                                elements=[model.parts[0].elements, e1[perm]])
    assert np.array_equal(shuffled["prony_H"][1], direct["prony_H"][1]) and shuffled["prony_H"][0] is None
    assert np.array_equal(shuffled["prony_S0"][1], direct["prony_S0"][1])
    per_part = part_prony_states(model, direct)
    assert per_part[0] is None and per_part[1]["prony_H"].shape == (3, len(e1), 6)
    with pytest.raises(ValueError, match="fat.*needs H \\(3"):
        part_prony_state(model, [None, H[:2]], [None, S0], 1e-4)
    with pytest.raises(ValueError, match="has 3 Prony terms but no state"):
        part_prony_state(model, [None, None], [None, None], 1e-4)
    with pytest.raises(ValueError, match="one prony_H array of 2 terms.*fat"):
        part_prony_states(model, {"prony_H": np.zeros((2, model.n_elements, 6)),
                                  "prony_S0": np.zeros((model.n_elements, 6)), "prony_dt": 1e-4})
    with pytest.raises(ValueError, match="2 parts"):
        part_prony_states(model, {"prony_H": [H], "prony_S0": [S0], "prony_dt": 1e-4})


def _u(X, a=0.0):
    """Displacement (m) with the drop test's symmetry about y = 0 (u_y odd, u_x and u_z even in
    y) and, for a = 0, about x = 0; a != 0 breaks the x symmetry (an off-centre impact)."""
    x, y, z = X.T
    return 0.03 * np.stack([x * (1 + 40 * z) + 30 * x * y * y + a * (1 + 0 * x),
                            y * (1 - 25 * z) + 20 * x * x * y + 400 * a * x * y,
                            -0.3 * z - 40 * (x * x + 2 * y * y) + 200 * x * x * y * y + 600 * a * x * z], axis=1)


def _series(tmp_path, model, u, shape="hemisphere", lateral=None, full=True):
    sph = dataclasses.replace(model.sphere, shape=shape, edge_radius=0.003 if shape == "flat" else 0.0,
                              center=(model.sphere.center[0], model.sphere.center[1],
                                      model.sphere.center[2] - (model.sphere.radius if shape in ("flat", "plane") else 0)))
    model = dataclasses.replace(model, sphere=sph)
    t = np.linspace(0.0, 2e-3, 11)
    z = sph.center[2] - 0.5 * t
    res = Result(t=t, backend="fake", steps=10, wall_time=0.0, impactor_z=z,
                 frames=[(0.0, 0.0 * u), (1e-3, u)], impactor_lateral=lateral)
    names = write_field_series(tmp_path, model, res, DEFAULT_FIELDS, full=full)
    return model, res, names


@pytest.mark.parametrize("symmetry", ["quarter", "half"])
def test_mirrored_model_is_symmetric_to_round_off_and_reads_back(tmp_path, symmetry):
    model = _model(symmetry)
    a = 0.0 if symmetry == "quarter" else 1e-3      # the half model: an impact off-centre in x
    _series(tmp_path, model, _u(model.nodes, a))
    mesh = meshio.read(tmp_path / "specimen_0001.vtu")
    x, hexes = mesh.points, mesh.cells_dict["hexahedron"]
    factor = 4 if symmetry == "quarter" else 2
    assert hexes.shape == (factor * model.n_elements, 8)
    notes = json.loads((tmp_path / "fields.json").read_text())
    assert notes["symmetry"] == f"full (mirrored {symmetry})"
    # every array's name, unit and shape
    arrays = {**{k: (v, "point") for k, v in mesh.point_data.items()}, **{k: (v[0], "cell") for k, v in mesh.cell_data.items()}}
    assert set(arrays) == set(notes["arrays"])
    assert {v["field"] for v in notes["arrays"].values()} == set(DEFAULT_FIELDS) - {"velocity"}
    for name, (value, where) in arrays.items():
        info = FIELDS[notes["arrays"][name]["field"]]
        suffix = "_instantaneous" if info.key in ("cauchy_stress", "pressure", "von_mises") else ""
        assert name == f"{info.key}{suffix} [{info.unit}]" and info.where == where
        rows = len(x) if where == "point" else len(hexes)
        assert value.shape == ((rows,) if info.components == 1 else (rows, info.components))
    # the part array and its id -> name mapping (header note of the file and fields.json)
    part = mesh.cell_data["part [-]"][0]
    assert sorted(set(part.tolist())) == [0.0, 1.0] and (part == 0).sum() == factor * len(model.parts[0].elements)
    head = (tmp_path / "specimen_0001.vtu").read_text(errors="replace")[:2000]
    assert "part ids: 0 = muscle (material neo-hookean, material_id 0); 1 = fat (material cfm, material_id 1)" in head
    assert [(p["name"], p["material"], p["elements"]) for p in notes["parts"]] == \
        [("muscle", "neo-hookean", len(model.parts[0].elements)), ("fat", "cfm", len(model.parts[1].elements))]
    # symmetric to round-off about each mirror plane: scalars equal, shear across the plane odd
    centre = x[hexes].mean(axis=1)
    planes = [(0, 0.0), (1, 0.0)] if symmetry == "quarter" else [(1, 0.0)]
    odd = {0: (3, 5), 1: (3, 4)}          # Voigt 12, 13 across x = 0; 12, 23 across y = 0
    for axis, at in planes:
        image = centre.copy()
        image[:, axis] = 2 * at - image[:, axis]
        match = np.array([np.argmin(np.linalg.norm(centre - c, axis=1)) for c in image])
        assert np.abs(centre[match] - image).max() < 1e-12
        for name, blocks in mesh.cell_data.items():
            v = np.asarray(blocks[0], dtype=np.float64)
            w = v[match].copy()
            if name.startswith("cauchy_stress"):
                w[:, list(odd[axis])] *= -1
            scale = max(np.nanmax(np.abs(v)), 1e-300)
            assert np.array_equal(np.isnan(v), np.isnan(w)), name
            assert np.nanmax(np.abs(v - w)) <= 1e-12 * scale, (name, axis)
        assert np.abs(mesh.cell_data["cauchy_stress_instantaneous [Pa]"][0][:, odd[axis][0]]).max() > 0
    if symmetry == "half":  # and equal to the fields computed on the whole specimen with the same motion
        whole = _model("none")
        Fw = deformation_gradients(mean_gradients(whole.nodes, whole.hexes), whole.hexes,
                                   whole.nodes + _u(whole.nodes, a))
        direct, _ = model_cell_fields(whole, Fw, DEFAULT_FIELDS)
        wc = (whole.nodes + _u(whole.nodes, a))[whole.hexes].mean(axis=1)
        order = np.array([np.argmin(np.linalg.norm(wc - c, axis=1)) for c in centre])
        assert sorted(order.tolist()) == list(range(whole.n_elements))
        for name, blocks in mesh.cell_data.items():
            key = notes["arrays"][name]["field"]
            v, w = np.asarray(blocks[0], dtype=np.float64), direct[key][order]
            assert np.nanmax(np.abs(v - w)) <= 1e-9 * max(np.nanmax(np.abs(w)), 1e-300), key
    u = mesh.point_data["displacement [m]"]
    node_image = x - u
    node_image[:, 1] = -node_image[:, 1]
    nm = np.array([np.argmin(np.linalg.norm(x - u - p, axis=1)) for p in node_image])
    assert np.abs(u[nm] * np.array([1, -1, 1]) - u).max() < 1e-15
    # the cut view reads the mirrored series of several parts
    from cfm_core.post.cutview import render_cut
    info = render_cut(tmp_path, 1e-3, "part", tmp_path / "cut.png")
    assert (info["min"], info["max"]) == (0.0, 1.0) and (tmp_path / "cut.png").stat().st_size > 5_000


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("symmetry", ["quarter", "half", "none"])
def test_impactor_block_lies_on_the_shape_at_each_frames_position(tmp_path, shape, symmetry):
    model = _model(symmetry)
    lateral = None
    if symmetry != "quarter":   # moves in x (and y where nothing holds it): from the in-plane history
        t = np.linspace(0.0, 2e-3, 11)
        lateral = {"x": 1e-3 + 2.0 * t, "y": (0.5e-3 - 1.0 * t) if symmetry == "none" else 0 * t}
    model, res, names = _series(tmp_path, model, 0.0 * model.nodes, shape, lateral, full=False)
    assert names[-1] == "impactor_*.vtu (2 frames)"
    sph = model.sphere
    for k, time in enumerate((0.0, 1e-3)):
        pts = meshio.read(tmp_path / f"impactor_000{k}.vtu").points
        c = np.array([sph.center[0], sph.center[1], np.interp(time, res.t, res.impactor_z)])
        if lateral is not None and shape != "plane":
            c[:2] = np.interp(time, res.t, lateral["x"]), np.interp(time, res.t, lateral["y"])
        g, _ = gap("sphere" if shape == "hemisphere" else shape, sph.radius, sph.edge_radius, c, pts)
        assert np.abs(g).max() < 1e-12, shape
        assert len(pts) > 100
        if shape == "hemisphere":
            assert pts[:, 2].max() <= c[2] + 1e-12 and pts[:, 2].min() == pytest.approx(c[2] - sph.radius, abs=1e-12)
        if shape == "plane":   # the patch covers the specimen's footprint
            lo, hi = model.nodes[:, :2].min(axis=0), model.nodes[:, :2].max(axis=0)
            assert (pts[:, :2].min(axis=0) < lo).all() and (pts[:, :2].max(axis=0) > hi).all()
        elif symmetry == "quarter":
            assert (pts[:, 0] >= c[0] - 1e-15).all() and (pts[:, 1] >= c[1] - 1e-15).all()
            assert pts[:, 0].max() == pytest.approx(c[0] + sph.radius) and pts[:, 1].max() == pytest.approx(c[1] + sph.radius)
        elif symmetry == "half":
            assert (pts[:, 1] >= c[1] - 1e-15).all() and pts[:, 0].min() == pytest.approx(c[0] - sph.radius)
        else:
            assert pts[:, 1].min() == pytest.approx(c[1] - sph.radius)
    notes = json.loads((tmp_path / "fields.json").read_text())
    assert notes["impactor_shape"] == shape and shape in notes["impactor"]
    pvd = (tmp_path / "specimen.pvd").read_text()
    assert {p for p in re.findall(r'part="(\d)"', pvd)} == {"0", "1"}


@pytest.mark.parametrize("shape", ["sphere", "hemisphere", "flat"])
@pytest.mark.parametrize("offset_y", [0.0, 0.004])
def test_cut_view_section_of_the_impactor_lies_on_its_surface(shape, offset_y):
    """The impactor's section drawn by ``cfm fields`` for any shape and position (an off-centre
    impactor's axis is not in the cut plane): every segment end lies on the triangulated surface
    (gap of the exact shape within the chord error of the triangulation) and in the plane."""
    from cfm_core.post.cutview import section
    from cfm_core.post.impactor_mesh import impactor_surface
    from cfm_core.scene.impactor import gap
    from cfm_core.scene.model import RigidSphere

    imp = RigidSphere(0.02, 0.1, (0.0, 0.0, 0.0), -1.0, shape=shape, edge_radius=0.004 if shape == "flat" else 0.0)
    pts, tri = impactor_surface(imp, n=48)
    centre = np.array([0.003, offset_y, 0.03])
    seg = section(pts + centre, tri, 0.0)
    assert len(seg) > 20
    ends = seg.reshape(-1, 2)
    xyz = np.stack([ends[:, 0], np.zeros(len(ends)), ends[:, 1]], axis=1)
    g, _ = gap("sphere" if shape == "hemisphere" else shape, 0.02, imp.edge_radius, centre, xyz)
    assert np.abs(g).max() < 3e-5  # inside the facets of the triangulation (20 mm radius): measured 1.3e-5 m
    if shape == "sphere":  # the circle x^2 + z^2 = R^2 - y0^2 about the centre's (x, z)
        r = np.hypot(ends[:, 0] - centre[0], ends[:, 1] - centre[2])
        assert np.allclose(r, np.sqrt(0.02 ** 2 - offset_y ** 2), rtol=2e-3)
