"""The check-cost benchmark (cfm_verification.benchmarks.checks) runs on a small drop test and its
numpy and numba monitors agree (it asserts their reports are equal)."""

import pytest

pytest.importorskip("numba")


def test_the_check_benchmark_times_every_row_on_a_coarse_drop_test(capsys):
    from cfm_verification.benchmarks import checks

    times = checks.main(["--size", "0.002", "--repeat", "2"])
    assert set(times) == {"numpy", "numba, 1 thread", "numba, 2 threads"}
    assert all(0.0 < t < 1e4 for t in times.values())
    assert "same report" in capsys.readouterr().out
