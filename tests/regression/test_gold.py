"""Gold-standard regression suite: every named case recomputed and compared with its stored
reference (verification/gold/data/*.json) to a relative tolerance of 1e-3.

An intended change: ``python -m cfm_verification.gold`` prints the differences,
``python -m cfm_verification.gold --update`` rewrites the references after their independent checks.
"""

import copy

import pytest

from cfm_verification.gold import RTOL
from cfm_verification.gold.cases import CASES
from cfm_verification.gold.record import compare
from cfm_verification.gold.store import case_names, compute, load, why_rewrite

SCENES = {"point", "single-element", "relaxation", "drop-test"}


def test_the_suite_spans_scenes_materials_and_backends():
    assert len(CASES) >= 40 and len(set(case_names())) == len(CASES)
    assert {c.scene for c in CASES} == SCENES
    materials = {c.overrides.get("material", "cfm") for c in CASES}
    assert materials == {"cfm", "cfm-septa", "neo-hookean", "ogden", "mooney-rivlin"}
    assert {c.backend for c in CASES} == {"numpy", "numba", "torch", "skfem"}
    assert any(c.overrides.get("elastic") for c in CASES) and any(not c.overrides.get("elastic") for c in CASES)
    drops = [c for c in CASES if c.scene == "drop-test"]
    assert len({c.overrides.get("thickness") for c in drops}) >= 3
    assert len({c.overrides.get("velocity", 1.0) for c in drops}) >= 3
    assert any("friction" in c.overrides for c in drops)
    assert len({c.overrides.get("element_size", 1e-3) for c in drops}) >= 3


@pytest.mark.parametrize("name", case_names())
def test_stored_reference_is_complete(name):
    doc = load(name)
    assert doc is not None, f"no stored reference for {name}: python -m cfm_verification.gold --update --only {name}"
    assert doc["commit"] and doc["commit"] != "unknown" and doc["rtol"] == RTOL
    assert doc["checked"], "each reference says where it was checked independently"
    why = why_rewrite(name, doc)
    assert why is None, (f"{name}: the stored reference is {why}; rewrite it from a commit: "
                         f"python -m cfm_verification.gold --update --only {name}")
    rec = doc["record"]
    assert rec["steps"] > 0 and rec["dt_max"] > 0 and rec["samples"]
    if rec["kind"] != "point":
        assert rec["energies"] and "energy_error" in rec


@pytest.mark.parametrize("name", case_names())
def test_gold_case_reproduces_its_reference(name):
    doc = load(name)
    assert doc is not None
    rec, _ = compute(name)
    diffs = compare(rec, doc["record"], RTOL)
    assert not diffs, (f"{name} differs from its reference (produced at {doc['commit']}, checked: {doc['checked']}):\n"
                       + "\n".join(diffs) + "\nIf intended: python -m cfm_verification.gold --update --only " + name)


def test_compare_detects_a_small_change():
    """The comparison itself can fail: a 2e-3 change of the peak, of one sample, of an energy, or
    one step more is reported; a 2e-4 change is not."""
    doc = load("drop-cfm-6mm-numba")
    rec = doc["record"]
    assert compare(copy.deepcopy(rec), rec, RTOL) == []
    for mutate, needle in ((lambda r: r.__setitem__("peak", r["peak"] * 1.002), "peak"),
                           (lambda r: r["samples"].__setitem__(5, r["samples"][5] + 2e-3 * abs(r["peak"])), "samples"),
                           (lambda r: r["energies"]["internal"].__setitem__("max_abs", r["energies"]["internal"]["max_abs"] * 1.002), "internal"),
                           (lambda r: r.__setitem__("steps", int(r["steps"] * 1.002) + 1), "steps"),
                           (lambda r: r["summary"].__setitem__("duration", r["summary"]["duration"] * 1.002), "duration")):
        new = copy.deepcopy(rec)
        mutate(new)
        diffs = compare(new, rec, RTOL)
        assert diffs and needle in diffs[0], (needle, diffs)
    small = copy.deepcopy(rec)
    small["peak"] *= 1.0002
    assert compare(small, rec, RTOL) == []
