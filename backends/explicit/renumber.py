"""Renumbering of a model's nodes and elements for memory locality (numpy and scipy only).

The explicit solvers read the 8 corner nodes of every element (gather) and add the element forces
back onto them (scatter) every step. With elements processed in blocks, the cost of those
accesses is set by how compact the set of nodes a block touches is: numbered in the order a mesh
generator happened to write them, neighbouring elements can lie far apart in memory and on a
mesh of 10^5 - 10^6 elements every access misses the cache. Before a run the backends therefore
renumber the model once:

- elements along a space-filling curve over their centroids (``"morton"``: Z-order on 2^21
  cells per axis, so that 2^k consecutive elements fill a compact box), or in reverse
  Cuthill-McKee order of the element adjacency (``"rcm"``, scipy), or in the mesh's own order
  (``"none"``);
- nodes in the order the renumbered elements first touch them, so that each block of elements
  touches a compact range of node numbers (nodes of no element go last, in their own order).

The permutation is internal to a backend: :meth:`Renumbering.model` gives the renumbered model
the solver runs, and the maps here turn its node and element indices back into the user's
(outputs, error messages). Only the order of floating-point sums changes (round-off).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

METHODS = ("morton", "rcm", "none")


@dataclass(frozen=True)
class Renumbering:
    """A node and element permutation: internal index -> the user's.

    Parameters
    ----------
    elements : (e,) ndarray of int64
        User index of internal element i.
    nodes : (n,) ndarray of int64
        User index of internal node j.
    """

    elements: np.ndarray
    nodes: np.ndarray

    @property
    def node_index(self) -> np.ndarray:
        """(n,) int64: internal index of user node u (the inverse of ``nodes``)."""
        inv = np.empty_like(self.nodes)
        inv[self.nodes] = np.arange(self.nodes.size, dtype=np.int64)
        return inv

    def user_element(self, i: int) -> int:
        """The user's index of internal element ``i`` (int)."""
        return int(self.elements[int(i)])

    def user_node(self, j: int) -> int:
        """The user's index of internal node ``j`` (int)."""
        return int(self.nodes[int(j)])

    def to_user_nodes(self, a: np.ndarray) -> np.ndarray:
        """A per-node array (n, ...) in internal order, returned in the user's order (a copy)."""
        return np.asarray(a)[self.node_index]

    def to_user_elements(self, a: np.ndarray, axis: int = 0) -> np.ndarray:
        """A per-element array (internal order along ``axis``) returned in the user's order (a copy)."""
        a = np.asarray(a)
        out = np.empty_like(a)
        index = [slice(None)] * a.ndim
        index[axis] = self.elements
        out[tuple(index)] = a
        return out

    def frame_state_to_user(self, state: dict) -> dict:
        """A frame's stored state (``Result.frame_state`` entry: ``velocity`` (n, 3), ``prony_H``
        (k, e, 6), ``prony_S0`` (e, 6), scalars) in the user's node and element order. Per-part
        Prony state (lists, :func:`cfm_core.post.fields.part_prony_state`) is already in the user's
        order and passes through."""
        out = dict(state)
        if "velocity" in out:
            out["velocity"] = self.to_user_nodes(out["velocity"])
        if isinstance(out.get("prony_H"), np.ndarray):
            out["prony_H"] = self.to_user_elements(out["prony_H"], axis=1)
        if isinstance(out.get("prony_S0"), np.ndarray):
            out["prony_S0"] = self.to_user_elements(out["prony_S0"])
        return out

    def to_internal_nodes(self, a: np.ndarray) -> np.ndarray:
        """A per-node array (n, ...) in the user's order, returned in internal order (a copy)."""
        return np.asarray(a)[self.nodes]

    def model(self, model):
        """The renumbered copy of ``model`` (a :class:`cfm_core.scene.model.Model`): nodes,
        connectivity, fixed dofs, prescribed nodes, contact nodes and part elements in internal numbering; the
        rest shared with ``model``."""
        idx = self.node_index
        hexes = idx[np.asarray(model.hexes, dtype=np.int64)[self.elements]]
        fixed = np.asarray(model.fixed_dofs, dtype=np.int64).reshape(-1, 2).copy()
        fixed[:, 0] = idx[fixed[:, 0]]
        pr = model.prescribed
        if pr is not None:
            pr = dataclasses.replace(pr, nodes=idx[np.asarray(pr.nodes, dtype=np.int64)])
        parts = model.parts
        if parts:
            inv = np.empty_like(self.elements)
            inv[self.elements] = np.arange(self.elements.size, dtype=np.int64)
            parts = tuple(dataclasses.replace(p, elements=np.sort(inv[np.asarray(p.elements, dtype=np.int64)]))
                          for p in parts)
        return dataclasses.replace(
            model, parts=parts, nodes=np.ascontiguousarray(np.asarray(model.nodes, dtype=np.float64)[self.nodes]),
            hexes=np.ascontiguousarray(hexes), fixed_dofs=fixed, prescribed=pr,
            sphere_nodes=idx[np.asarray(model.sphere_nodes, dtype=np.int64)],
            plane_nodes=idx[np.asarray(model.plane_nodes, dtype=np.int64)])


def plan(nodes: np.ndarray, hexes: np.ndarray, method: str = "morton", groups: np.ndarray | None = None) -> Renumbering:
    """The renumbering of a mesh for locality; see the module docstring.

    Parameters
    ----------
    nodes : (n, 3) ndarray
        Reference coordinates (m).
    hexes : (e, 8) ndarray of int
        Connectivity.
    method : {"morton", "rcm", "none"}
        Element order: Z-order curve over the centroids, reverse Cuthill-McKee of the element
        adjacency (elements sharing a node), or the user's (the nodes are renumbered in
        first-touch order all the same).
    groups : (e,) ndarray of int, optional
        Part index of each element (:meth:`cfm_core.scene.model.Model.element_part`): the
        internal order is sorted by part first (stable), so that each part's elements form one
        contiguous range; the method orders the elements within a part.

    Returns
    -------
    Renumbering
        Element order and first-touch node order.

    Raises
    ------
    ValueError
        An unknown ``method`` (an internal choice, never user input).
    """
    nodes = np.asarray(nodes, dtype=np.float64)
    hexes = np.asarray(hexes, dtype=np.int64)
    n, ne = nodes.shape[0], hexes.shape[0]
    if method == "none" or ne == 0:
        order = np.arange(ne, dtype=np.int64)
    elif method == "morton":
        order = morton_order(nodes[hexes].mean(axis=1))
    elif method == "rcm":
        order = rcm_order(hexes, n)
    else:
        raise ValueError(f"renumbering method {method!r} is not one of {METHODS}")
    if groups is not None and ne:
        g = np.asarray(groups, dtype=np.int64)
        if g.max(initial=0) > 0:
            order = order[np.argsort(g[order], kind="stable")]
    return Renumbering(order.astype(np.int64), first_touch(hexes[order], n))


def first_touch(hexes: np.ndarray, n_nodes: int) -> np.ndarray:
    """(n,) int64: user node of each internal node, in the order the rows of ``hexes`` (already
    in internal element order) first use them; unused nodes last, in their own order."""
    flat = np.asarray(hexes, dtype=np.int64).ravel()
    used, at = np.unique(flat, return_index=True)
    first = np.full(n_nodes, flat.size, dtype=np.int64)
    first[used] = at
    return np.argsort(first, kind="stable").astype(np.int64)


def _spread(q: np.ndarray) -> np.ndarray:
    """The bits of q (< 2^21, uint64) spread to every third bit (Morton interleave)."""
    q = q & np.uint64(0x1FFFFF)
    q = (q | (q << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    q = (q | (q << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    q = (q | (q << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    q = (q | (q << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    q = (q | (q << np.uint64(2))) & np.uint64(0x1249249249249249)
    return q


def morton_order(points: np.ndarray) -> np.ndarray:
    """(m,) int64: the order of ``points`` (m, 3) (m) along a Z-order curve on a grid of 2^21
    cells per axis over their bounding box (cubic cells, so that the curve follows space, not
    the box's aspect ratio); ties keep their order."""
    p = np.asarray(points, dtype=np.float64)
    lo = p.min(axis=0)
    span = float((p.max(axis=0) - lo).max())
    scale = (2 ** 21 - 1) / span if span > 0.0 else 0.0
    q = np.floor((p - lo) * scale).astype(np.uint64)
    key = _spread(q[:, 0]) | (_spread(q[:, 1]) << np.uint64(1)) | (_spread(q[:, 2]) << np.uint64(2))
    return np.argsort(key, kind="stable").astype(np.int64)


def rcm_order(hexes: np.ndarray, n_nodes: int) -> np.ndarray:
    """(e,) int64: reverse Cuthill-McKee order of the elements (adjacent when they share a node)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    ne = hexes.shape[0]
    rows = np.repeat(np.arange(ne), hexes.shape[1])
    en = csr_matrix((np.ones(rows.size, dtype=np.int8), (rows, hexes.ravel())), shape=(ne, n_nodes))
    adj = (en @ en.T).tocsr()
    return np.asarray(reverse_cuthill_mckee(adj, symmetric_mode=True), dtype=np.int64)


def locality(hexes: np.ndarray, block: int = 32) -> float:
    """Mean number of distinct nodes touched per element over blocks of ``block`` consecutive
    elements (a measure of gather reuse: 1 + 1/block-ish for a perfect order, 8 with no reuse)."""
    hexes = np.asarray(hexes, dtype=np.int64)
    ne = hexes.shape[0]
    total = 0
    for b in range(0, ne, block):
        total += np.unique(hexes[b:b + block]).size
    return total / max(ne, 1)
