"""The quick verification suite, run in-process into a temporary directory (CI: ~3 minutes on 2 cores).

A study: it runs with ``--runslow`` (the default suite stays under 10 minutes on 2 cores); CI runs it
after the default suite (``.ci/run``), and ``cfm verify`` runs the same suite from the command line.

CI states the backends it requires with $CFM_VERIFY_REQUIRE (default here: all four, which
``pip install -e ".[all,test]"`` installs); a missing one fails the suite.
"""

import json
import os

import pytest

from cfm_verification.agreement import SHARED, TRUTH_POINT
from cfm_verification.stability import KNOWN_DEFECTS

pytestmark = pytest.mark.slow

REQUIRED = [s for s in os.environ.get("CFM_VERIFY_REQUIRE", "numpy,numba,torch,skfem").split(",") if s]


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    from cfm_verification.suite import run_suite

    out = tmp_path_factory.mktemp("verify-quick")
    rep = run_suite("quick", None, out, progress=None, require=REQUIRED)
    return out, rep


def test_verdict_is_passed_but_for_the_declared_known_defects(quick):
    """Nothing skipped, every required backend present; the only failures are the declared known
    defects (each must still fail: a fixed defect is removed from KNOWN_DEFECTS)."""
    _, rep = quick
    assert rep["incomplete"] == [], rep["incomplete"]
    known = [m for m in rep["failed"] if any(m.startswith(k) for k in KNOWN_DEFECTS)]
    unexpected = [m for m in rep["failed"] if m not in known]
    assert not unexpected, "checks failed:\n" + "\n".join(unexpected)
    gone = [k for k in KNOWN_DEFECTS if not any(m.startswith(k) for m in rep["failed"])
            and k.split(" / ")[-1] in {b["name"] for b in rep["inventory"] if b["status"] == "available"}]
    assert not gone, f"known defects no longer present (remove them from KNOWN_DEFECTS): {gone}"
    assert rep["verdict"] == ("FAILED" if known else "PASSED")
    assert rep["checks"] > 80


def test_every_backend_is_checked_against_an_independent_truth(quick):
    _, rep = quick
    pointers = {b["name"] for b in rep["inventory"] if b["status"] == "available" and b["can_point"]}
    assert {"numpy", "numba", "torch", "skfem"} <= pointers
    truth_rows = [r for r in rep["agreement"] if r["check"] == "material point" and r["a"] == TRUTH_POINT]
    assert {r["b"] for r in truth_rows} == pointers  # the numpy reference included
    assert all(r["passed"] and r["rel_l2"] <= 1e-10 for r in truth_rows)
    self_checks = [r for r in rep["agreement"] if r["check"] == "truth self-check"]
    assert len(self_checks) == 8 and all(r["passed"] for r in self_checks)
    runners = {b["name"] for b in rep["inventory"] if b["status"] == "available" and b["can_run"]}
    qs = {r["b"] for r in rep["agreement"] if r["check"] == "single element vs quasi-static uniaxial"}
    assert qs == runners


def test_no_row_compares_a_code_path_with_itself_without_saying_so(quick):
    _, rep = quick
    for r in rep["agreement"]:
        extent = SHARED.get(("material point" if r["check"] == "material point" else "scene", *sorted((r["a"], r["b"]))))
        if r["a"] == r["b"]:
            assert r["pair"] in ("energy", "run")  # a run's own energy balance, not a comparison
        elif extent and extent[0] == "all":
            assert r["informational"] and r["pair"] == "shared code" and "shared code" in r["error"]
        elif extent:
            assert r["shared"] == extent[1] and not r["informational"]
    assert any(r["informational"] for r in rep["agreement"])  # numpy and skfem's point driver are labelled


def test_scene_agreement_uses_time_of_peak_and_duration(quick):
    _, rep = quick
    drop = [r for r in rep["agreement"] if r["check"].startswith("drop test") and r["pair"] == "explicit-explicit"]
    assert drop and all(r["t_peak_diff"] is not None and r["duration_diff"] is not None for r in drop)
    assert all(abs(r["t_peak_diff"]) <= r["tol_t_peak"] for r in drop)
    assert all(r["ends_loaded_1"] < 0.02 and r["ends_loaded_2"] < 0.02 for r in drop)


def test_stability_rows_state_and_meet_their_expected_outcome(quick):
    _, rep = quick
    for r in rep["stability"]:
        assert r["expected"] in ("completes",) or r["expected"].startswith("diagnostic:")
        key = f"stability / {r['case']} / {r['backend']}"
        if key in KNOWN_DEFECTS:
            assert r["passed"] is False and "above the 1 % rule" in r["verdict"]
        else:
            assert r["passed"] is True, r["verdict"]
            if r["kind"] == "scene":
                assert r["energy_error"] <= 0.01


def test_drucker_and_stored_paper_results_are_in_the_verdict(quick):
    _, rep = quick
    rows = {r["check"]: r for r in rep["drucker_checks"]}
    assert rows["cfm: U''(J) lost at J = 1.29 (Ogden beta = 9)"]["passed"]
    assert "J = 1.2" in rows["cfm: U''(J) lost at J = 1.29 (Ogden beta = 9)"]["reason"]
    stored = rep["paper"]["checks"]
    assert len(stored) == 1 and stored[0]["passed"] and stored[0]["commit"]
    assert all(abs(d) <= 1e-3 for d in stored[0]["differences"].values())


def test_report_files_agree_with_the_verdict(quick):
    out, rep = quick
    md = (out / "report.md").read_text()
    assert f"**Result: {rep['verdict']}** (exit {rep['exit_code']}" in md
    for m in rep["failed"]:
        assert f"- {m}" in md
    data = json.loads((out / "report.json").read_text())
    assert data["verdict"] == rep["verdict"] and data["failed"] == rep["failed"]
    assert data["commit"] == rep["commit"] and len(data["commit"]) >= 40
    assert "Fastest to 1 % error (peak and rel L2, against the reference above)" in md
    wp = {s["label"]: s for s in rep["work_precision"]}
    assert wp["small drop test 20x20x6 mm"]["reference"].startswith("Richardson extrapolation")
    figures = sorted(rep["figures"])
    assert {f.split("_")[0] for f in figures} >= {"agreement", "workprecision", "drucker", "paper.png"}
    for f in figures:
        assert f in md and (out / f).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
