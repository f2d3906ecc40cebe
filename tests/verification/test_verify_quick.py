"""The quick verification suite, run in-process into a temporary directory (CI: under 3 minutes)."""

import json

import pytest


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    from cfm_verification.suite import run_suite

    out = tmp_path_factory.mktemp("verify-quick")
    rep = run_suite("quick", None, out, progress=None)
    return out, rep


def test_agreement_within_tolerances(quick):
    _, rep = quick
    failed = [f"{r['check']} / {r['case']}: {r['a']} vs {r['b']} rel L2 {r['rel_l2']} peak {r['peak_diff']} "
              f"(limits {r['tol_rel_l2']} / {r['tol_peak']}) {r.get('error', '')}" for r in rep["agreement"] if not r["passed"]]
    assert not failed, "agreement checks out of tolerance:\n" + "\n".join(failed)
    assert any(r["check"] == "material point" for r in rep["agreement"])


def test_stability_cases(quick):
    _, rep = quick
    failed = [f"{r['case']} on {r['backend']}: {r['verdict']}" for r in rep["stability"] if r["passed"] is False]
    assert not failed, "stability checks failed:\n" + "\n".join(failed)
    for r in rep["stability"]:
        assert r["verdict"].startswith(("completed: finite results", "stopped with a clear diagnostic", "not run"))


def test_report_contents(quick):
    out, rep = quick
    md = (out / "report.md").read_text()
    for heading in ("### Agreement table", "## Stability on stiff and extreme cases", "### Material stability (Drucker)",
                    "## Error against run time (work-precision)", "## Paper comparison"):
        assert heading in md
    assert "![work-precision" in md and any(f.startswith("workprecision_") for f in rep["figures"])
    for f in rep["figures"]:
        assert (out / f).stat().st_size > 1000
    assert "git commit: `" in md and rep["commit"]
    for key in ("platform", "cpu_count", "python", "numpy", "numba", "torch"):
        assert key in rep["machine"]
    data = json.loads((out / "report.json").read_text())
    assert data["mode"] == "quick" and data["passed"] == rep["passed"]
    assert "NaN" not in (out / "report.json").read_text()


def test_drucker_warnings_hydrostatic():
    from cfm_core.material.registry import make_material
    from cfm_verification.drucker import DruckerWarning, drucker_warnings
    from cfm_verification.histories import hydrostatic, uniaxial_compression

    mat = make_material("cfm")
    _, F = hydrostatic(J_end=1.5)
    with pytest.warns(DruckerWarning, match="U''"):
        msgs = drucker_warnings(mat, F)
    assert msgs and "J 1.29" in msgs[0]
    _, F = uniaxial_compression(stretch=0.7)
    assert drucker_warnings(mat, F, emit=False) == []
