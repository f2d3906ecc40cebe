"""verification.calculix: the CalculiX rows judge what issue 22 sets (synthetic runs, no ccx needed)."""

import numpy as np
import pytest

from cfm_core.simulation.result import Result
from verification import calculix


def _drop_run(peak_g, duration, ok=True):
    t = np.linspace(0.0, 0.012, 601)
    y = np.where(t < duration, peak_g * 9.80665 * np.sin(np.pi * np.clip(t / duration, 0, 1)), 0.0)
    return {"ok": ok, "t": t, "y": y, "backend": "x", "message": "" if ok else "boom", "wall": 1.0,
            "summary": {"peak_g": peak_g, "duration": duration}}


@pytest.mark.parametrize("peak, dur, passed, why", [(56.0, 0.0107, True, ""),
                                                     (54.0, 0.0107, False, "peak difference"),
                                                     (56.5, 0.0112, False, "contact duration")])
def test_drop_row_applies_3_percent_peak_and_5_percent_duration(peak, dur, passed, why):
    r = calculix._drop_row("drop", _drop_run(56.69, 0.01064), _drop_run(peak, dur))
    assert r["passed"] is passed and why in r["error"]
    assert r["tol_peak"] == 0.03 and r["tol_duration"] == pytest.approx(0.05 * 0.01064)


def test_drop_row_names_a_failed_run():
    r = calculix._drop_row("drop", _drop_run(56.69, 0.01064), _drop_run(0, 0.01, ok=False))
    assert r["passed"] is False and "boom" in r["error"]


def _neo(t, f):
    return {"ok": True, "message": "", "result": Result(t=np.asarray(t), backend="calculix", steps=len(t) - 1,
                                                       wall_time=0.0, contact_force=np.asarray(f))}


def test_native_drop_row_compares_the_shared_increments_only():
    t = np.arange(16) * 5e-5
    f = np.r_[0.0, np.linspace(0.2, 4.0, 15)]
    t2 = np.r_[t[:14], 6.625e-4, 7e-4]  # the runs part after increment 13
    f2 = np.r_[f[:14], 9.0, 9.0]
    r = calculix._native_drop_row("neo", _neo(t, f), _neo(t2, f2))
    assert r["passed"] and r["shared_increments"] == 13 and r["peak_diff"] == 0.0
    f3 = f2.copy()
    f3[5] *= 1 + 1e-5  # a difference on a shared increment fails the 1e-6 rule
    assert not calculix._native_drop_row("neo", _neo(t, f), _neo(t2, f3))["passed"]
    short = calculix._native_drop_row("neo", _neo(t[:6], f[:6]), _neo(t[:6], f[:6]))
    assert not short["passed"] and "10 needed" in short["error"]


def test_no_rows_unless_calculix_is_selected_and_available():
    assert calculix.rows([{"name": "calculix", "status": "not selected"}], cache=None) == []
    assert calculix.rows([], cache=None) == []


def test_the_ci_gate_passes_only_a_report_with_every_calculix_row_passed(tmp_path, capsys):
    import json

    def report(rows):
        p = tmp_path / "report.json"
        p.write_text(json.dumps({"agreement": rows}))
        return p

    good = [{"check": f"calculix check {i}", "case": "c", "passed": True, "error": ""} for i in range(calculix.ROWS)]
    other = {"check": "scene", "case": "x", "passed": False, "error": "not ours"}
    assert calculix.main(["--check", str(report(good + [other]))]) == 0
    assert "all 6 passed" in capsys.readouterr().out
    bad = good[:-1] + [{"check": "calculix drop", "case": "drop 8 mm", "passed": False, "error": "peak 4 % beyond 0.03"}]
    assert calculix.main(["--check", str(report(bad))]) == 1
    assert "calculix drop / drop 8 mm: FAILED: peak 4 % beyond 0.03" in capsys.readouterr().out
    assert calculix.main(["--check", str(report(good[:3]))]) == 1
    assert "3 calculix rows in the report, 6 expected" in capsys.readouterr().out
    assert calculix.check_report(report(good[:-1] + [dict(good[0], passed=None)])) == ["calculix check 0 / c: not judged"]
