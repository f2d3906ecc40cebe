"""Summary and provenance of models with several parts (cfm_core.runs.provenance, parts,
pipeline): every part listed with its material record, density and element count; one
material exactly as before."""

import dataclasses
import json

import numpy as np
import pytest

import cfm_core as cfm
from cfm_core import make_material
from cfm_core.runs import provenance as prov
from cfm_core.runs.parts import describe_model, parts_info
from cfm_core.runs.pipeline import batch_key, drop_test_outcome
from cfm_core.scene import build_model
from cfm_core.scene.model import Part
from cfm_core.simulation.result import Result

SCENE = dict(thickness=0.004, element_size=2e-3, width=0.012)


def _scene():
    return cfm.builtin_scene("drop-test").with_overrides(**SCENE)


def _two_parts(model, fat_k2=1.66):
    zc = model.nodes[model.hexes].mean(axis=1)[:, 2]
    parts = (Part("skin", make_material("neo-hookean"), 1100.0, np.flatnonzero(zc < 0.002)),
             Part("fat", make_material("cfm", {"k2": fat_k2}), 900.0, np.flatnonzero(zc >= 0.002)))
    return dataclasses.replace(model, parts=parts, material=parts[0].material, density=parts[0].density)


def _result(model):
    """A half-sine contact pulse of 2 ms (N), its exact impulse (N s) and the impactor's motion."""
    t = np.linspace(0.0, 3e-3, 301)
    T, F0 = 2e-3, 50.0
    on = t < T
    force = np.where(on, F0 * np.sin(np.pi * t / T), 0.0)
    impulse = np.where(on, F0 * T / np.pi * (1 - np.cos(np.pi * t / T)), 2 * F0 * T / np.pi)
    z = model.sphere.center[2] - 1.0 * t
    return Result(t=t, backend="numba", steps=300, wall_time=0.1, contact_force=force, impulse=impulse,
                  acceleration=force / model.mass_full, impactor_z=z, impactor_v=-1.0 + 0 * t)


def test_provenance_lists_every_part_and_one_material_is_as_before():
    model = build_model(_scene())
    one = prov.provenance("numba", {}, model.material, {}, parts=model.part_list())
    assert one == prov.provenance("numba", {}, model.material, {})       # a one-part model: no "parts"
    assert "parts" not in one and one["material"] == prov.material_record(model.material)
    two = _two_parts(model, fat_k2=3.0)
    rec = prov.provenance("numba", {}, two.material, {}, parts=two.part_list())
    json.dumps(rec, allow_nan=False)
    assert [(p["name"], p["material"]["name"], p["density"], p["elements"]) for p in rec["parts"]] == \
        [("skin", "neo-hookean", 1100.0, len(two.parts[0].elements)), ("fat", "cfm", 900.0, len(two.parts[1].elements))]
    assert sum(p["elements"] for p in rec["parts"]) == model.n_elements
    fat = rec["parts"][1]["material"]
    assert fat["definition_digest"] == prov.material_record(make_material("cfm"))["definition_digest"]
    assert fat["parameters"]["k2"] == 3.0 and fat["overrides"] == {"k2": {"value": 3.0, "default": 1.66}}
    # titles and comparisons name the part whose value differs
    assert "fat: k2 = 3 (default 1.66)" in prov.describe_run(rec)
    base = prov.provenance("numba", {}, two.material, {}, parts=_two_parts(model).part_list())
    assert prov.describe_differences({"a": base, "b": rec}) == ["fat: k2: 1.66 | 3"]


def test_summary_lists_the_parts_and_one_material_summary_is_unchanged():
    scene = _scene()
    model = build_model(scene)
    single = drop_test_outcome(scene, model, _result(model)).summary
    # the one-material summary: the material, its values and the scene's density, no part list
    assert parts_info(model) == {}
    assert "parts" not in single and "parts" not in single["provenance"]
    assert (single["material"], single["parameters"], single["density"]) == \
        ("cfm", dict(model.material.values), scene.specimen.density)
    assert single["provenance"]["material"] == prov.material_record(model.material)
    assert single["scene"]["material"]["parameters"] == dict(model.material.values)
    two = _two_parts(model)
    summary = drop_test_outcome(scene, two, _result(two)).summary
    json.dumps(summary, allow_nan=False)
    rows = summary["parts"]
    assert [(r["name"], r["material"], r["density"], r["elements"]) for r in rows] == \
        [("skin", "neo-hookean", 1100.0, len(two.parts[0].elements)), ("fat", "cfm", 900.0, len(two.parts[1].elements))]
    assert rows[1]["parameters"] == dict(make_material("cfm").values)
    assert rows[0]["definition_digest"] == prov.material_record(make_material("neo-hookean"))["definition_digest"]
    assert summary["material"] == "neo-hookean + cfm" and summary["density"] is None
    assert set(summary["parameters"]) == {"skin", "fat"} and "parts" in summary["units"]
    assert [p["name"] for p in summary["provenance"]["parts"]] == ["skin", "fat"]
    # the peak is that of the pulse, whatever the parts: the summary's physics is untouched
    assert summary["peak_g"] == pytest.approx(single["peak_g"], rel=1e-12)
    assert "impactor_shape" not in single and "impactor_shape" not in summary
    flat = dataclasses.replace(two, sphere=dataclasses.replace(two.sphere, shape="flat", edge_radius=1e-3))
    flat_summary = drop_test_outcome(scene, flat, _result(flat)).summary
    assert (flat_summary["impactor_shape"], flat_summary["impactor_edge_radius"]) == ("flat", 1e-3)
    # the scene's [material] is left as given, not overwritten with one part's values
    assert summary["scene"]["material"] == {"name": "cfm", "moduli": "long-term", "elastic": False}


def test_the_run_names_parts_symmetry_and_shape_and_batches_keep_them_apart():
    model = build_model(_scene())
    two = _two_parts(model)
    line = describe_model(two)
    assert line.startswith("model: quarter symmetry (planes x = 0 and y = 0), 2 parts: skin (neo-hookean, "
                           "1100 kg/m^3") and "fat (cfm, 900 kg/m^3" and line.endswith("; hemisphere impactor")
    half = dataclasses.replace(two, meta={**two.meta, "symmetry": "half"},
                               sphere=dataclasses.replace(two.sphere, shape="flat", edge_radius=1e-3))
    assert describe_model(half).startswith("model: half symmetry (plane y = 0)") and "flat impactor" in describe_model(half)
    assert batch_key(model) != batch_key(two)
    assert batch_key(two) != batch_key(dataclasses.replace(two, sphere=half.sphere))
    assert batch_key(model) == batch_key(build_model(_scene()))
