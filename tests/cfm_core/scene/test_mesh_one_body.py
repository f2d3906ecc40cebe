"""Imported meshes must be one body: coincident nodes that the elements do not share (a mesh exported
element by element, layers that do not share nodes) and disconnected parts are found when the mesh
is read; coincident nodes are merged on request ([specimen] merge_nodes = true) or refused with a
count and a hint. Without this, such a mesh ran with exit 0 and a peak of 0.3 g instead of 110 g."""

import numpy as np
import pytest

from cfm_core.errors import InputError
from cfm_core.scene import builtin_scene, load_scene
from cfm_core.scene.mesh import check_one_body, connected_parts, read_hex_mesh, structured_hex_mesh

meshio = pytest.importorskip("meshio")

COARSE = dict(width=0.02, thickness=0.005, element_size=0.0025)


def _write(path, nodes, hexes):
    meshio.write(str(path), meshio.Mesh(np.asarray(nodes, float), [("hexahedron", np.asarray(hexes))]))
    return path


def element_by_element(nodes, hexes):
    """The same mesh with 8 own nodes per element (as some exporters write it)."""
    return nodes[hexes].reshape(-1, 3), np.arange(hexes.size).reshape(-1, 8)


def test_a_mesh_exported_element_by_element_is_refused_with_the_count(tmp_path):
    nodes, hexes = structured_hex_mesh(2e-3, 1e-3, 1e-3, 2, 1, 1)  # 12 nodes, 2 elements sharing 4
    path = _write(tmp_path / "split.vtu", *element_by_element(nodes, hexes))
    with pytest.raises(InputError, match=r"4 node\(s\) lie on top of other nodes.*merge_nodes = true"):
        read_hex_mesh(path)
    merged_nodes, merged_hexes = read_hex_mesh(path, merge=True)
    assert merged_nodes.shape == (12, 3) and merged_hexes.shape == (2, 8)
    shared = set(merged_hexes[0]) & set(merged_hexes[1])
    assert len(shared) == 4


def test_layers_that_do_not_share_nodes_are_refused(tmp_path):
    n1, h1 = structured_hex_mesh(2e-3, 2e-3, 1e-3, 2, 2, 1)
    n2, h2 = structured_hex_mesh(2e-3, 2e-3, 1e-3, 2, 2, 1, origin=(0.0, 0.0, 1e-3))
    nodes, hexes = np.vstack([n1, n2]), np.vstack([h1, h2 + len(n1)])
    with pytest.raises(InputError, match=r"9 node\(s\) lie on top"):
        check_one_body(nodes, hexes)
    merged, mh = check_one_body(nodes, hexes, merge=True)
    assert len(merged) == 27 and np.unique(connected_parts(mh, len(merged))).size == 1


def test_disconnected_parts_are_refused_with_their_sizes(tmp_path):
    n1, h1 = structured_hex_mesh(2e-3, 2e-3, 1e-3, 2, 2, 1)
    n2, h2 = structured_hex_mesh(1e-3, 1e-3, 1e-3, 1, 1, 1, origin=(5e-3, 0.0, 0.0))
    path = _write(tmp_path / "two.vtu", np.vstack([n1, n2]), np.vstack([h1, h2 + len(n1)]))
    with pytest.raises(InputError, match=r"2 disconnected parts \(elements per part: 4, 1\)"):
        read_hex_mesh(path, merge=True)


@pytest.mark.parametrize("merge", [False, True])
def test_drop_test_on_an_element_by_element_mesh(tmp_path, merge):
    """Merged, the split mesh gives the structured mesh's peak (same geometry); unmerged, it is refused."""
    pytest.importorskip("numba")
    from cfm_core.runs import drop_test
    from cfm_core.scene import build_model

    structured = builtin_scene("drop-test").with_overrides(**COARSE)
    model = build_model(structured)
    path = _write(tmp_path / "quarter.vtu", *element_by_element(model.nodes, model.hexes))
    text = f'[scene]\ntype = "drop-test"\n[specimen]\nmesh = "{path}"\n' + ("merge_nodes = true\n" if merge else "")
    (tmp_path / "scene.toml").write_text(text)
    if not merge:
        with pytest.raises(InputError, match="not one body"):
            load_scene(tmp_path / "scene.toml")
        return
    scene = load_scene(tmp_path / "scene.toml")
    got = drop_test(scene, "numba").summary["peak_g"]
    want = drop_test(structured, "numba").summary["peak_g"]
    assert got == pytest.approx(want, rel=1e-9) and got > 50.0


@pytest.mark.parametrize("twice", ["every element", "one element"])
def test_a_mesh_listing_an_element_twice_is_refused(tmp_path, twice):
    """Every element written twice (a volume in two physical groups) ran as a specimen twice as dense and twice as
    stiff: 54.5 g for 67.3 g, exit 0."""
    nodes, hexes = structured_hex_mesh(2e-3, 2e-3, 1e-3, 2, 2, 1)
    extra = hexes if twice == "every element" else hexes[2:3, [1, 2, 3, 0, 5, 6, 7, 4]]   # the same nodes, turned
    path = _write(tmp_path / "dup.vtu", nodes, np.vstack([hexes, extra]))
    with pytest.raises(InputError, match=r"more than once .*: the 5th hexahedron of the file repeats the (1st|3rd) "
                                         r"hexahedron of the file\."):
        read_hex_mesh(path)


def test_contact_acts_on_a_top_and_bottom_that_are_not_exactly_flat(tmp_path):
    """Contact was given to the nodes at exactly the top z (and z = 0): a top lowered by 0.1 um at random left 1
    top node of 49 in contact, and the impactor passed through the rest (exit 3, blaming the load). The
    surfaces are now the boundary faces facing up and down: the same run as the flat mesh's."""
    from cfm_core.scene.builder import build_model
    from cfm_core.runs.pipeline import run_model

    nodes, hexes = structured_hex_mesh(0.015, 0.015, 0.005, 6, 6, 2)
    flat = _write(tmp_path / "flat.vtu", nodes, hexes)
    rng = np.random.default_rng(1)
    noisy = nodes.copy()
    top, bottom = noisy[:, 2] > 0.005 - 1e-9, noisy[:, 2] < 1e-9
    noisy[top, 2] -= 1e-7 * rng.random(top.sum())
    noisy[bottom, 2] += 1e-7 * rng.random(bottom.sum())
    noisy[np.argmin(noisy[:, 2]), 2] = 0.0
    noisy[np.argmax(noisy[:, 2]), 2] = 0.005
    bumpy = _write(tmp_path / "noisy.vtu", noisy, hexes)
    scene = builtin_scene("drop-test").with_overrides(end_time=2e-3)
    a, b = (build_model(scene.with_overrides(mesh=str(p))) for p in (flat, bumpy))
    assert np.array_equal(a.sphere_nodes, b.sphere_nodes) and len(a.sphere_nodes) == 49
    assert np.array_equal(a.plane_nodes, b.plane_nodes) and len(b.plane_nodes) == 49
    ra, rb = run_model(a, "numba"), run_model(b, "numba")
    assert np.max(np.abs(rb.contact_force - ra.contact_force)) <= 1e-3 * np.max(np.abs(ra.contact_force))
