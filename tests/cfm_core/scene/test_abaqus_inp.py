"""Abaqus .inp meshes (cfm_core.scene.abaqus_inp): every spelling Abaqus accepts gives the flat file's mesh;
what is not read is refused naming the file, the line and the value.

Each reading test failed before cfm read .inp files itself (meshio 5.3.5): lower-case types were
refused, INPUT= and *INCLUDE inside *NODE gave "np.int64(1)", a comment inside *ELEMENT dropped the
elements after it (exit 0), CAE's *Part/*Instance gave "np.int32(2)", a second *NODE block replaced
the first.
"""

import math

import numpy as np
import pytest

from cfm_core.errors import InputError
from cfm_core.scene.abaqus_inp import element_kind
from cfm_core.scene.mesh import read_cell_sets, read_hex_mesh, structured_hex_mesh

# 3 x 2 x 2 elements, bottom at z = 0: node k is Abaqus node k + 1, element e is element e + 1
NODES, HEXES = structured_hex_mesh(0.003, 0.002, 0.002, 3, 2, 2)
LOWER = np.flatnonzero(NODES[HEXES, 2].mean(axis=1) < 0.001)


def node_lines(nodes=NODES, indent=""):
    return [f"{indent}{k + 1}, {x!r}, {y!r}, {z!r}" for k, (x, y, z) in enumerate(nodes.tolist())]


def element_lines(hexes=HEXES):
    return [", ".join(str(v) for v in [e + 1, *(h + 1)]) for e, h in enumerate(hexes)]


def flat(etype="C3D8R"):
    return ["*HEADING", "a block", "*NODE", *node_lines(), f"*ELEMENT, TYPE={etype}", *element_lines()]


def write(tmp_path, lines, name="m.inp"):
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def same_as_flat(path):
    nodes, hexes = read_hex_mesh(path)
    np.testing.assert_array_equal(nodes, NODES)
    np.testing.assert_array_equal(hexes, HEXES)


def refused(path, *patterns):
    with pytest.raises(InputError) as err:
        read_hex_mesh(path)
    text = str(err.value)
    assert f"mesh file '{path}'" in text and "meshio" not in text and "\n" not in text
    for p in patterns:
        assert p in text, text
    return text


# ----------------------------------------------------------------------------- case (fault 1)
@pytest.mark.parametrize("keyword, etype", [
    ("*ELEMENT, TYPE=", "c3d8r"), ("*ELEMENT, TYPE=", "c3d8rh"), ("*Element, type=", "C3D8R"),
    ("*element,type = ", "C3d8"), ("*ELEMENT, TYPE=", "C3D8H"), ("*ELEMENT, TYPE=", "c3d8i"),
    ("*ELEMENT, TYPE=", "C3D8RT"), ("*ELEMENT, TYPE=", " C3D8IH ")])
def test_element_types_and_keywords_in_any_case(tmp_path, keyword, etype):
    lines = ["*heading", "x", "*Node", *node_lines(), keyword + etype, *element_lines()]
    same_as_flat(write(tmp_path, lines))


def test_every_c3d8_variant_is_a_brick_and_other_types_are_named():
    for t in ("C3D8", "c3d8r", "C3D8RH", "C3D8IH", "C3D8HT", "C3D8RPH"):
        assert element_kind(t) == ("hexahedron", 8)
    assert element_kind("C3D20R") == ("hexahedron20", 20) and element_kind("c3d10m") == ("tetra10", 10)
    assert element_kind("S4R") == ("quad", 4) and element_kind("r3d4") == ("quad", 4)
    assert element_kind("STRI65") == ("triangle6", 6) and element_kind("SFM3D4R") == ("quad", 4)
    assert element_kind("SC8R") is None and element_kind("CONN3D2") is None and element_kind("C3D9") is None


# ----------------------------------------------------------------------------- INPUT= and *INCLUDE (fault 2)
def test_node_input_file(tmp_path):
    (tmp_path / "nodes.inp").write_text("\n".join(node_lines()) + "\n")
    same_as_flat(write(tmp_path, ["*NODE, INPUT=nodes.inp", "*ELEMENT, TYPE=C3D8R", *element_lines()]))


def test_include_inside_node_and_element_blocks(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "nodes.inp").write_text("** the nodes\n" + "\n".join(node_lines()) + "\n")
    (tmp_path / "sub" / "elements.inp").write_text("\n".join(element_lines()) + "\n")
    same_as_flat(write(tmp_path, ["*NODE", "*INCLUDE, INPUT=sub/nodes.inp", "*ELEMENT, TYPE=C3D8R",
                                  "*Include, input=sub/elements.inp"]))


def test_element_input_file_and_nested_includes_relative_to_their_own_folder(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "elements.inp").write_text("\n".join(element_lines()) + "\n")
    (tmp_path / "sub" / "mesh.inp").write_text("*NODE\n" + "\n".join(node_lines()) + "\n"
                                               "*ELEMENT, TYPE=C3D8R, INPUT=elements.inp\n")
    same_as_flat(write(tmp_path, ["*HEADING", "*INCLUDE, INPUT=sub/mesh.inp"]))


def test_missing_and_circular_includes_are_named(tmp_path):
    path = write(tmp_path, ["*NODE, INPUT=absent.inp", "*ELEMENT, TYPE=C3D8R", *element_lines()])
    refused(path, "line 1 ('*NODE, INPUT=absent.inp')", "INPUT=absent.inp of *NODE does not exist",
            str(tmp_path / "absent.inp"))
    (tmp_path / "a.inp").write_text("*INCLUDE, INPUT=b.inp\n")
    (tmp_path / "b.inp").write_text("*INCLUDE, INPUT=a.inp\n")
    refused(tmp_path / "a.inp", "line 1 of", "already being read")
    (tmp_path / "kw.inp").write_text("*NODE\n1, 0, 0, 0\n")
    refused(write(tmp_path, ["*NODE, INPUT=kw.inp"]), "must hold only data lines", "kw.inp")


# ----------------------------------------------------------------------------- other forms (fault 3)
def test_comment_and_blank_lines_inside_data_blocks_end_nothing(tmp_path):
    nodes, elements = node_lines(), element_lines()
    lines = ["*NODE", *nodes[:7], "** a comment", "", *nodes[7:], "*ELEMENT, TYPE=C3D8R", *elements[:5],
             "**", "   ", *elements[5:], "** the end"]
    same_as_flat(write(tmp_path, lines))


def test_several_node_and_element_blocks(tmp_path):
    nodes, elements = node_lines(), element_lines()
    lines = ["*NODE, NSET=A", *nodes[:10], "*NODE, NSET=B", *nodes[10:], "*ELEMENT, TYPE=C3D8R, ELSET=LOW",
             *elements[:6], "*ELEMENT, TYPE=C3D8, ELSET=HIGH", *elements[6:]]
    path = write(tmp_path, lines)
    same_as_flat(path)
    sets = read_cell_sets(path)
    assert np.array_equal(sets["LOW"], LOWER) and np.array_equal(sets["HIGH"], np.arange(6, 12))


def test_connectivity_continued_on_following_lines_and_keyword_lines_continued(tmp_path):
    cont = []
    for line in element_lines():
        parts = line.split(", ")
        cont += [", ".join(parts[:4]) + ",", ", ".join(parts[4:7]), ", ".join(parts[7:]) + ","]
    same_as_flat(write(tmp_path, ["*NODE", *node_lines(), "*ELEMENT,", "TYPE=C3D8R, ELSET=ALL", *cont]))


def test_blank_coordinates_are_zero_and_fortran_exponents_are_read(tmp_path):
    nodes = [", ".join([str(k + 1)] + ["" if v == 0 else f"{v:.17e}".replace("e", "D") for v in xyz])
             for k, xyz in enumerate(NODES.tolist())]
    nodes[0] = "1"  # all three coordinates left out
    same_as_flat(write(tmp_path, ["*NODE", *nodes, "*ELEMENT, TYPE=C3D8R", *element_lines()]))


def test_elset_generate_names_and_repeats(tmp_path):
    lines = flat() + ["*ELSET, ELSET=low, GENERATE", "1, 6, 1", "*Elset, elset=odd, generate", "1, 11, 2",
                      "*ELSET, ELSET=both", "LOW, 12,", "*ELSET, ELSET=both", "odd", "*NSET, NSET=N, GENERATE",
                      "1, 9999, 1"]
    sets = read_cell_sets(write(tmp_path, lines))
    assert np.array_equal(sets["low"], LOWER)
    assert np.array_equal(sets["odd"], np.arange(0, 11, 2))
    assert np.array_equal(sets["both"], np.union1d(np.union1d(LOWER, [11]), np.arange(0, 11, 2)))


CAE_HEAD = ["*Heading", "** Job name: Job-1 Model name: Model-1", "*Preprint, echo=NO, model=NO, history=NO",
            "**", "** PARTS", "**"]
CAE_TAIL = ["** MATERIALS", "*Material, name=Fat", "*Density", " 950.,", "*Elastic", "1e6, 0.45",
            "*Step, name=Drop, nlgeom=YES", "*Dynamic, Explicit", ", 0.01", "*Output, field", "*Node Output",
            "U, V", "*Element Output, directions=YES", "S,", "*End Step"]


def cae(part_nodes, placement=(), independent=False):
    mesh = ["*Node", *node_lines(part_nodes, "      "), "*Element, type=C3D8R", *element_lines(),
            "*Nset, nset=Set-1, generate", f"  1,  {len(NODES)},   1", "*Elset, elset=Set-1, generate",
            f"  1,  {len(HEXES)},   1", "*Elset, elset=Fat, generate", " 1, 6, 1",
            "** Section: Section-1", "*Solid Section, elset=Set-1, material=Fat", ","]
    part = ["*Part, name=Specimen", *([] if independent else mesh), "*End Part"]
    assembly = ["**", "** ASSEMBLY", "**", "*Assembly, name=Assembly", "**",
                "*Instance, name=Specimen-1, part=Specimen", *placement, *(mesh if independent else []),
                "*End Instance", "**", "*Node", "      1,   0.0,  0.0,  0.05", "*Nset, nset=RP, internal", "1,",
                "*Elset, elset=Top, instance=Specimen-1, generate", " 7, 12, 1", "*End Assembly"]
    return CAE_HEAD + part + assembly + CAE_TAIL


@pytest.mark.parametrize("independent", [False, True])
def test_abaqus_cae_parts_assembly_and_instances(tmp_path, independent):
    path = write(tmp_path, cae(NODES, independent=independent))
    same_as_flat(path)  # the assembly's reference node (number 1 too) is not the part's node 1
    sets = read_cell_sets(path)
    assert np.array_equal(sets["Fat"], LOWER) and np.array_equal(sets["Specimen-1.Fat"], LOWER)
    assert np.array_equal(sets["Top"], np.arange(6, 12)) and len(sets["Set-1"]) == 12


def test_instance_translation_then_rotation_are_applied(tmp_path):
    """The part is drawn turned by -90 degrees about z and moved; the instance turns and moves it back."""
    t = np.array([0.01, -0.02, 0.003])
    turned = NODES @ np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1.0]]).T - t  # (x, y) -> (y, -x), then - t
    rotation = "0., 0., 0., 0., 0., 1., 90."
    nodes, hexes = read_hex_mesh(write(tmp_path, cae(turned, [", ".join(map(repr, t.tolist())), rotation])))
    np.testing.assert_allclose(nodes, NODES, atol=1e-15)
    np.testing.assert_array_equal(hexes, HEXES)
    assert math.isclose(nodes[:, 2].min(), 0.0, abs_tol=1e-15)


def test_several_instances_name_their_sets(tmp_path):
    lines = cae(NODES)
    at = lines.index("*End Instance") + 1
    lines[at:at] = ["*Instance, name=Specimen-2, part=Specimen", "0.003, 0., 0.", "*End Instance"]
    path = write(tmp_path, lines)
    sets = read_cell_sets(path)
    assert np.array_equal(sets["Specimen-2.Fat"], LOWER + 12) and "Fat" not in sets  # bare name: ambiguous
    nodes, hexes = read_hex_mesh(path, merge=True)  # the two blocks touch at x = 0.003
    assert hexes.shape == (24, 8) and nodes[:, 0].max() == pytest.approx(0.006)


# ----------------------------------------------------------------------------- what is refused, and how
def test_malformed_lines_are_named(tmp_path):
    nodes, elements = node_lines(), element_lines()
    bad = nodes.copy()
    bad[4] = "5, 0.001, abc, 0.0"
    refused(write(tmp_path, ["*NODE", *bad, "*ELEMENT, TYPE=C3D8R", *elements]),
            "line 6 ('5, 0.001, abc, 0.0')", "coordinate y of node 5 'abc' is not a finite number")
    missing = elements.copy()
    missing[3] = missing[3].replace(", 6,", ", 999,")
    refused(write(tmp_path, ["*NODE", *nodes, "*ELEMENT, TYPE=C3D8R", *missing]),
            f"line {len(nodes) + 6} ('4, ", "element 4 uses node 999, which no *NODE line defines")
    refused(write(tmp_path, ["*NODE", *nodes, nodes[0], "*ELEMENT, TYPE=C3D8R", *elements]),
            f"line {len(nodes) + 2}", "node 1 is defined a second time")
    refused(write(tmp_path, ["*NODE", *nodes, "*ELEMENT, TYPE=C3D8R", *elements, elements[0]]),
            "element 1 is defined a second time")
    short = elements[:-1] + [elements[-1].rsplit(",", 1)[0]]
    refused(write(tmp_path, ["*NODE", *nodes, "*ELEMENT, TYPE=C3D8R", *short]),
            "element 12 of TYPE=C3D8R has 7 node numbers", "a C3D8R element has 8")
    refused(write(tmp_path, ["*NODE", *nodes, "*ELEMENT", *elements]), "*ELEMENT needs TYPE=")
    refused(write(tmp_path, flat() + ["*ELSET, ELSET=X", "1, 99"]), "the element set X names element 99")
    refused(write(tmp_path, flat() + ["*ELSET, ELSET=X", "NOPE"]), "names the set 'NOPE', which is not defined")
    refused(write(tmp_path, flat() + ["*ELSET, ELSET=X, GENERATE", "6, 1"]), "last element 1 is below the first 6")


def test_unread_types_and_keywords_are_refused_by_name(tmp_path):
    text = refused(write(tmp_path, flat("SC8R")), f"line {len(NODES) + 4} ('*ELEMENT, TYPE=SC8R')",
                   "TYPE=SC8R is not one cfm reads", "C3D8R")
    assert "C3D8 and its variants" in text
    refused(write(tmp_path, flat()[:3 + len(NODES)] + ["*ELEMENT, TYPE=C3D20R"]
                  + [", ".join(str(v) for v in range(1, 22))]), "contains 1 hexahedron20")
    refused(write(tmp_path, flat() + ["*NGEN, NSET=X", "1, 5"]), "*NGEN generates nodes, which cfm does not read")
    refused(write(tmp_path, ["*NODE, SYSTEM=C", *node_lines(), "*ELEMENT, TYPE=C3D8R", *element_lines()]),
            "SYSTEM=C gives cylindrical or spherical coordinates")
    refused(write(tmp_path, ["*SYSTEM", "0, 0, 0, 1, 0, 0", *flat()]), "*SYSTEM moves the nodes")
    same_as_flat(write(tmp_path, ["*SYSTEM", *flat()]))  # *SYSTEM without data: the global system


def test_cae_structure_mistakes_are_named(tmp_path):
    lines = cae(NODES)
    no_assembly = lines[:lines.index("*Assembly, name=Assembly")]
    refused(write(tmp_path, no_assembly), "defines the part(s) 'Specimen' but no *Instance")
    refused(write(tmp_path, [x.replace("part=Specimen", "part=Other") for x in lines]),
            "is of PART=Other, which is not defined before it (parts: 'Specimen')")
    refused(write(tmp_path, [x for x in lines if x != "*End Part"]), "*Assembly inside *Part, name=Specimen (line 7",
            "which is not closed")
    unclosed = lines[:lines.index("*End Instance")]
    refused(write(tmp_path, unclosed), "is not closed at the end of the file")
    refused(write(tmp_path, [x.replace("instance=Specimen-1", "instance=Nope") for x in lines]),
            "INSTANCE=Nope names no *Instance")


def test_compressed_and_binary_files_are_named(tmp_path):
    import gzip

    path = tmp_path / "m.inp"
    path.write_bytes(gzip.compress(("\n".join(flat()) + "\n").encode()))
    refused(path, "is gzip-compressed")
    path.write_bytes(b"\x00\x01\x02binary")
    refused(path, "is a binary file")


# ----------------------------------------------------------------------------- through the command line
def test_cli_drop_test_on_a_lower_case_cae_mesh_matches_the_flat_file_and_refusals_exit_2(tmp_path):
    import json
    import subprocess
    import sys

    nodes, hexes = structured_hex_mesh(0.015, 0.015, 0.005, 6, 6, 2)  # a quarter of a 30 mm x 5 mm block

    def run(path):
        out = tmp_path / f"o_{path.stem}"
        done = subprocess.run([sys.executable, "-m", "cfm_core.cli", "drop-test", "--mesh", str(path),
                               "--element-size", "0.0025", "--width", "0.03", "--thickness", "0.005",
                               "--out", str(out), "--quiet", "--no-plot"], capture_output=True, text=True, timeout=300)
        return done, out

    upper = write(tmp_path, ["*NODE", *node_lines(nodes), "*ELEMENT, TYPE=C3D8R", *element_lines(hexes)], "upper.inp")
    (tmp_path / "nodes.inp").write_text("\n".join(node_lines(nodes)) + "\n")
    lower = write(tmp_path, ["*heading", "*part, name=block", "*node, input=nodes.inp", "*element, type=c3d8r",
                             *element_lines(hexes), "*end part", "*assembly, name=a",
                             "*instance, name=block-1, part=block", "*end instance", "*end assembly"], "lower.inp")
    peaks = []
    for path in (upper, lower):
        done, out = run(path)
        assert done.returncode == 0, done.stderr
        peaks.append(json.loads((out / "summary.json").read_text())["peak_g"])
    assert peaks[0] == peaks[1] == pytest.approx(135.65962, rel=1e-6)
    (tmp_path / "nodes.inp").unlink()
    done, _ = run(lower)
    assert done.returncode == 2 and "Traceback" not in done.stderr and "\n" not in done.stderr.strip()
    assert "line 3 ('*node, input=nodes.inp')" in done.stderr and "does not exist" in done.stderr


# ----------------------------------------------------------------------------- mesh checks name the file's labels
def labelled(nodes=NODES, hexes=HEXES, node0=1001, element0=101):
    """A flat file whose node numbers start at node0 and element numbers at element0 (not at 1)."""
    return (["*NODE", *[f"{k + node0}, {x!r}, {y!r}, {z!r}" for k, (x, y, z) in enumerate(nodes.tolist())],
             "*ELEMENT, TYPE=C3D8R"] +
            [", ".join(str(v) for v in [e + element0, *(h + node0)]) for e, h in enumerate(hexes)])


def test_an_inverted_element_is_named_by_its_element_and_node_numbers(tmp_path):
    """The message named "element 1 (nodes [9, 10, 14, 13, 1, 2, 6, 5])", 0-based rows after renumbering, for
    the file's element 102 on nodes 1010 ... 1006."""
    hexes = HEXES.copy()
    hexes[1] = hexes[1][[4, 5, 6, 7, 0, 1, 2, 3]]  # top and bottom swapped: mirrored
    text = refused(write(tmp_path, labelled(hexes=hexes)), "element 102 (the 2nd hexahedron of the file; nodes "
                   + ", ".join(str(v + 1001) for v in hexes[1]) + ") has a non-positive Jacobian")
    assert "element 1 " not in text and "nodes 0-3" not in text and "first four nodes the bottom face" in text


def test_a_corner_is_named_by_its_place_and_node_number(tmp_path):
    nodes = NODES.copy()
    nodes[HEXES[0, 6]] = nodes[HEXES[0, 0]] + [0.0002, 0.0002, 0.0002]  # corner 7 pulled inside past the centre
    text = refused(write(tmp_path, labelled(nodes=nodes)), "element 101 (the 1st hexahedron of the file; nodes ")
    assert f"m^3 at its 7th node ({HEXES[0, 6] + 1001}); 1 bad element(s) in total" in text


def test_a_repeated_element_is_named_by_its_numbers(tmp_path):
    """It said "element 12 repeats element 1 (0-based, hexahedra in the file's order)" for elements 113 and 102."""
    refused(write(tmp_path, labelled(hexes=np.vstack([HEXES, HEXES[1:2]]))),
            "element 113 (the 13th hexahedron of the file) repeats element 102 (the 2nd hexahedron of the file)")


def test_an_element_collapsed_by_merging_is_named_by_its_number(tmp_path):
    nodes = np.vstack([NODES, NODES[HEXES[4, 2]]])  # a twin of element 105's 3rd node, used by it alone
    hexes = HEXES.copy()
    hexes[4, 3] = len(NODES)  # its 4th node is now at the same place as its 3rd
    path = write(tmp_path, labelled(nodes=nodes, hexes=hexes))
    with pytest.raises(InputError, match=r"merging coincident nodes collapsed element 105 \(the 5th hexahedron"):
        read_hex_mesh(path, merge=True)


def test_an_instance_element_is_named_as_abaqus_names_it(tmp_path):
    """In an assembly the labels are INSTANCE.NUMBER, as Abaqus writes them in its own messages."""
    lines = cae(NODES)
    at = lines.index("*Element, type=C3D8R") + 2  # element 2's line
    e, *nodes = lines[at].split(", ")
    lines[at] = ", ".join([e, *nodes[4:], *nodes[:4]])
    refused(write(tmp_path, lines), "element Specimen-1.2 (the 2nd hexahedron of the file; nodes Specimen-1."
            + ", Specimen-1.".join(nodes[4:] + nodes[:4]) + ")")


def test_a_file_without_labels_names_the_place_of_the_element_and_its_points(tmp_path):
    """A .vtu has no labels: "the 2nd hexahedron of the file" and the file's 0-based point indices (the message
    gave the rows left after unused points were dropped: 9 for the file's point 10)."""
    meshio = pytest.importorskip("meshio")
    nodes, hexes = structured_hex_mesh(3.0, 1.0, 1.0, 3, 1, 1)
    hexes[1] = hexes[1][[4, 5, 6, 7, 0, 1, 2, 3]]
    path = tmp_path / "m.vtu"
    meshio.write(path, meshio.Mesh(np.vstack([[[5.0, 5.0, 5.0]], nodes]), [("hexahedron", hexes + 1)]))
    with pytest.raises(InputError) as err:
        read_hex_mesh(path)
    assert "the 2nd hexahedron of the file (points " + ", ".join(str(v + 1) for v in hexes[1]) + " of the file, " \
           "0-based)" in str(err.value)


def test_texts_about_a_mesh_file_say_which_reader_reads_it(tmp_path, capsys):
    """--mesh's help said "read with meshio" and the messages offered .inp among meshio's formats, although cfm
    reads .inp files itself."""
    from cfm_core.cli import main

    with pytest.raises(SystemExit):
        main(["drop-test", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "read with meshio" not in help_text
    assert "an Abaqus .inp (read by cfm's own reader) or a format meshio reads (.vtu, .msh, ...)" in help_text
    with pytest.raises(InputError) as err:
        read_hex_mesh(tmp_path / "absent.inp")
    assert "(Abaqus .inp, or a format meshio reads: .vtu, .msh, ...)" in str(err.value)
    junk = tmp_path / "junk.vtu"
    junk.write_text("not a mesh")
    with pytest.raises(InputError) as err:
        read_hex_mesh(junk)
    assert "meshio reads (.vtu, .msh, ...) or an Abaqus .inp file (read by cfm itself)" in str(err.value)


def _labelled_block(path, n=3, layers=2, h=0.002):
    """An n x n x layers block of C3D8 elements of edge h (m), nodes numbered from 1001 and elements
    from 101 in the file, x fastest."""
    label, lines = {}, ["*NODE"]
    for k in range(layers + 1):
        for j in range(n + 1):
            for i in range(n + 1):
                label[i, j, k] = 1001 + len(label)
                lines.append(f"{label[i, j, k]}, {i * h}, {j * h}, {k * h}")
    lines.append("*ELEMENT, TYPE=C3D8, ELSET=FAT")
    e = 101
    for k in range(layers):
        for j in range(n):
            for i in range(n):
                corners = [label[i, j, k], label[i + 1, j, k], label[i + 1, j + 1, k], label[i, j + 1, k],
                           label[i, j, k + 1], label[i + 1, j, k + 1], label[i + 1, j + 1, k + 1], label[i, j + 1, k + 1]]
                lines.append(f"{e}, " + ", ".join(map(str, corners)))
                e += 1
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_run_failure_names_the_element_as_the_mesh_file_numbers_it(tmp_path):
    """A run-time failure named the model's 0-based element ("element 9 is folded"); with a mesh file
    the message also gives the file's element number and nodes (element 110, the 10th hexahedron,
    nodes from 1017), computed here from the file's own numbering."""
    import cfm_core as cfm
    from cfm_core.errors import NumericalError

    mesh = _labelled_block(tmp_path / "block.inp")
    scene = cfm.builtin_scene("drop-test").with_overrides(mesh=str(mesh), velocity=20.0)
    with pytest.raises(NumericalError) as info:
        cfm.drop_test(scene)
    e = info.value.element
    assert e is not None and "folded" in str(info.value)
    rows = read_hex_mesh(mesh)[1][e]                   # the model's nodes are the file's, from 1001, in order
    nodes = ", ".join(str(1001 + int(r)) for r in rows)
    import re

    assert re.search(rf"In block\.inp, element {e} of the model is element {101 + e} \(the {e + 1}(st|nd|rd|th) "
                     rf"hexahedron of the file; nodes {nodes}\)\.$", str(info.value))
