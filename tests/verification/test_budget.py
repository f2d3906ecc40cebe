"""The verification suite's time budget: cost estimates and skipped runs listed, not failed."""

import pytest

from cfm_core.scene.scene import builtin_scene
from cfm_verification.agreement import Budget, scene_agreement
from cfm_verification.stability import run_scene_cases


def _run(total, ok=True):
    return {"total": total, "ok": ok}


def test_estimate_scales_with_elements_thickness_and_speed():
    b = Budget(100.0)
    small = builtin_scene("drop-test").with_overrides(thickness=0.004, element_size=0.002)
    big = small.with_overrides(thickness=0.008)  # twice the layers and twice the duration
    assert b.estimate("x", big) == 0.0 and b.allows("x", big) == (True, "")  # nothing to estimate from
    run = _run(10.0)
    b.record("x", small, run)
    b.record("x", small, run)  # the same cached run is counted once
    assert b.spent["x"] == 10.0
    assert b.estimate("x", big) == pytest.approx(10.0 * 2 * 2)
    assert b.estimate("x", big.with_overrides(velocity=2.0)) == pytest.approx(20.0)
    assert b.allows("x", big)[0]  # 10 + 40 <= 100
    b.record("x", big, _run(60.0))
    ok, why = b.allows("x", big)
    assert not ok and "estimated 60 s" in why and "budget of 100 s" in why and "--budget" in why
    assert b.allows("other", big)[0]  # per backend


class _Cache:
    def __init__(self):
        self.calls = []

    def run(self, scene, backend, **options):
        self.calls.append(backend)
        return {"total": 50.0, "ok": True, "status": "completed", "message": "", "energy_error": 0.0,
                "summary": None}


def test_over_budget_runs_are_listed_as_skipped():
    drop = builtin_scene("drop-test").with_overrides(element_size=0.002)
    runners = [{"name": "slow", "kind": "implicit", "status": "available", "can_run": True, "reason": ""}]
    budget, cache = Budget(60.0), _Cache()
    scene_agreement("first", drop, runners, cache, budget)  # first run: always made
    rows, runs = scene_agreement("second", drop.with_overrides(thickness=0.016), runners, cache, budget)
    assert cache.calls == ["slow"] and runs == {}
    assert rows[0]["passed"] is None and rows[0]["error"].startswith("skipped: estimated")
    stab = [r for r in run_scene_cases(drop, runners, cache, 2e-3, budget) if r["backend"] == "slow"]
    # the 2 mm specimen (1/4 of the elements, 1/4 of the duration: estimated 3 s) still fits; the
    # full-size cases (estimated 50 s each, 50 s spent) do not
    ran = [r for r in stab if r["passed"] is not None]
    assert [r["case"] for r in ran] == ["2 mm specimen"] and cache.calls == ["slow", "slow"]
    assert all(r["verdict"].startswith("skipped: estimated") for r in stab if r["passed"] is None)
