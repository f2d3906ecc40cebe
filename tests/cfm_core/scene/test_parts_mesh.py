"""[parts.NAME]: materials of the named cell sets of a user mesh (gmsh, Abaqus, VTU)."""

import meshio
import numpy as np
import pytest

from cfm_core.errors import InputError
from cfm_core.scene.builder import build_model
from cfm_core.scene.mesh import read_cell_sets, structured_hex_mesh
from cfm_core.scene.scene import load_scene, scene_from_dict, scene_to_toml

# a full 2 x 2 x 4 block centred at x = y = 0: the lower two element layers "fat", the upper "skin"
NODES, HEXES = structured_hex_mesh(0.01, 0.01, 0.004, 2, 2, 4, (-0.005, -0.005, 0.0))
LOWER = np.flatnonzero(NODES[HEXES, 2].mean(axis=1) < 0.002)
UPPER = np.flatnonzero(NODES[HEXES, 2].mean(axis=1) > 0.002)


def drop(**sections):
    return {"scene": {"type": "drop-test"}, **sections}


def write(tmp_path, kind):
    tags = np.where(NODES[HEXES, 2].mean(axis=1) < 0.002, 1, 2)
    if kind == "gmsh":
        path = tmp_path / "block.msh"
        mesh = meshio.Mesh(NODES, [("hexahedron", HEXES)], cell_data={"gmsh:physical": [tags],
                                                                     "gmsh:geometrical": [tags]},
                           field_data={"fat": np.array([1, 3]), "skin": np.array([2, 3])})
        meshio.write(path, mesh, file_format="gmsh22", binary=False)
        return path, ("fat", "skin")
    if kind == "abaqus":
        path = tmp_path / "block.inp"
        meshio.write(path, meshio.Mesh(NODES, [("hexahedron", HEXES)],
                                       cell_sets={"FAT": [LOWER], "SKIN": [UPPER], "ALL": [np.arange(len(HEXES))]}))
        return path, ("FAT", "SKIN")
    path = tmp_path / "block.vtu"
    meshio.write(path, meshio.Mesh(NODES, [("hexahedron", HEXES)], cell_data={"part": [tags]}))
    return path, ("part_1", "part_2")


@pytest.mark.parametrize("kind", ["gmsh", "abaqus", "vtu"])
def test_parts_from_mesh_cell_sets(tmp_path, kind):
    path, (lower, upper) = write(tmp_path, kind)
    sets = read_cell_sets(path)
    assert np.array_equal(sets[lower], LOWER) and np.array_equal(sets[upper], UPPER)
    s = scene_from_dict(drop(specimen={"mesh": str(path)}, parts={
        upper: {"material": "neo-hookean", "parameters": {"mu": 4e5}, "density": 1100.0},
        lower: {"parameters": {"c": 20.0}}}))
    m = build_model(s)
    assert s.specimen.symmetry == "none" and m.symmetry_factor == 1.0  # a full mesh
    assert [p.name for p in m.parts] == [upper, lower]  # the order of the scene
    assert np.array_equal(m.parts[0].elements, UPPER) and np.array_equal(m.parts[1].elements, LOWER)
    assert m.parts[0].material.values["mu"] == 4e5 and m.parts[0].density == 1100.0
    assert m.parts[1].material.name == "cfm" and m.parts[1].material.values["c"] == 20.0
    assert m.parts[1].density == 950.0  # [specimen] density
    rho = m.element_density()
    assert np.all(rho[UPPER] == 1100.0) and np.all(rho[LOWER] == 950.0)
    # the scene.toml a run writes repeats it
    (tmp_path / "scene.toml").write_text(scene_to_toml(s))
    again = load_scene(tmp_path / "scene.toml")
    assert again == s and again.parts == s.parts


def test_abaqus_names_match_case_insensitively(tmp_path):
    path, _ = write(tmp_path, "abaqus")
    s = scene_from_dict(drop(specimen={"mesh": str(path)}, parts={"fat": {}, "skin": {"density": 1100.0}}))
    assert np.array_equal(build_model(s).parts[1].elements, UPPER)


def test_part_absent_from_the_mesh_lists_the_names(tmp_path):
    path, _ = write(tmp_path, "gmsh")
    with pytest.raises(InputError, match=r"\[parts.muscle\]: the mesh .* has no cell set .*named 'muscle'; "
                                         r"the names it has: 'fat', 'skin'"):
        scene_from_dict(drop(specimen={"mesh": str(path)}, parts={"fat": {}, "muscle": {}}))


def test_cells_in_no_part_are_refused(tmp_path):
    path, _ = write(tmp_path, "gmsh")
    assert (UPPER[0], UPPER[1]) == (8, 9)
    with pytest.raises(InputError, match=rf"{len(UPPER)} of the {len(HEXES)} hexahedra .* are in no part "
                                         rf"\(the 9th, 10th, 11th, 12th, 13th, \.\.\. hexahedra of the file\)"):
        scene_from_dict(drop(specimen={"mesh": str(path)}, parts={"fat": {}}))


def abaqus_labelled(tmp_path, extra_sets=()):
    """The block as an .inp whose element numbers start at 501 and node numbers at 1001 (not at 1)."""
    lines = ["*NODE", *[f"{k + 1001}, {x!r}, {y!r}, {z!r}" for k, (x, y, z) in enumerate(NODES.tolist())],
             "*ELEMENT, TYPE=C3D8R, ELSET=ALL",
             *[", ".join(str(v) for v in [e + 501, *(h + 1001)]) for e, h in enumerate(HEXES)],
             "*ELSET, ELSET=FAT", ", ".join(str(e + 501) for e in LOWER), *extra_sets]
    path = tmp_path / "labelled.inp"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_cells_of_an_abaqus_mesh_are_named_by_their_element_numbers(tmp_path):
    """They were named by 0-based places ("hexahedra 8, 9, ..." for the file's elements 509, 510, ...)."""
    path = abaqus_labelled(tmp_path)
    with pytest.raises(InputError, match=r"are in no part \(elements 509, 510, 511, 512, 513, \.\.\. \(the 9th, 10th, "
                                         r"11th, 12th, 13th, \.\.\. hexahedra of the file\)\)"):
        scene_from_dict(drop(specimen={"mesh": str(path)}, parts={"FAT": {}}))
    with pytest.raises(InputError, match=r"both hold 8 cell\(s\) .* \(e\.g\. element 501 \(the 1st hexahedron of the "
                                         r"file\)\)"):
        scene_from_dict(drop(specimen={"mesh": str(path)}, parts={"FAT": {}, "ALL": {}}))


def test_overlapping_parts_are_refused(tmp_path):
    path, _ = write(tmp_path, "abaqus")
    with pytest.raises(InputError, match=rf"\[parts.ALL\] and \[parts.FAT\] both hold {len(LOWER)} cell"):
        scene_from_dict(drop(specimen={"mesh": str(path)}, parts={"FAT": {}, "ALL": {}}))


def test_part_errors(tmp_path):
    path, _ = write(tmp_path, "gmsh")
    with pytest.raises(InputError, match=r"unknown key 'thickness' in \[parts.fat\]"):
        scene_from_dict(drop(specimen={"mesh": str(path)}, parts={"fat": {"thickness": 0.1}, "skin": {}}))
    with pytest.raises(InputError, match=r"\[parts.fat\] density = -1.0 kg/m\^3 is out of range"):
        scene_from_dict(drop(specimen={"mesh": str(path)}, parts={"fat": {"density": -1.0}, "skin": {}}))
    with pytest.raises(InputError, match=r"\[parts\] give the materials .* but the scene has no mesh"):
        scene_from_dict(drop(parts={"fat": {}}))
    with pytest.raises(InputError, match=r"unknown key 'parts' at the top level of a single-element scene"):
        scene_from_dict({"scene": {"type": "single-element"}, "parts": {"fat": {}}})
    s = scene_from_dict(drop(specimen={"mesh": str(path)}, parts={"fat": {"material": "nope"}, "skin": {}}))
    with pytest.raises(InputError, match=r"\[parts.fat\]: .*nope"):
        build_model(s)


def test_mesh_without_parts_keeps_one_material(tmp_path):
    path, _ = write(tmp_path, "gmsh")
    m = build_model(scene_from_dict(drop(specimen={"mesh": str(path)})))
    assert m.parts == () and m.n_elements == len(HEXES)
