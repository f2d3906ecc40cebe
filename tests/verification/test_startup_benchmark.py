"""The end-to-end benchmark of a warm ``cfm drop-test`` (benchmarks/startup.py): its phases add up to
the measured total, and its instrumentation still finds the functions that bound them."""

import pytest

from cfm_verification.benchmarks import startup

pytest.importorskip("numba")


def test_phases_add_up_to_the_total():
    t = {"start": 10.05, "imported": 10.2, "model0": 10.25, "model1": 10.27, "run0": 10.28, "numba": 10.4,
         "run1": 12.0, "save0": 12.02, "plot0": 12.05, "mpl": 12.3, "plot1": 12.45, "save1": 12.47}
    p = startup.phases(10.0, 12.5, {"t": t, "run": {"kernels": 0.3, "solve": 1.2}})
    assert p["total"] == pytest.approx(2.5)
    assert sum(p[k] for k, _ in startup.PHASES) == pytest.approx(2.5, abs=1e-12)
    assert p["run_other"] == pytest.approx(12.0 - 10.4 - 0.3 - 1.2)
    assert p["write"] == pytest.approx(0.45 - 0.4) and p["exit"] == pytest.approx(0.03)
    assert "target < 2 s: not met" in startup.report({"phases": p, "totals": [2.5], "script": [2.4]})


def test_instrumented_run_of_a_small_drop_test():
    """A real run in a fresh process: every phase found (none negative), the sum is the total."""
    p, modules = startup.instrumented(0.004, 0.002)
    assert all(p[k] > -1e-3 for k, _ in startup.PHASES), p
    assert sum(p[k] for k, _ in startup.PHASES) == pytest.approx(p["total"], abs=1e-9)
    assert p["solve"] > 0 and p["mpl"] > 0 and "cfm_core.cli" in modules
    c = p["cpu"]
    assert all(c[k] > -1e-3 for k, _ in startup.CPU_PHASES), c
    assert sum(c[k] for k, _ in startup.CPU_PHASES) == pytest.approx(c["total"], abs=1e-9)
