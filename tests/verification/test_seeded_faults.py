"""Seeded faults: the quick suite, run on the sections a fault touches, must FAIL (or be
INCOMPLETE) with a message naming the check, for every deliberately broken variant:

- a 1 % stress error in one backend's material evaluation (numba);
- the Prony decay removed from the shared recurrence (numpy reference and skfem's point driver);
- a drop-test run truncated just after its peak (torch);
- a backend that is not available (torch), and the same with --require;
- an energy leak (numba's internal energy 3 % low);
- a budget that skips runs.

Each fault has a control: the same configuration without the fault does not fail.
"""

import dataclasses

import numpy as np
import pytest

from cfm_backends.numba_explicit import NumbaExplicitBackend
from cfm_backends.torch_explicit import TorchExplicitBackend
from cfm_core.cli import main
from cfm_core.material import prony
from cfm_verification import runs as vruns
from cfm_verification.suite import run_suite


@pytest.fixture(autouse=True)
def _no_required_from_env(monkeypatch):
    monkeypatch.delenv("CFM_VERIFY_REQUIRE", raising=False)


def _suite(tmp_path, backends, sections, **kw):
    return run_suite("quick", backends, tmp_path / "out", progress=None, sections=sections, require=[], **kw)


def _assert_fails(rep, *needles):
    assert rep["verdict"] == "FAILED" and rep["exit_code"] == 1, rep["failed"]
    hits = [m for m in rep["failed"] if all(n in m for n in needles)]
    assert hits, f"no failure message names {needles}: {rep['failed']}"
    md = (rep_out := rep["_out"]) and (rep_out / "report.md").read_text()
    assert "**Result: FAILED**" in md and hits[0].split(":")[0] in md


def _run(tmp_path, backends, sections, **kw):
    rep = _suite(tmp_path, backends, sections, **kw)
    rep["_out"] = tmp_path / "out"
    return rep


def _scaled(material, factor=1.01):
    """Every parameter in Pa times ``factor``: the stress of these materials scales with it."""
    pa = {p.name: material.values[p.name] * factor for p in material.spec.energy_parameters if p.unit == "Pa"}
    return material.with_values(**pa)


def test_control_point_and_scenes_on_numba_and_torch(tmp_path):
    rep = _run(tmp_path, ["numba", "torch"], ["point", "scenes"])
    assert rep["verdict"] == "INCOMPLETE" and rep["failed"] == [], rep["failed"]
    assert all("section not run" in m for m in rep["incomplete"])  # only the sections left out


def test_one_percent_stress_error_in_one_backend_fails(tmp_path, monkeypatch):
    point, run = NumbaExplicitBackend.point, NumbaExplicitBackend.run
    monkeypatch.setattr(NumbaExplicitBackend, "point", lambda self, m, t, F: point(self, _scaled(m), t, F))
    monkeypatch.setattr(NumbaExplicitBackend, "run", lambda self, model, **kw: run(
        self, dataclasses.replace(model, material=_scaled(model.material)), **kw))
    rep = _run(tmp_path, ["numba"], ["point", "scenes"])
    _assert_fails(rep, "agreement / material point", "numba", "rel L2")
    _assert_fails(rep, "single element", "numba vs truth (quasi-static")


def test_prony_decay_removed_from_the_shared_update_fails(tmp_path, monkeypatch):
    orig = prony.step_factors
    monkeypatch.setattr(prony, "step_factors", lambda dt, g, tau: (np.ones_like(np.asarray(tau, float)),
                                                                    orig(dt, g, tau)[1]))
    rep = _run(tmp_path, ["numpy", "skfem"], ["point"])
    _assert_fails(rep, "material point", "viscoelastic", "numpy vs truth")
    _assert_fails(rep, "material point", "viscoelastic", "skfem vs truth")  # shared code no longer hides it
    assert not [m for m in rep["failed"] if "elastic /" in m and "viscoelastic" not in m]


def test_run_truncated_after_the_peak_fails(tmp_path, monkeypatch):
    orig = vruns.run_scene

    def truncated(scene, backend, **options):
        out = orig(scene, backend, **options)
        if backend == "torch" and scene.type == "drop-test" and out["ok"]:
            k = int(np.argmax(out["y"])) + 3
            out = {**out, "t": out["t"][:k], "y": out["y"][:k]}
        return out

    monkeypatch.setattr(vruns, "run_scene", truncated)
    rep = _run(tmp_path, ["numba", "torch"], ["scenes"])
    _assert_fails(rep, "drop test", "torch vs numba", "ends while still loaded")
    assert any("duration differs" in m for m in rep["failed"])


def test_unavailable_backend_is_incomplete_and_fails_when_required(tmp_path, monkeypatch):
    monkeypatch.setattr(TorchExplicitBackend, "available", lambda self: (False, "seeded: torch missing"))
    rep = _run(tmp_path, None, ["point"])
    assert rep["verdict"] == "INCOMPLETE" and rep["exit_code"] == 4 and rep["failed"] == []
    assert any("backend 'torch' is unavailable: seeded: torch missing" in m for m in rep["incomplete"])
    rep = run_suite("quick", None, tmp_path / "req", progress=None, sections=["point"], require=["torch"])
    assert rep["verdict"] == "FAILED" and any("required backend 'torch'" in m for m in rep["failed"])


def test_energy_leak_fails(tmp_path, monkeypatch):
    run = NumbaExplicitBackend.run

    def leaky(self, model, **kw):
        res = run(self, model, **kw)
        res.energies["internal"] = res.energies["internal"] * 0.97
        return res

    monkeypatch.setattr(NumbaExplicitBackend, "run", leaky)
    rep = _run(tmp_path, ["numba"], ["scenes"])
    _assert_fails(rep, "agreement / energy balance", "numba", "above the 1 % rule")


def test_budget_that_skips_runs_is_incomplete_through_the_cli(tmp_path, capsys):
    """The whole quick suite (every section) on numba with a budget of 0.01 s: exit 4, never 0."""
    code = main(["verify", "--quick", "--backends", "numba", "--require", "", "--budget", "0.01",
                 "--out", str(tmp_path / "b")])
    out = capsys.readouterr().out
    assert code == 4, out
    assert "verify: INCOMPLETE" in out and "verify: FAILED" not in out and "section not run" not in out
    assert "skipped: estimated" in out and "budget of 0.01 s" in out
    assert "**Result: INCOMPLETE** (exit 4" in (tmp_path / "b" / "report.md").read_text()


def test_cli_exit_code_is_one_for_a_failed_check(tmp_path, monkeypatch, capsys):
    orig = prony.step_factors
    monkeypatch.setattr(prony, "step_factors", lambda dt, g, tau: (np.ones_like(np.asarray(tau, float)),
                                                                    orig(dt, g, tau)[1]))
    code = main(["verify", "--quick", "--backends", "numpy", "--require", "", "--only", "point",
                 "--out", str(tmp_path / "c")])
    assert code == 1 and "verify: FAILED agreement / material point" in capsys.readouterr().out


def test_report_json_records_the_code_plugins_and_gold_inputs(tmp_path):
    """report.json says which code made it (commit, dirty, source digest), where every backend and
    material came from, and the input digests of every gold case (old report: the commit string only)."""
    import json

    from cfm_core import fingerprint
    from cfm_verification.gold.store import case_names, inputs

    rep = _suite(tmp_path, ["numpy"], ["point"])
    doc = json.loads((tmp_path / "out" / "report.json").read_text())
    prov = doc["provenance"]
    assert prov["code"] == fingerprint.code_state() and prov["code"]["source_digest"]
    assert prov["backends"]["numpy"]["distribution"] == "cfm-materials"
    assert prov["materials"]["cfm-septa"]["definition_digest"]
    assert set(prov["gold"]) == set(case_names())
    assert prov["gold"]["point-cfm-septa-visco-uniaxial-numpy"] == inputs("point-cfm-septa-visco-uniaxial-numpy")
    assert prov["code"]["source_digest"] in (tmp_path / "out" / "report.md").read_text()
    assert rep["provenance"] == prov


def test_a_second_report_replaces_the_first_one_whole(tmp_path, monkeypatch):
    """`--only drucker` then `--only point` into one folder left drucker_*.png beside a report saying that
    section was not run; the report is now published whole, replacing the earlier one and its figures."""
    from cfm_verification import report

    write = report.write

    def with_a_figure(out, rep, runs):
        write(out, rep, runs)
        (out / "drucker_earlier.png").write_bytes(b"an earlier run's figure")

    monkeypatch.setattr(report, "write", with_a_figure)
    _suite(tmp_path, ["numpy"], ["point"])
    assert (tmp_path / "out" / "drucker_earlier.png").is_file()
    monkeypatch.setattr(report, "write", write)
    _suite(tmp_path, ["numpy"], ["point"])
    assert not (tmp_path / "out" / "drucker_earlier.png").exists() and (tmp_path / "out" / "report.md").is_file()
