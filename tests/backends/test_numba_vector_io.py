"""The element pass's 8-wide node gather and force scatter (kernels/element.py: gather8, scatter8).

Both are LLVM-level intrinsics; their results must be the scalar loops' to the bit: the gather
copies values, and the scatter adds each element's forces onto its buffer row in element order,
so elements sharing a row (a node at the same corner of two elements of one group of 8, as in a
mirrored mesh) sum in the same order. The reference here is a plain Python loop.
"""

import numpy as np
import pytest

pytest.importorskip("numba")

from cfm_backends.numba_explicit.kernels import element, layout

B, NF = layout.BLOCK, layout.NF


def _mesh(rng, ne: int, nn: int, e0: int, shared: bool):
    """A random corner table (nodes or buffer rows below nn); with ``shared``, rows repeated within
    the groups of 8 the kernels take from e0 on (the same node at the same corner of two elements
    of one group, as in a mirrored mesh), and none repeated otherwise."""
    if shared:
        conn = rng.integers(0, nn, size=(ne, 8)).astype(np.int32)
        conn[e0 + 3, :] = conn[e0, :]
        conn[e0 + 5, 2] = conn[e0 + 4, 2]
        conn[e0 + 15, 7] = conn[e0 + 8, 7]
        conn[e0 + 12, :] = conn[e0 + 9, :]
    else:   # each corner's column a permutation: no row twice within a group
        conn = np.stack([rng.permutation(nn)[:ne] for _ in range(8)], axis=1).astype(np.int32)
    return conn


@pytest.mark.parametrize("n", [32, 8, 13, 5])
def test_gather_is_the_scalar_copy(n):
    rng = np.random.default_rng(1)
    ne, nn, e0 = 80, 90, 40
    conn = _mesh(rng, ne, nn, e0, shared=True)
    x, v = rng.normal(size=(nn, 3)), rng.normal(size=(nn, 3))
    wk = np.full(layout.W_N * B, np.nan)
    element.gather_corners(wk, x, v, conn, e0, n)
    for a in range(8):
        for i in range(n):
            nd = conn[e0 + i, a]
            got = [wk[(layout.W_G + 6 * a + c) * B + i] for c in range(6)]
            assert got == [*x[nd], *v[nd]]
        for c in range(6):                                     # columns >= n untouched
            row = (layout.W_G + 6 * a + c) * B
            assert np.isnan(wk[row + n:row + B]).all()


@pytest.mark.parametrize("n", [32, 8, 13, 5])
@pytest.mark.parametrize("shared", [False, True])
def test_scatter_adds_in_element_order_to_the_bit(n, shared):
    rng = np.random.default_rng(2)
    ne, rows, e0 = 72, 80, 32
    slot = _mesh(rng, ne, rows, e0, shared)
    groups = [slot[e0 + g:e0 + min(g + 8, n), a] for g in range(0, n, 8) for a in range(8)]
    assert any(len(set(grp)) < len(grp) for grp in groups) == shared     # the case is there, or not
    wk = rng.normal(size=layout.W_N * B) * 10.0 ** rng.integers(-8, 8, size=layout.W_N * B)
    fb = rng.normal(size=rows * NF)
    want = fb.copy()
    for a in range(8):
        for i in range(n):
            r = int(slot[e0 + i, a]) * NF
            for c in range(6):
                want[r + c] += wk[(layout.W_FN + c) * B + i]
        element.scatter_corner(wk, fb, slot, e0, a, n)
    assert np.array_equal(fb, want)


def test_the_intrinsics_refuse_other_array_types():
    """The IR reads int32 corner tables and C-contiguous float64 arrays; anything else is a typing
    error, not a wrong read."""
    from numba.core.errors import TypingError

    wk = np.zeros(layout.W_N * B)
    x = np.zeros((20, 3))
    with pytest.raises(TypingError):
        element.gather_corners(wk, x, x, np.zeros((8, 8), dtype=np.int64), 0, 8)
    with pytest.raises(TypingError):
        element.scatter_corner(wk, np.zeros(20 * NF, dtype=np.float32), np.zeros((8, 8), dtype=np.int32), 0, 0, 8)
