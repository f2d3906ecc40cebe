"""Hexahedral meshes: structured generation, reading (Abaqus .inp files with cfm's own reader,
:mod:`cfm_core.scene.abaqus_inp`; other formats with meshio), node sets, volumes, Jacobians.

All coordinates are in m, volumes in m^3. Connectivity follows the meshio/VTK hexahedron order:
nodes 0-3 are the bottom face counter-clockwise seen from +z, nodes 4-7 the top face directly
above them, so that a well-formed element has a positive Jacobian everywhere.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import InputError

# Reference coordinates (xi, eta, zeta) of the 8 nodes of the trilinear hexahedron, VTK order.
HEX_REFERENCE = np.array(
    [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
     [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]],
    dtype=np.float64,
)

# Cell blocks that carry no volume (boundary markers written by mesh generators): ignored on read.
_SURFACE_CELL_TYPES = {"vertex", "line", "line3", "triangle", "triangle6", "quad", "quad8", "quad9"}



def meshio_read(path: Path):
    """``meshio.read(path)``, its failures as one InputError and its own printing kept off the terminal.

    meshio raises many exception types, and for a file it cannot place it prints "Error: Couldn't
    read file ..." and calls ``sys.exit(1)``; both become one paragraph naming the file and
    meshio's reason. An Abaqus ``.inp`` file (any case of the suffix) is read by cfm's own reader,
    :func:`cfm_core.scene.abaqus_inp.read_inp` (meshio's refused ``TYPE=c3d8r``, failed on
    ``*NODE, INPUT=...`` and dropped the elements after a comment line), whose InputError names the
    line.

    Parameters
    ----------
    path : pathlib.Path
        The mesh file.

    Returns
    -------
    meshio.Mesh
        The mesh as read.

    Raises
    ------
    InputError
        meshio cannot read the file, or cfm's reader an .inp file (naming the line).
    """
    import contextlib
    import io

    import meshio

    if Path(path).suffix.lower() == ".inp":
        from .abaqus_inp import read_inp

        return read_inp(path)
    said = io.StringIO()
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            return meshio.read(path)
    except (Exception, SystemExit) as exc:  # meshio raises many types and may even sys.exit(1)
        printed = " ".join(said.getvalue().split())
        reason = printed if isinstance(exc, SystemExit) or not str(exc).strip() else " ".join(str(exc).split())
        reason = reason.removeprefix("Error: ") or type(exc).__name__
        raise InputError(f"mesh file '{path}' could not be read by meshio ({reason[:300]}). Use a format meshio "
                         f"reads (.vtu, .msh, ...) or an Abaqus .inp file (read by cfm itself), with a suffix that "
                         f"names it.") from None


def _ordinal(n: int) -> str:
    """1 -> '1st', 2 -> '2nd', 3 -> '3rd', 11 -> '11th', 22 -> '22nd'."""
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


class MeshNames:
    """How messages name the hexahedra of a mesh and their nodes.

    A mesh read from a file is named as its user knows it: by the file's own labels where it has
    them (an Abaqus .inp file's element and node numbers, ``INSTANCE.NUMBER`` in an assembly),
    otherwise the hexahedra by their place in the file (1-based: "the 5th hexahedron of the
    file") and the nodes by their 0-based point index in the file (as VTK, ParaView and meshio
    count them), before unused points are dropped and coincident ones merged. A mesh made in
    memory (no file) is named by its 0-based rows.

    Parameters
    ----------
    corners : ndarray, shape (e, 8)
        Per hexahedron its nodes: the file's point indices (a file), or the rows (in memory).
    labels : cfm_core.scene.abaqus_inp.Labels, optional
        The file's node and element numbers (the Abaqus reader's ``file_labels``).
    blocks : sequence of (int, int), optional
        Per hexahedron block of the file, in order: its cell-block index and its first hexahedron.
    from_file : bool
        Whether the mesh was read from a file (default: made in memory).
    """

    def __init__(self, corners, labels=None, blocks=(), from_file: bool = False):
        self.corners = np.asarray(corners)
        self.labels = labels
        self.blocks = list(blocks)
        self.from_file = from_file

    def _label(self, e: int) -> str:
        block, first = max((b for b in self.blocks if b[1] <= e), key=lambda b: b[1])
        return self.labels.element(block, e - first)

    def element(self, e: int, with_nodes: bool = False) -> str:
        """Hexahedron ``e`` (0-based row), optionally with its nodes.

        E.g. "element 105 (the 2nd hexahedron of the file; nodes 1010, 1011, ...)" (labels), "the 2nd
        hexahedron of the file (points 9, 10, ... of the file, 0-based)", "element 1 (nodes [9, 10, ...])"
        (in memory).
        """
        rows = self.corners[e].tolist()
        if not self.from_file:
            return f"element {e} (nodes {rows})" if with_nodes else f"element {e}"
        nth = f"the {_ordinal(e + 1)} hexahedron of the file"
        if self.labels is not None:
            nodes = "; nodes " + ", ".join(self.labels.node(i) for i in rows) if with_nodes else ""
            return f"element {self._label(e)} ({nth}{nodes})"
        return f"{nth} (points {', '.join(str(i) for i in rows)} of the file, 0-based)" if with_nodes else nth

    def elements(self, indices, more: bool = False) -> str:
        """Several hexahedra (0-based rows), ``more``: followed by ", ...".

        E.g. "elements 101, 102, ..." (labels), "the 1st, 2nd, ... hexahedra of the file", "elements 0, 1, ..."
        (in memory).
        """
        rows = [int(e) for e in indices]
        tail, plural = (", ..." if more else ""), len(rows) > 1 or more
        word = "elements" if plural else "element"
        if not self.from_file:
            return f"{word} {', '.join(map(str, rows))}{tail}"
        nths = f"the {', '.join(_ordinal(e + 1) for e in rows)}{tail} {'hexahedra' if plural else 'hexahedron'} of the file"
        if self.labels is not None:
            return f"{word} {', '.join(self._label(e) for e in rows)}{tail} ({nths})"
        return nths

    def corner(self, e: int, a: int) -> str:
        """Corner ``a`` (0-7, in node order) of hexahedron ``e``: "5th node (1001)", or "corner 4" in memory."""
        if not self.from_file:
            return f"corner {a}"
        i = int(self.corners[e, a])
        return f"{_ordinal(a + 1)} node ({self.labels.node(i) if self.labels is not None else f'point {i}'})"


def _shape_gradients(points: np.ndarray) -> np.ndarray:
    """dN_a/dxi_k of the trilinear shape functions at reference points (p, 3) -> (p, 8, 3)."""
    r = HEX_REFERENCE
    p = np.asarray(points, dtype=np.float64)
    f = 1.0 + p[:, None, :] * r[None, :, :]  # (p, 8, 3): 1 + xi_k * r_ak
    g = np.empty_like(f)
    g[..., 0] = r[None, :, 0] * f[..., 1] * f[..., 2]
    g[..., 1] = r[None, :, 1] * f[..., 0] * f[..., 2]
    g[..., 2] = r[None, :, 2] * f[..., 0] * f[..., 1]
    return g / 8.0


def hex_jacobians(nodes: np.ndarray, hexes: np.ndarray,
                  points: np.ndarray | None = None) -> np.ndarray:
    """Jacobian determinants det(dx/dxi) (m^3 per unit reference volume, i.e. volume/8 for a cube).

    points: (p, 3) reference coordinates; default: the centre then the 8 corners (p = 9).
    Returns (e, p). A value <= 0 means an inverted, degenerate or wrongly ordered element.
    """
    if points is None:
        points = np.vstack([np.zeros((1, 3)), HEX_REFERENCE])
    dn = _shape_gradients(points)
    x = np.asarray(nodes, dtype=np.float64)[np.asarray(hexes)]  # (e, 8, 3)
    jac = np.einsum("eai,pak->epik", x, dn)  # (e, p, 3, 3): dx_i/dxi_k
    return np.linalg.det(jac)


def element_volumes(nodes: np.ndarray, hexes: np.ndarray) -> np.ndarray:
    """Exact volume (m^3) of each trilinear hexahedron, shape (e,).

    det J of a trilinear map is at most quadratic in each reference coordinate, so the 2x2x2
    Gauss rule (exact up to cubic per coordinate, weights 1) integrates it exactly.
    """
    g = 1.0 / math.sqrt(3.0)
    gauss = HEX_REFERENCE * g
    return hex_jacobians(nodes, hexes, gauss).sum(axis=1)


def structured_hex_mesh(lx: float, ly: float, lz: float, nx: int, ny: int, nz: int,
                        origin=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Box [ox, ox+lx] x [oy, oy+ly] x [oz, oz+lz] (m) split into nx * ny * nz equal hexahedra.

    Returns nodes (n, 3) float64 in m, n = (nx+1)(ny+1)(nz+1), node (i, j, k) at index
    i + (nx+1) * (j + (ny+1) * k); and hexes (nx*ny*nz, 8) int64 in VTK order (positive volume).
    The box faces hold exactly ox and ox + lx (as float64 computes them), so node sets on them
    can use tight tolerances.
    """
    for name, val in (("lx", lx), ("ly", ly), ("lz", lz)):
        if isinstance(val, bool) or not isinstance(val, (int, float, np.floating, np.integer)) \
                or not math.isfinite(val) or val <= 0:
            raise InputError(f"mesh size {name} = {val!r} m is invalid: it must be a finite "
                             f"number > 0 m.")
    for name, val in (("nx", nx), ("ny", ny), ("nz", nz)):
        if isinstance(val, bool) or not isinstance(val, (int, np.integer)) or val < 1:
            raise InputError(f"element count {name} = {val!r} is invalid: it must be an "
                             f"integer >= 1.")
    if len(origin) != 3 or not all(math.isfinite(float(o)) for o in origin):
        raise InputError(f"mesh origin = {origin!r} m is invalid: it must be three finite "
                         f"numbers (m).")
    ox, oy, oz = (float(o) for o in origin)
    xs = ox + np.linspace(0.0, float(lx), nx + 1)
    ys = oy + np.linspace(0.0, float(ly), ny + 1)
    zs = oz + np.linspace(0.0, float(lz), nz + 1)
    z, y, x = np.meshgrid(zs, ys, xs, indexing="ij")  # x varies fastest
    nodes = np.column_stack([x.ravel(), y.ravel(), z.ravel()])

    def idx(i, j, k):
        return i + (nx + 1) * (j + (ny + 1) * k)

    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    i, j, k = i.ravel(), j.ravel(), k.ravel()
    hexes = np.column_stack([
        idx(i, j, k), idx(i + 1, j, k), idx(i + 1, j + 1, k), idx(i, j + 1, k),
        idx(i, j, k + 1), idx(i + 1, j, k + 1), idx(i + 1, j + 1, k + 1), idx(i, j + 1, k + 1),
    ]).astype(np.int64)
    return nodes, hexes


def _hexahedron_blocks(mesh) -> tuple[list[np.ndarray], list[tuple[int, int]]]:
    """The hexahedron blocks of a meshio mesh and, per block, (its cell-block index, its first hexahedron);
    empty blocks (an ``*ELEMENT`` line without data) left out."""
    blocks, where = [], []
    for b, block in enumerate(mesh.cells):
        if block.type == "hexahedron" and len(block.data):
            where.append((b, sum(len(x) for x in blocks)))
            blocks.append(np.asarray(block.data, dtype=np.int64))
    return blocks, where


def _file_names(mesh, hexes: np.ndarray, where) -> MeshNames:
    """How messages name the hexahedra of a mesh read from a file (its labels, when the reader gave them)."""
    return MeshNames(hexes, getattr(mesh, "file_labels", None), where, from_file=True)


def file_mesh_names(path) -> MeshNames:
    """How messages name the hexahedra of the mesh file ``path`` and their nodes (:class:`MeshNames`), in the
    order :func:`read_hex_mesh` and :func:`read_cell_sets` count them; for a message, the file is read again.

    Parameters
    ----------
    path : str or Path
        A mesh file :func:`read_hex_mesh` has read.

    Returns
    -------
    MeshNames
        The file's labels (Abaqus .inp), else the hexahedra's places in the file.
    """
    mesh = meshio_read(Path(path))
    blocks, where = _hexahedron_blocks(mesh)
    return _file_names(mesh, np.vstack(blocks) if blocks else np.zeros((0, 8), dtype=np.int64), where)


def read_hex_mesh(path, merge: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Read a hexahedral mesh file; return (nodes (n, 3) in m, hexes (e, 8) int64).

    An Abaqus .inp file is read by cfm's own reader (:func:`cfm_core.scene.abaqus_inp.read_inp`),
    every other format by meshio (:func:`meshio_read`).

    Only ``hexahedron`` volume cells are accepted; vertex, line, triangle and quad blocks
    (boundary markers from mesh generators) are ignored; any other cell type is an InputError
    naming what was found. Nodes used by no hexahedron are dropped and the rest renumbered.
    The mesh must be one body (:func:`check_one_body`): coincident nodes that are not shared are
    merged when ``merge`` is True and refused otherwise; disconnected parts are refused.
    An element listed twice is refused (:func:`check_duplicate_cells`).
    Every element must have a positive Jacobian at its centre and its 8 corners (VTK node order);
    otherwise an InputError names the first bad element. The messages name elements and nodes as
    the file does (:class:`MeshNames`: an .inp file's element and node numbers, else the nth
    hexahedron of the file and its 0-based point indices). Coordinates are taken as metres.

    Parameters
    ----------
    path : str or Path
        A mesh file: Abaqus .inp, or a format meshio reads (.vtu, .msh, ...).
    merge : bool
        Merge coincident nodes the elements do not share (default: refuse such a mesh).

    Returns
    -------
    nodes : ndarray, shape (n, 3)
        Coordinates (m).
    hexes : ndarray, shape (e, 8)
        Connectivity, int64, VTK order.

    Raises
    ------
    InputError
        Unreadable file, other cell types, a mesh that is not one body, a bad Jacobian.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"mesh file '{path}' does not exist; give the path of a hexahedral mesh file "
                         f"(Abaqus .inp, or a format meshio reads: .vtu, .msh, ...).")
    mesh = meshio_read(path)
    found = {}
    for block in mesh.cells:
        found[block.type] = found.get(block.type, 0) + len(block.data)
    blocks, where = _hexahedron_blocks(mesh)
    found_text = ", ".join(f"{n} {t}" for t, n in found.items()) or "no cells"
    other = sorted(t for t in found if t != "hexahedron" and t not in _SURFACE_CELL_TYPES)
    if other or not blocks:
        raise InputError(f"mesh file '{path}' must contain only 8-node 'hexahedron' volume cells, "
                         f"but it contains {found_text}. Re-mesh with linear hexahedra.")
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"mesh file '{path}' has points of shape {points.shape}; 3D points (n, 3) "
                         f"in m are required.")
    hexes = np.vstack(blocks)
    names = _file_names(mesh, hexes, where)
    used = np.unique(hexes)
    if used[0] < 0 or used[-1] >= len(points):
        bad = int(used[0]) if used[0] < 0 else int(used[-1])
        raise InputError(f"mesh file '{path}' refers to point {bad} (0-based) but has only "
                         f"{len(points)} points.")
    renumber = np.full(len(points), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    nodes = points[used].copy()
    hexes = renumber[hexes]
    if not np.all(np.isfinite(nodes)):
        raise InputError(f"mesh file '{path}' has non-finite (NaN or inf) node coordinates.")
    source = f"mesh file '{path}'"
    nodes, hexes = check_one_body(nodes, hexes, source=source, merge=merge, names=names)
    check_duplicate_cells(hexes, source=source, names=names)
    check_hex_jacobians(nodes, hexes, source=source, names=names)
    return nodes, hexes


def check_duplicate_cells(hexes: np.ndarray, source: str = "the mesh", names: MeshNames | None = None) -> None:
    """Refuse hexahedra listed more than once (the same 8 nodes, in any order).

    A file whose hexahedron block is written twice (a gmsh volume in two physical groups) ran as a
    specimen twice as dense and twice as stiff: each element's mass and forces were counted twice
    (54.5 g for 67.3 g, exit 0).

    Parameters
    ----------
    hexes : ndarray, shape (e, 8)
        Connectivity (after merging coincident nodes).
    source : str
        What the mesh is, for the message.
    names : MeshNames, optional
        How to name the elements (a file's labels); default: their 0-based rows.

    Raises
    ------
    InputError
        Naming the count and the first pair.
    """
    names = names or MeshNames(hexes)
    key = np.sort(np.asarray(hexes), axis=1)
    _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
    if counts.size and counts.max() > 1:
        dup = np.flatnonzero(counts > 1)
        twin = int(first[dup[0]])
        other = int(np.flatnonzero((key == key[twin]).all(axis=1))[1])
        extra = int(np.sum(counts[dup] - 1))
        raise InputError(f"{source} lists {extra} {'hexahedron' if extra == 1 else 'hexahedra'} more than once (the "
                         f"same 8 nodes): {names.element(other)} repeats {names.element(twin)}. Each would count "
                         f"its mass and stiffness twice. Write each element once (a volume exported in two physical groups, or "
                         f"a block written twice, does this); parts are named by cell sets over one block.")


def coincident_nodes(nodes: np.ndarray, tol: float) -> np.ndarray:
    """Groups of coincident nodes.

    Parameters
    ----------
    nodes : ndarray, shape (n, 3)
        Node coordinates (m).
    tol : float
        Distance (m) below which two nodes are the same.

    Returns
    -------
    ndarray, shape (n,)
        For each node the smallest index of its group (itself when it has no twin), int64.
    """
    from scipy.spatial import cKDTree

    nodes = np.asarray(nodes, dtype=np.float64)
    target = np.arange(len(nodes), dtype=np.int64)
    if len(nodes) < 2:
        return target
    pairs = cKDTree(nodes).query_pairs(r=tol, output_type="ndarray")
    if pairs.size == 0:
        return target
    # union-find over the pairs, each group represented by its smallest index
    parent = np.arange(len(nodes), dtype=np.int64)

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b in pairs:
        ra, rb = root(int(a)), root(int(b))
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    return np.array([root(i) for i in range(len(nodes))], dtype=np.int64)


def connected_parts(hexes: np.ndarray, n_nodes: int) -> np.ndarray:
    """Connected parts of a mesh (elements sharing a node are connected).

    Parameters
    ----------
    hexes : ndarray, shape (e, 8)
        Connectivity.
    n_nodes : int
        Number of nodes.

    Returns
    -------
    ndarray, shape (e,)
        Label of the part each element belongs to (0, 1, ...).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    hexes = np.asarray(hexes, dtype=np.int64)
    ne = hexes.shape[0]
    rows = np.repeat(np.arange(ne), hexes.shape[1])
    graph = coo_matrix((np.ones(rows.size), (rows, ne + hexes.ravel())), shape=(ne + n_nodes, ne + n_nodes))
    _, labels = connected_components(graph, directed=False)
    return labels[:ne]


def check_one_body(nodes: np.ndarray, hexes: np.ndarray, source: str = "mesh", merge: bool = False,
                   rel_tol: float = 1e-6, names: MeshNames | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A mesh that is one body: (nodes (n', 3) in m, hexes (e, 8)), coincident nodes merged on request.

    Parameters
    ----------
    nodes : ndarray, shape (n, 3)
        Node coordinates (m).
    hexes : ndarray, shape (e, 8)
        Connectivity (VTK order).
    source : str
        What the mesh is, for messages.
    merge : bool
        Merge nodes closer than ``rel_tol`` x the mean edge length (a mesh exported element by
        element, or layers that do not share nodes); False: refuse such a mesh.
    rel_tol : float
        Distance (-, relative to the mean edge length) below which two nodes are the same.
    names : MeshNames, optional
        How to name the elements (a file's labels); default: their 0-based rows.

    Returns
    -------
    nodes, hexes
        Unchanged, or with coincident nodes merged and unused nodes dropped.

    Raises
    ------
    InputError
        Coincident unmerged nodes (without ``merge``: their count and the hint to merge), or parts
        that share no node (their count and element counts): a specimen in pieces carries no load
        from one to the next, and a drop test on it gives a tiny, wrong peak without any error.
    """
    nodes = np.asarray(nodes, dtype=np.float64)
    hexes = np.asarray(hexes, dtype=np.int64)
    tol = rel_tol * mean_edge_length(nodes, hexes)
    target = coincident_nodes(nodes, tol)
    dup = int(np.count_nonzero(target != np.arange(len(nodes))))
    if dup:
        if not merge:
            raise InputError(
                f"{source}: {dup} node(s) lie on top of other nodes (within {tol:.3g} m) without being shared "
                f"by the elements, so the mesh is not one body (it was exported element by element, or its "
                f"layers or parts do not share nodes): loads would not pass between the elements. Merge them "
                f"in the mesher, or set [specimen] merge_nodes = true to merge them on reading.")
        used, hexes = np.unique(target[hexes], return_inverse=True)
        hexes = hexes.reshape(-1, 8).astype(np.int64)
        nodes = nodes[used]
        degenerate = np.flatnonzero([len(set(h)) < 8 for h in hexes.tolist()])
        if degenerate.size:
            raise InputError(f"{source}: merging coincident nodes collapsed "
                             f"{(names or MeshNames(hexes)).element(int(degenerate[0]))} "
                             f"({degenerate.size} in total): some of its own corners coincide; fix the mesh.")
    labels = connected_parts(hexes, len(nodes))
    counts = np.bincount(labels)
    if counts.size > 1:
        sizes = ", ".join(str(int(c)) for c in sorted(counts, reverse=True)[:6]) + (", ..." if counts.size > 6 else "")
        raise InputError(
            f"{source}: the mesh is {counts.size} disconnected parts (elements per part: {sizes}) that share no "
            f"node: a specimen must be one body. Remove the stray parts, or connect them (if their nodes "
            f"coincide, set [specimen] merge_nodes = true).")
    return nodes, hexes


def check_hex_jacobians(nodes: np.ndarray, hexes: np.ndarray, source: str = "mesh",
                        names: MeshNames | None = None) -> None:
    """Refuse a mesh with an element whose Jacobian is <= 0 at its centre or a corner.

    Parameters
    ----------
    nodes : ndarray, shape (n, 3)
        Coordinates (m).
    hexes : ndarray, shape (e, 8)
        Connectivity, VTK order.
    source : str
        What the mesh is, for the message.
    names : MeshNames, optional
        How to name the element and its nodes (a file's labels); default: their 0-based rows.

    Raises
    ------
    InputError
        Naming the first bad element, its nodes, where its Jacobian is lowest and the count.
    """
    dets = hex_jacobians(nodes, hexes)
    bad = np.flatnonzero(np.any(dets <= 0.0, axis=1))
    if bad.size:
        names = names or MeshNames(hexes)
        e = int(bad[0])
        p = int(np.argmin(dets[e]))
        where = "centre" if p == 0 else names.corner(e, p - 1)
        raise InputError(
            f"{source}: {names.element(e, with_nodes=True)} has a non-positive Jacobian "
            f"{dets[e, p]:.3g} m^3 at its {where}; {bad.size} bad element(s) in total. The "
            f"element is inverted, degenerate or not in the hexahedron node order of VTK and Abaqus C3D8 "
            f"(its first four nodes the bottom face, counter-clockwise seen from +z, its last four the top "
            f"face above them); fix the mesh."
        )


def nodes_on_plane(nodes: np.ndarray, axis: int, value: float, tol: float = 1e-9) -> np.ndarray:
    """Indices (int64, ascending) of nodes with |x_axis - value| <= tol; value and tol in m."""
    if axis not in (0, 1, 2):
        raise InputError(f"axis = {axis!r} is invalid: use 0, 1 or 2 (x, y, z).")
    return np.flatnonzero(np.abs(np.asarray(nodes)[:, axis] - value) <= tol).astype(np.int64)


#: The 6 faces of a VTK hexahedron (local corners).
HEX_FACES = ((0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7))


def facing_nodes(nodes: np.ndarray, hexes: np.ndarray, up: bool, cos_min: float = 0.5) -> np.ndarray:
    """Nodes (int64, ascending) of the boundary faces whose outward normal points up (``up``) or down,
    within arccos(cos_min) of the z axis (60 degrees by default): the surface an impactor from above,
    or the plate below, can touch.

    A boundary face belongs to one element only; its outward normal is its area vector (the cross
    product of its diagonals) turned away from the element's centroid. On a specimen with a flat top
    these are the nodes of the plane z = top; on a mesh whose top is curved, sloped or not exactly
    flat they are all the nodes of the top surface (picking the plane z = top left the others
    without contact: a top lowered by 0.1 um left 1 node of 49, and the impactor passed through).

    Parameters
    ----------
    nodes : ndarray, shape (n, 3)
        Coordinates (m).
    hexes : ndarray, shape (e, 8)
        Connectivity, VTK order.
    up : bool
        Upward-facing (True) or downward-facing faces.
    cos_min : float
        Smallest |n_z| / |n| of a face counted (-).

    Returns
    -------
    ndarray
        Node indices.
    """
    x = np.asarray(nodes, dtype=np.float64)
    hexes = np.asarray(hexes, dtype=np.int64)
    faces = hexes[:, np.array(HEX_FACES)].reshape(-1, 4)                  # (6 e, 4)
    owner = np.repeat(np.arange(len(hexes)), 6)
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    boundary = counts[inverse.ravel()] == 1
    f, owner = faces[boundary], owner[boundary]
    p = x[f]                                                                # (b, 4, 3)
    normal = np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1])
    outward = p.mean(axis=1) - x[hexes[owner]].mean(axis=1)
    normal *= np.where(np.einsum("ij,ij->i", normal, outward) < 0.0, -1.0, 1.0)[:, None]
    nz = normal[:, 2] / np.maximum(np.linalg.norm(normal, axis=1), 1e-300)
    pick = nz >= cos_min if up else nz <= -cos_min
    return np.unique(f[pick]).astype(np.int64)


def mean_edge_length(nodes: np.ndarray, hexes: np.ndarray) -> float:
    """Mean length (m) of the 12 edges of all elements (the characteristic element size)."""
    x = np.asarray(nodes)[np.asarray(hexes)]
    pairs = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
             (0, 4), (1, 5), (2, 6), (3, 7)]
    a, b = np.array(pairs).T
    return float(np.linalg.norm(x[:, a] - x[:, b], axis=-1).mean())


def read_cell_sets(path) -> dict[str, np.ndarray]:
    """Named sets of the hexahedra of a mesh file (cell sets, physical groups, integer cell data).

    The indices count the hexahedra in the order :func:`read_hex_mesh` returns them (the
    hexahedron blocks of the file one after the other). Names come from, in this order:
    the cell sets (Abaqus ``*ELSET``, read by :mod:`cfm_core.scene.abaqus_inp`; gmsh 4 physical
    groups and the others meshio reads as ``cell_sets``); gmsh 2 physical
    groups (``gmsh:physical`` tags named by ``field_data``; a tag without a name is
    ``physical_TAG``); every other integer cell-data array ARRAY except ``gmsh:geometrical``,
    one set per value V named ``ARRAY_V`` (e.g. a VTU array ``part`` with ids 1 and 2 gives
    ``part_1`` and ``part_2``). A name already taken keeps its first meaning.

    Parameters
    ----------
    path : str or Path
        A mesh file: Abaqus .inp, or a format meshio reads.

    Returns
    -------
    dict of str to ndarray
        Set name to the sorted, unique hexahedron indices (int64) it holds; sets holding no
        hexahedron are left out.

    Raises
    ------
    InputError
        The file cannot be read (:func:`meshio_read`).
    """
    mesh = meshio_read(Path(path))
    offsets, start = {}, 0
    for b, block in enumerate(mesh.cells):
        if block.type == "hexahedron":
            offsets[b] = start
            start += len(block.data)
    sets: dict[str, np.ndarray] = {}

    def add(name, per_block):
        if name in sets:
            return
        idx = [np.asarray(sel, dtype=np.int64).ravel() + offsets[b] for b, sel in enumerate(per_block)
               if b in offsets and sel is not None and len(sel)]
        if idx:
            sets[name] = np.unique(np.concatenate(idx))

    for name, per_block in (mesh.cell_sets or {}).items():
        add(str(name), per_block)
    names = {int(v[0]): str(k) for k, v in (mesh.field_data or {}).items() if len(v) > 1 and int(v[1]) == 3}
    for array, per_block in (mesh.cell_data or {}).items():
        if array == "gmsh:geometrical":
            continue
        values = [np.asarray(d) if b in offsets else None for b, d in enumerate(per_block)]
        ints = [v for v in values if v is not None]
        if not ints or not all(v.ndim == 1 and np.issubdtype(v.dtype, np.integer) for v in ints):
            continue
        for tag in np.unique(np.concatenate(ints)).tolist():
            name = (names.get(tag, f"physical_{tag}") if array == "gmsh:physical" else f"{array}_{tag}")
            add(name, [None if v is None else np.flatnonzero(v == tag) for v in values])
    return sets
