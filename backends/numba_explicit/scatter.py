"""The plan of the conflict-free node scatter of the numba element pass (numpy, set-up only).

The element blocks are split into chunks of consecutive blocks, one parallel task each
(``kernels/element.py``). A chunk adds its element forces onto a force buffer of NF values per
row: row j (< n) belongs to node j and is written only by the chunk that touches node j first
(its owner); a chunk that touches a node an earlier chunk owns writes a halo row of its own
(rows n, n + 1, ...; in chunk order, then node order). The node loop adds a node's halo rows, in
chunk order, to its own row. With nodes numbered in first-touch order
(:func:`cfm_backends.explicit.renumber.first_touch`) each chunk owns a contiguous range of
rows, which it zeroes before adding to it.

The chunk count depends on the element count alone, never on the thread count, so that a run
gives the same bits with any number of threads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TARGET_BLOCKS = 32   # blocks per chunk at least (1024 elements of 32): the halo stays a few % of the nodes
MAX_CHUNKS = 64      # enough tasks for 16+ threads to share the load dynamically


@dataclass(frozen=True)
class ScatterPlan:
    """Arrays of the scatter (see the module docstring).

    slot : (e, 8) int64, the buffer row each element corner adds to; chunks : (c + 1, 3) int64,
    per chunk its first block, first owned row and first halo row (last row: the ends);
    hptr : (n + 1,) int64, hrow : (h,) int64, the CSR list of each node's halo rows;
    rows : int, the rows of the buffer (n + h).
    """

    slot: np.ndarray
    chunks: np.ndarray
    hptr: np.ndarray
    hrow: np.ndarray
    rows: int


def chunk_count(n_blocks: int) -> int:
    """Chunks for ``n_blocks`` element blocks: about TARGET_BLOCKS blocks each, 1 to MAX_CHUNKS."""
    return int(min(MAX_CHUNKS, max(1, n_blocks // TARGET_BLOCKS)))


def plan(hexes: np.ndarray, n_nodes: int, block: int, n_chunks: int | None = None,
         parts: list | None = None) -> ScatterPlan:
    """The scatter plan of a connectivity whose nodes are numbered in first-touch order.

    Parameters
    ----------
    hexes : (e, 8) ndarray of int
        Connectivity in the solver's (renumbered) order.
    n_nodes : int
        Number of nodes n (nodes of no element get a row that stays zero).
    block : int
        Elements per block (``kernels.layout.BLOCK``).
    n_chunks : int, optional
        Chunks (default :func:`chunk_count`; per part with ``parts``).
    parts : list of (int, int), optional
        Element ranges [first, end) of the parts (contiguous, in order, covering all elements):
        each part's elements are blocked on their own (its first element starts a block, its
        last block may be partial) and split into its own chunks, so that a chunk never spans
        two parts. Block numbers then count the parts' blocks in turn. Default: one part.

    Returns
    -------
    ScatterPlan

    Raises
    ------
    ValueError
        The nodes are not in first-touch order (an internal error: the solver renumbers them).
    """
    hexes = np.asarray(hexes, dtype=np.int64)
    ne = hexes.shape[0]
    eblk = np.zeros(ne, dtype=np.int64)                                     # block of each element
    bounds = [np.zeros(1, dtype=np.int64)]
    b0 = 0
    for ea, eb in (parts if parts is not None else [(0, ne)]):
        nblk = -(-(eb - ea) // block)
        nch = chunk_count(nblk) if n_chunks is None else int(max(1, min(n_chunks, nblk)))
        bounds.append(b0 + ((np.arange(1, nch + 1, dtype=np.int64) * nblk) // nch))  # first block of each chunk
        eblk[ea:eb] = b0 + np.arange(eb - ea) // block
        b0 += nblk
    bounds = np.concatenate(bounds)
    nch = bounds.size - 1
    ech = np.searchsorted(bounds, eblk, side="right") - 1                   # chunk of each element
    flat = hexes.ravel()
    used, first = np.unique(flat, return_index=True)
    owner = np.full(n_nodes, nch, dtype=np.int64)
    owner[used] = ech[first // 8]
    touched = used.size
    if touched and (used[-1] != touched - 1 or np.any(np.diff(owner[:touched]) < 0)):
        raise ValueError("scatter plan: the nodes are not numbered in first-touch order")
    own = np.searchsorted(owner[:touched], np.arange(nch + 1), side="left")  # first owned node per chunk
    cch = np.repeat(ech, 8)
    halo = owner[flat] != cch
    keys = np.unique(cch[halo] * n_nodes + flat[halo])                      # (chunk, node), chunk-major
    hch, hnode = np.divmod(keys, n_nodes)
    slot = flat.copy()
    slot[halo] = n_nodes + np.searchsorted(keys, cch[halo] * n_nodes + flat[halo])
    hfirst = n_nodes + np.searchsorted(hch, np.arange(nch + 1), side="left")
    chunks = np.ascontiguousarray(np.stack([bounds, own, hfirst], axis=1), dtype=np.int64)
    order = np.lexsort((hch, hnode))                                         # by node, then chunk
    hrow = (n_nodes + order).astype(np.int64)
    hptr = np.concatenate([[0], np.cumsum(np.bincount(hnode, minlength=n_nodes))]).astype(np.int64)
    return ScatterPlan(np.ascontiguousarray(slot.reshape(ne, 8)), chunks, hptr, np.ascontiguousarray(hrow),
                       int(n_nodes + keys.size))
