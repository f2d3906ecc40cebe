"""The independent truths, the union comparison, the verdict rules, expected stability outcomes,
the Drucker checks and the stored paper results: each check is shown to fail on a wrong input."""

import copy
import json

import numpy as np
import pytest

from cfm_core.material.kinematics import to_voigt
from cfm_core.material.registry import make_material
from cfm_verification import histories, truths
from cfm_verification.compare import compare_union
from cfm_verification.drucker import J_CONVEXITY_LIMIT, checks, stability_map
from cfm_verification.paper_compare import stored_check
from cfm_verification.stability import COMPLETES, judge
from cfm_verification.verdict import decide


@pytest.mark.parametrize("elastic", [True, False])
def test_hand_written_stress_equals_the_mpmath_reference(elastic):
    mat = make_material("cfm", elastic=elastic)
    p = truths.cfm_params(mat)
    rng = np.random.default_rng(3)
    Fs = [np.diag([0.6, 1.25, 1.3]), np.diag([0.8, 1.1, 1.1]), 0.9 * np.eye(3),
          np.eye(3) + 0.2 * rng.standard_normal((3, 3)), np.array([[1, 0.4, 0], [0, 1, 0], [0, 0, 1.0]])]
    for F in Fs:
        mp = truths.cauchy_mp(F, **p)
        S_iso, S_vol = truths.cfm_pk2_parts(F[None], **p)
        sig = F @ (S_iso + S_vol)[0] @ F.T / np.linalg.det(F)
        assert np.abs(sig - mp).max() <= 1e-9 * max(np.abs(mp).max(), 1.0)


def test_a_wrong_parameter_is_seen_by_the_mpmath_reference():
    p = truths.cfm_params(make_material("cfm", elastic=True))
    F = np.diag([1.3, 0.9, 0.85])
    S_iso, S_vol = truths.cfm_pk2_parts(F[None], **{**p, "k1": p["k1"] * 1.001})
    mp = truths.cauchy_mp(F, **p)
    assert np.abs(F @ (S_iso + S_vol)[0] @ F.T / np.linalg.det(F) - mp).max() > 1e-6 * np.abs(mp).max()


def test_summed_prony_integral_relaxes_a_held_step_as_g():
    gammas, taus = [0.45, 0.435, 0.094], [1e-3, 0.1, 10.0]
    t = np.concatenate([[0.0], np.logspace(-6, 2, 30)])
    S0 = np.repeat(np.diag([1.0, -2.0, 3.0])[None], t.size, axis=0)
    S = truths.prony_convolution(t, S0, gammas, taus)
    g = 1 - sum(gammas) + sum(a * np.exp(-t / b) for a, b in zip(gammas, taus))
    assert np.allclose(S[:, 2, 2] / 3.0, g, rtol=1e-13)


@pytest.mark.parametrize("name", list(histories.AGREEMENT))
def test_truth_matches_the_package_reference_and_sees_a_removed_decay(name, monkeypatch):
    from cfm_core.material import prony
    from cfm_core.material.reference import stress_history

    mat = make_material("cfm")
    t, F = histories.AGREEMENT[name]()
    truth = truths.stress_history(mat, t, F)
    ref = to_voigt(stress_history(mat, t, F))
    assert np.linalg.norm(ref - truth) / np.linalg.norm(truth) < 1e-10
    orig = prony.step_factors
    monkeypatch.setattr(prony, "step_factors", lambda dt, g, tau: (np.ones_like(np.asarray(tau, float)),
                                                                    orig(dt, g, tau)[1]))
    broken = to_voigt(stress_history(mat, t, F))
    assert np.linalg.norm(broken - truths.stress_history(mat, t, F)) / np.linalg.norm(truth) > 1e-3


def test_uniaxial_truth_agrees_with_the_package_solution():
    from cfm_core.simulation.point import uniaxial

    mat = make_material("cfm")
    t0, f0 = truths.uniaxial_force(mat, 100.0, 0.5, 1e-3, steps=100, hold=2e-3)
    t1, _, P, _ = uniaxial(mat, 100.0, 0.5, steps=100, hold=2e-3)
    assert np.allclose(t0, t1) and np.allclose(f0, P * 1e-6, rtol=1e-8, atol=1e-12 * abs(f0).max())


def _pulse(t, t0=0.0, width=4e-3):
    return np.where((t >= t0) & (t <= t0 + width), np.sin(np.pi * (t - t0) / width) ** 2, 0.0)


def test_union_comparison_sees_a_truncated_or_shifted_run():
    t = np.linspace(0, 6e-3, 301)
    a = _pulse(t)
    same = compare_union(t, a, t, a)
    assert same["rel_l2"] == 0 and same["t_peak_diff"] == 0 and same["duration_diff"] == 0
    k = int(np.argmax(a)) + 3
    cut = compare_union(t[:k], a[:k], t, a)
    assert cut["ends_loaded_1"] > 0.9 and cut["rel_l2"] > 0.3 and cut["duration_diff"] < -1.5e-3
    shifted = compare_union(t + 1e-4, a, t, a)
    assert shifted["t_peak_diff"] == pytest.approx(1e-4) and shifted["end_diff"] == pytest.approx(1e-4)


def test_verdict_rules():
    inv = [{"name": "a", "status": "available", "reason": ""}, {"name": "b", "status": "not selected", "reason": ""}]
    ok = {"agreement": [{"check": "c", "case": "x", "a": "t", "b": "a", "passed": True}]}
    assert decide(ok, inv)["verdict"] == "PASSED"
    skipped = {"agreement": ok["agreement"] + [{"check": "c", "case": "y", "a": "a", "b": "a", "passed": None,
                                                "error": "skipped: estimated 9 s"}]}
    v = decide(skipped, inv)
    assert v["verdict"] == "INCOMPLETE" and v["exit_code"] == 4 and "skipped: estimated 9 s" in v["incomplete"][0]
    info = {"agreement": ok["agreement"] + [{"check": "c", "case": "z", "a": "p", "b": "q", "passed": True,
                                             "informational": True}]}
    assert decide(info, inv)["checks"] == 1
    missing = inv + [{"name": "c", "status": "unavailable", "reason": "not installed"}]
    assert decide(ok, missing)["verdict"] == "INCOMPLETE"
    v = decide(ok, missing, required=["c"])
    assert v["verdict"] == "FAILED" and v["exit_code"] == 1 and "required backend 'c'" in v["failed"][0]
    assert decide(ok, inv, not_run_sections=["paper"])["verdict"] == "INCOMPLETE"
    bad = {"stability": [{"case": "k", "backend": "a", "passed": False, "verdict": "FAILURE: x"}]}
    assert decide(bad, inv)["failed"] == ["stability / k / a: FAILURE: x"]


def test_expected_outcomes_are_judged_both_ways():
    assert judge("completes", "energy 0.1 %", COMPLETES)[1]
    assert not judge("completes-out-of-tolerance", "energy 2 % above the 1 % rule", COMPLETES)[1]
    assert not judge("diagnostic", "NumericalError: overflow", COMPLETES)[1]
    assert judge("diagnostic", "NumericalError: fibre exponential overflows", "diagnostic: overflows")[1]
    assert not judge("diagnostic", "InputError: other", "diagnostic: overflows")[1]
    assert not judge("completes", "energy 0.1 %", "diagnostic: overflows")[1]
    assert not judge("failure", "raw exception", COMPLETES)[1]


def test_drucker_checks_pin_the_volumetric_limit():
    smap = stability_map(make_material("cfm"))
    rows = {r["check"]: r for r in checks({"cfm": smap})}
    assert all(r["passed"] for r in rows.values()), rows
    assert J_CONVEXITY_LIMIT == pytest.approx(1.2915, abs=1e-4)
    moved = copy.deepcopy(smap)
    iv = moved["paths"]["volumetric"]["U''(J)"]["intervals"]
    iv[0][0] += 0.05  # the loss would start at J = 1.47
    assert not {r["check"]: r for r in checks({"cfm": moved})}["cfm: U''(J) lost at J = 1.29 (Ogden beta = 9)"]["passed"]
    rows = checks({"cfm": smap, "broken": {"error": "ValueError: x"}})
    assert [r["passed"] for r in rows if "broken" in r["check"]] == [False]


class _Cache:
    def __init__(self, summary):
        self.summary = summary

    def run(self, scene, backend, **options):
        return {"ok": True, "summary": self.summary, "message": ""}


def test_stored_paper_results_need_a_stamp_and_a_reproduction(tmp_path):
    row = {"thickness": 0.008, "moduli": "long-term", "peak_g": 56.8, "t_peak": 5.5e-3, "duration": 1.076e-2,
           "steps": 1787}
    path = tmp_path / "results.json"
    path.write_text(json.dumps({"rows": [row]}))
    check, rows = stored_check("numba", _Cache(row), path)
    assert check["passed"] is False and "no commit stamp" in check["reason"] and rows == []
    path.write_text(json.dumps({"commit": "abc", "rows": [row]}))
    check, rows = stored_check("numba", _Cache(row), path)
    assert check["passed"] and rows
    check, rows = stored_check("numba", _Cache({**row, "peak_g": 56.8 * 1.002}), path)
    assert check["passed"] is False and "not reproduced" in check["reason"] and "peak_g" in check["reason"]


def test_scenes_beyond_the_paper_are_judged_by_issue_21s_implicit_explicit_limit():
    """The flat impactor's explicit-implicit pair: 3 % on the peak (issue 21), not the paper's
    drop test's 1 %; the paper's drop test keeps its own limit."""
    import numpy as np

    from cfm_core.scene.scene import builtin_scene
    from cfm_verification import agreement

    t = np.linspace(0.0, 0.01, 501)
    pulse = np.sin(np.pi * t / 0.01)

    class Cache:
        def run(self, scene, name):  # skfem 2 % below numba: within 3 %, beyond 1 %
            y = pulse * (0.98 if name == "skfem" else 1.0)
            return {"ok": True, "t": t, "y": y, "energy_error": 0.0, "message": "", "total": 0.0}

    backends = [{"name": "numba", "kind": "explicit"}, {"name": "skfem", "kind": "implicit"}]
    for scene, passed in ((builtin_scene("flat-impactor"), True), (builtin_scene("drop-test"), False)):
        rows, _ = agreement.scene_agreement("x", scene, backends, Cache())
        (pair,) = [r for r in rows if r.get("pair") not in ("energy",) and r["a"] != r["b"]]
        assert pair["passed"] is passed, pair
