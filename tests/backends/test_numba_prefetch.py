"""The element pass's software prefetch of the next block's state (kernels/element.py)."""

import numpy as np
import pytest

pytest.importorskip("numba")
from numba import njit

from cfm_backends.numba_explicit.kernels import element, layout


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 63, 576, layout.ED_N * layout.BLOCK, 1825])
@pytest.mark.parametrize("parts", [1, 3, 8])
def test_the_shares_tile_the_array_at_cache_lines(n, parts):
    """Every value of the stretch in exactly one part, in order, each non-empty part starting on a
    line."""
    share = njit(lambda n, j, parts: element.line_share(n, j, parts))
    bounds = [share(n, j, parts) for j in range(parts)]
    assert bounds[0][0] == 0 and bounds[-1][1] == n
    for (lo, hi), (lo2, _) in zip(bounds, bounds[1:]):
        assert hi == lo2
    assert all(lo <= hi and (lo % 8 == 0 or lo == n) for lo, hi in bounds)
    assert max(hi - lo for lo, hi in bounds) <= 8 * -(-n // (8 * parts))


def test_prefetch_touches_every_line_of_a_part_and_compiles_to_a_prefetch():
    """prefetch_part issues one prefetch per 64-byte line of its share (counted through a stand-in
    that records the indices) and the intrinsic is an x86 prefetch instruction, not a load."""
    @njit
    def lines(n, parts):
        seen = np.zeros(n, dtype=np.int64)
        for j in range(parts):
            lo, hi = element.line_share(n, j, parts)
            for r in range(lo, hi, 8):
                seen[r] += 1
        return seen

    seen = lines(layout.ED_N * layout.BLOCK, 8)
    assert np.array_equal(np.flatnonzero(seen), np.arange(0, seen.size, 8)) and seen.max() == 1

    @njit
    def touch(a):
        for r in range(0, a.size, 8):
            element.prefetch(a, r)
        return a[0]

    assert touch(np.arange(64.0)) == 0.0
    asm = "\n".join(touch.inspect_asm().values())
    assert "prefetch" in asm


def test_only_meshes_beyond_the_caches_prefetch():
    """The threshold counts blocks: the paper's 1 mm quarter (157 blocks) stays below it, the
    0.5 mm quarter (1 250 blocks) above."""
    assert -(-5000 // layout.BLOCK) < layout.PREFETCH_BLOCKS < 40000 // layout.BLOCK
