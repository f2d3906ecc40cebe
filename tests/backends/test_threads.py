"""cfm_backends.threads.num_threads: the count set for the block, the caller's restored after it."""

import pytest

from cfm_backends.threads import num_threads


class Lib:
    """Stands in for numba / torch: records the counts set."""

    def __init__(self, n):
        self.n, self.calls = n, []

    def get_num_threads(self):
        return self.n

    def set_num_threads(self, n):
        self.calls.append(n)
        self.n = n


@pytest.mark.parametrize("threads, serial, inside", [(3, False, 3), (3, True, 3), (None, True, 1), (None, False, 8)])
def test_count_inside_and_restored_after(threads, serial, inside):
    lib = Lib(8)
    with num_threads(lib, threads, serial=serial):
        assert lib.n == inside
    assert lib.n == 8


def test_restored_when_the_run_raises():
    lib = Lib(4)
    with pytest.raises(ZeroDivisionError):
        with num_threads(lib, 1):
            assert lib.n == 1
            1 / 0
    assert lib.n == 4


def test_numba_count_restored():
    numba = pytest.importorskip("numba")
    before = numba.get_num_threads()
    with num_threads(numba, 1):
        assert numba.get_num_threads() == 1
    assert numba.get_num_threads() == before
