"""[[specimen.layers]]: conforming layered blocks, their parts, materials and errors."""

import numpy as np
import pytest

from cfm_core.errors import InputError
from cfm_core.scene.builder import build_model
from cfm_core.scene.mesh import element_volumes
from cfm_core.scene.scene import builtin_scene, scene_from_dict


def drop(**sections):
    return {"scene": {"type": "drop-test"}, **sections}


def layered(layers, **specimen):
    return scene_from_dict(drop(specimen={"element_size": 2e-3, "width": 0.02, **specimen, "layers": layers}))


@pytest.mark.parametrize("symmetry", ["quarter", "half", "none"])
@pytest.mark.parametrize("split", [(0.004, 0.004), (0.002, 0.006), (0.002, 0.002, 0.004)])
def test_same_material_layers_equal_the_one_material_block(split, symmetry):
    one = build_model(scene_from_dict(drop(specimen={"element_size": 2e-3, "width": 0.02, "thickness": 0.008,
                                                     "symmetry": symmetry})))
    lay = build_model(layered([{"thickness": t} for t in split], symmetry=symmetry))
    assert np.array_equal(lay.nodes, one.nodes) and np.array_equal(lay.hexes, one.hexes)
    assert np.array_equal(lay.fixed_dofs, one.fixed_dofs)
    assert np.array_equal(lay.sphere_nodes, one.sphere_nodes) and np.array_equal(lay.plane_nodes, one.plane_nodes)
    assert lay.sphere == one.sphere and lay.symmetry_factor == one.symmetry_factor
    assert [p.name for p in lay.parts] == [f"layer{i + 1}" for i in range(len(split))]
    # the parts tile the elements in layer order, each the elements between its planes
    z = lay.nodes[lay.hexes, 2].mean(axis=1)
    bottom = 0.0
    for part, t in zip(lay.parts, split):
        inside = np.flatnonzero((z > bottom) & (z < bottom + t))
        assert np.array_equal(part.elements, inside)
        bottom += t
    assert np.array_equal(np.sort(np.concatenate([p.elements for p in lay.parts])), np.arange(lay.n_elements))
    assert np.array_equal(lay.element_density(), np.full(lay.n_elements, 950.0))


def test_layers_of_different_spacing_are_conforming_with_exact_interfaces():
    s = layered([{"thickness": 0.003, "element_size": 1e-3, "name": "bottom"},
                 {"thickness": 0.005, "element_size": 2.5e-3, "name": "top", "density": 1100.0}])
    m = build_model(s)
    assert s.specimen.thickness == 0.008 and s.specimen.grid == (5, 5, 5)
    planes = np.unique(m.nodes[:, 2])
    assert np.array_equal(planes, [0.0, 0.001, 0.002, 0.003, 0.003 + 0.0025, 0.008])
    assert m.n_nodes == 6 * 6 * 6  # one node per grid point: the layers share their interface nodes
    vol = element_volumes(m.nodes, m.hexes)
    area = 0.01 * 0.01
    for part, t in zip(m.parts, (0.003, 0.005)):
        assert vol[part.elements].sum() == pytest.approx(t * area, rel=1e-12)
    assert [p.density for p in m.parts] == [950.0, 1100.0]
    assert m.density == 950.0 and m.material is m.parts[0].material
    rho = m.element_density()
    assert np.all(rho[m.parts[1].elements] == 1100.0) and np.all(rho[m.parts[0].elements] == 950.0)
    assert [e["cells_through_thickness"] for e in m.meta["parts"]] == [3, 2]
    top = m.nodes[m.sphere_nodes, 2]
    assert np.all(top == 0.008) and m.sphere.center[2] == 0.008 + 0.055


def test_layer_materials_inherit_and_override():
    s = scene_from_dict(drop(specimen={"element_size": 2e-3, "width": 0.02, "layers": [
        {"thickness": 0.004, "parameters": {"k1": 2000.0}},
        {"thickness": 0.002, "material": "neo-hookean", "parameters": {"mu": 5000.0}, "elastic": True},
        {"thickness": 0.002, "moduli": "instantaneous"}]},
        material={"name": "cfm", "parameters": {"c": 20.0}}))
    p = build_model(s).parts
    assert p[0].material.name == "cfm" and p[0].material.values["c"] == 20.0 and p[0].material.values["k1"] == 2000.0
    assert p[1].material.name == "neo-hookean" and p[1].material.values["mu"] == 5000.0
    assert "c" not in p[1].material.values  # a layer naming a material does not take [material]'s parameters
    assert p[2].material.moduli == "instantaneous" and p[2].material.values["c"] == 20.0
    m = build_model(s)  # Model.material is the first part's; the meta keeps [material]'s values
    assert m.material is m.parts[0].material and m.meta["material_parameters"]["c"] == 20.0


@pytest.mark.parametrize("layers, specimen, match", [
    ([{"thickness": 0.004}], {"thickness": 0.005}, r"thickness = 0.005 m disagrees with the sum"),
    ([{"thickness": 0.004, "colour": "red"}], {}, r"unknown key 'colour' in layer 1 .*allowed keys: thickness"),
    ([{"material": "cfm"}], {}, r"layer 1 .* needs thickness \(m\)"),
    ([{"thickness": 0.002, "element_size": 0.003}], {}, r"layer 1 .*element_size = 0.003 m is out of range"),
    ([{"thickness": -0.002}], {}, r"thickness = -0.002 m is out of range"),
    ([{"thickness": 0.002, "density": 0.0}], {}, r"density = 0.0 kg/m\^3 is out of range"),
    ([{"thickness": 0.002, "name": "a"}, {"thickness": 0.002, "name": "a"}], {}, r"name 'a' is used twice"),
    ([{"thickness": 0.002, "moduli": "short"}], {}, r"moduli = 'short' is not allowed"),
    ({"thickness": 0.002}, {}, r"must be an array of tables \[\[specimen.layers\]\]"),
])
def test_layer_errors(layers, specimen, match):
    with pytest.raises(InputError, match=match):
        layered(layers, **specimen)


def test_layer_material_errors_name_the_layer():
    s = layered([{"thickness": 0.004, "name": "skin", "material": "no-such"}, {"thickness": 0.004}])
    with pytest.raises(InputError, match="layer 'skin'"):
        build_model(s)


def test_layers_and_mesh_are_exclusive(tmp_path):
    import meshio

    from cfm_core.scene.mesh import structured_hex_mesh

    nodes, hexes = structured_hex_mesh(0.01, 0.01, 0.004, 2, 2, 2)
    meshio.write(tmp_path / "q.vtu", meshio.Mesh(nodes, [("hexahedron", hexes)]))
    with pytest.raises(InputError, match=r"mesh .* and \[\[specimen.layers\]\] cannot be used together"):
        scene_from_dict(drop(specimen={"mesh": str(tmp_path / "q.vtu"), "layers": [{"thickness": 0.004}]}))


def test_one_material_scene_has_no_parts():
    m = build_model(builtin_scene("drop-test").with_overrides(element_size=2e-3))
    assert m.parts == () and not m.multi_material and "parts" not in m.meta
