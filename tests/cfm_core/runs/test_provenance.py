"""The provenance record (cfm_core.runs.provenance): what produced an output."""

import json

import pytest

from cfm_core import InputError
from cfm_core.material.registry import make_material
from cfm_core.runs import provenance as prov


def test_backend_record_resolves_every_default_and_names_the_distribution():
    rec = prov.backend_record("numba", {"hourglass": 0.05})
    assert rec["name"] == "numba" and rec["distribution"] == "cfm-materials"
    assert rec["options"]["hourglass"] == 0.05
    assert rec["options"]["safety"] == 0.9  # a default written out, so a repeat does not depend on it
    assert (rec["dtype"], rec["device"]) == ("float64", "cpu")
    t32 = prov.backend_record("torch", {"dtype": "float32"})
    assert t32["dtype"] == "float32" and t32["options"]["dtype"] == "float32"
    with pytest.raises(InputError, match="hourglas"):
        prov.backend_record("numba", {"hourglas": 0.05})


def test_material_record_names_terms_digest_and_overrides():
    base = prov.material_record(make_material("cfm"))
    stiff = prov.material_record(make_material("cfm", {"k2": 3.0}))
    assert [t["name"] for t in base["terms"]] == ["lipid", "circular-fibers", "ogden-volumetric"]
    assert all(t["distribution"] == "cfm-materials" for t in base["terms"])
    assert base["definition_digest"] == stiff["definition_digest"]  # values are not the definition
    assert base["overrides"] == {} and stiff["parameters"]["k2"] == 3.0
    assert prov.material_record(make_material("ogden"))["definition_digest"] != base["definition_digest"]


def test_input_files_follow_contents(tmp_path):
    mesh = tmp_path / "specimen.msh"
    mesh.write_bytes(b"one")
    first = prov.input_files([mesh])
    mesh.write_bytes(b"two")
    assert prov.input_files([mesh]) != first
    assert list(first) == [str(mesh)] and first[str(mesh)].startswith("sha256:")
    with pytest.raises(InputError, match="cannot be read"):
        prov.input_files([tmp_path / "missing.msh"])


def test_record_is_strict_json_and_differences_are_named():
    material = make_material("cfm")
    a = prov.provenance("numba", {}, material)
    b = prov.provenance("torch", {"dtype": "float32"}, make_material("cfm", {"k2": 3.0}))
    json.dumps(a, allow_nan=False)  # dt_max = inf is written as text
    assert a["backend"]["options"]["dt_max"] == "inf"
    phrases = prov.describe_differences({"a": a, "b": b})
    assert "backend: numba | torch" in phrases and "dtype: float64 | float32" in phrases
    assert any(p.startswith("k2: 1.66 | 3") for p in phrases)
    assert prov.describe_differences({"a": a, "a2": prov.provenance("numba", {}, material)}) == []


def test_a_changed_material_definition_is_named_among_the_differences():
    """The same material name, its code (or a helper's value, or a Prony default) changed between
    the runs: cfm compare said "none recorded (same ... material ...)"."""
    material = make_material("cfm")
    a = prov.provenance("numba", {}, material)
    b = json.loads(json.dumps(a))
    b["material"]["definition_digest"] = "5772" + a["material"]["definition_digest"][4:]
    phrases = prov.describe_differences({"a": a, "b": b})
    assert phrases == [f"material definition: {a['material']['definition_digest'][:8]} | "
                       f"{b['material']['definition_digest'][:8]}"]
