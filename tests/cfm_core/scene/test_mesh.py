"""Tests of cfm_core.scene.mesh: structured hexahedra, volumes, Jacobians, node sets, meshio reading."""

import meshio
import numpy as np
import pytest

from cfm_core.errors import InputError
from cfm_core.scene.mesh import check_hex_jacobians, element_volumes, hex_jacobians, mean_edge_length, nodes_on_plane, read_hex_mesh, structured_hex_mesh


def _write(path, nodes, cells):
    meshio.write(path, meshio.Mesh(nodes, cells))
    return path


def test_structured_counts_and_exact_faces():
    nodes, hexes = structured_hex_mesh(0.025, 0.02, 0.008, 5, 4, 8, origin=(-0.01, 0.0, 0.0))
    assert nodes.shape == (6 * 5 * 9, 3) and nodes.dtype == np.float64
    assert hexes.shape == (5 * 4 * 8, 8) and hexes.dtype == np.int64
    assert nodes[:, 0].min() == -0.01 and nodes[:, 0].max() == -0.01 + 0.025  # ox, ox + lx
    assert nodes[:, 2].min() == 0.0 and nodes[:, 2].max() == 0.008
    assert len(np.unique(hexes)) == len(nodes)


def test_first_element_is_in_vtk_order():
    nodes, hexes = structured_hex_mesh(2.0, 3.0, 4.0, 1, 1, 1)
    x = nodes[hexes[0]]
    expected = [[0, 0, 0], [2, 0, 0], [2, 3, 0], [0, 3, 0], [0, 0, 4], [2, 0, 4], [2, 3, 4], [0, 3, 4]]
    np.testing.assert_array_equal(x, expected)
    # bottom face counter-clockwise seen from +z: (x1 - x0) x (x2 - x1) points up
    assert np.cross(x[1] - x[0], x[2] - x[1])[2] > 0


def test_volumes_sum_and_positive_jacobians():
    lx, ly, lz = 0.025, 0.025, 0.0048
    nodes, hexes = structured_hex_mesh(lx, ly, lz, 25, 25, 5)
    vol = element_volumes(nodes, hexes)
    assert vol.sum() == pytest.approx(lx * ly * lz, rel=1e-12)
    np.testing.assert_allclose(vol, lx * ly * lz / hexes.shape[0], rtol=1e-12)
    dets = hex_jacobians(nodes, hexes)
    assert dets.shape == (hexes.shape[0], 9)
    # affine elements: det J = V / 8 everywhere
    np.testing.assert_allclose(dets, np.repeat(vol[:, None] / 8.0, 9, axis=1), rtol=1e-12)


def test_volumes_exact_for_distorted_mesh():
    """Moving interior nodes changes element shapes (non-affine) but not the total volume."""
    nodes, hexes = structured_hex_mesh(1.0, 1.0, 1.0, 4, 4, 4)
    rng = np.random.default_rng(0)
    interior = np.all((nodes > 1e-12) & (nodes < 1 - 1e-12), axis=1)
    nodes[interior] += rng.uniform(-0.08, 0.08, size=(interior.sum(), 3))
    vol = element_volumes(nodes, hexes)
    assert vol.sum() == pytest.approx(1.0, rel=1e-13)
    # each element against a 6-point-per-direction Gauss rule (independent of the 2-point one)
    g, w = np.polynomial.legendre.leggauss(6)
    pts = np.array(np.meshgrid(g, g, g, indexing="ij")).reshape(3, -1).T
    wts = np.einsum("i,j,k->ijk", w, w, w).ravel()
    np.testing.assert_allclose(vol, hex_jacobians(nodes, hexes, pts) @ wts, rtol=1e-12)


def test_structured_rejects_bad_input():
    for args in [(0.0, 1, 1, 1, 1, 1), (1, -1, 1, 1, 1, 1), (1, 1, float("nan"), 1, 1, 1),
                 (1, 1, 1, 0, 1, 1), (1, 1, 1, 1, 1.5, 1), (1, 1, 1, 1, 1, True)]:
        with pytest.raises(InputError):
            structured_hex_mesh(*args)


def test_inverted_element_is_named():
    nodes, hexes = structured_hex_mesh(3.0, 1.0, 1.0, 3, 1, 1)
    hexes[1] = hexes[1][[4, 5, 6, 7, 0, 1, 2, 3]]  # top and bottom swapped: mirrored
    with pytest.raises(InputError, match=r"element 1 \(nodes"):
        check_hex_jacobians(nodes, hexes)


def test_meshio_round_trip(tmp_path):
    nodes, hexes = structured_hex_mesh(0.01, 0.02, 0.005, 2, 3, 4, origin=(-0.005, -0.01, 0))
    path = _write(tmp_path / "box.vtu", nodes, [("hexahedron", hexes)])
    n2, h2 = read_hex_mesh(path)
    np.testing.assert_array_equal(n2, nodes)
    np.testing.assert_array_equal(h2, hexes)
    assert h2.dtype == np.int64


def test_read_drops_unused_nodes_and_ignores_surface_cells(tmp_path):
    nodes, hexes = structured_hex_mesh(1.0, 1.0, 1.0, 1, 1, 1)
    extra = np.vstack([[[5.0, 5.0, 5.0]], nodes])  # unused node first: indices shift by one
    quads = np.array([[0, 1, 2, 3]]) + 1
    path = _write(tmp_path / "m.vtu", extra, [("hexahedron", hexes + 1), ("quad", quads)])
    n2, h2 = read_hex_mesh(path)
    np.testing.assert_array_equal(n2, nodes)
    np.testing.assert_array_equal(h2, hexes)


def test_read_rejects_other_volume_cells(tmp_path):
    nodes = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    path = _write(tmp_path / "tet.vtu", nodes, [("tetra", np.array([[0, 1, 2, 3]]))])
    with pytest.raises(InputError, match="1 tetra"):
        read_hex_mesh(path)


def test_read_rejects_inverted_element(tmp_path):
    nodes, hexes = structured_hex_mesh(2.0, 1.0, 1.0, 2, 1, 1)
    hexes[1] = hexes[1][[0, 3, 2, 1, 4, 7, 6, 5]]  # clockwise ordering
    path = _write(tmp_path / "bad.vtu", nodes, [("hexahedron", hexes)])
    with pytest.raises(InputError, match="the 2nd hexahedron of the file ") as err:
        read_hex_mesh(path)
    assert "bad.vtu" in str(err.value)


def test_read_missing_and_unreadable_files(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        read_hex_mesh(tmp_path / "nope.vtu")
    junk = tmp_path / "junk.vtu"
    junk.write_text("not a mesh")
    with pytest.raises(InputError, match="could not be read"):
        read_hex_mesh(junk)


def test_nodes_on_plane_and_edge_length():
    nodes, hexes = structured_hex_mesh(0.004, 0.002, 0.001, 4, 2, 1)
    top = nodes_on_plane(nodes, 2, 0.001, tol=1e-12)
    assert len(top) == 5 * 3 and np.all(nodes[top, 2] == 0.001)
    assert top.dtype == np.int64 and np.all(np.diff(top) > 0)
    assert len(nodes_on_plane(nodes, 0, 0.0)) == 3 * 2
    assert mean_edge_length(nodes, hexes) == pytest.approx(0.001)
    with pytest.raises(InputError):
        nodes_on_plane(nodes, 3, 0.0)
