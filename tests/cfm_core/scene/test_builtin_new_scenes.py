"""The layered-tissue and flat-impactor built-in scenes, and scene.toml round trips of the new keys."""

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from cfm_core.scene.builder import build_model
from cfm_core.scene.scene import builtin_scene, builtin_scenes, load_scene, scene_from_dict, scene_to_dict, scene_to_toml
from cfm_core.scene.sections import Specimen

SCENES = Path(__file__).resolve().parents[3] / "cfm_core" / "scene" / "scenes"


def test_new_scenes_are_registered():
    assert {"layered-tissue", "flat-impactor"} <= set(builtin_scenes())


def test_layered_tissue():
    s = builtin_scene("layered-tissue")
    sp = s.specimen
    assert [lay.name for lay in sp.layers] == ["muscle", "sat", "skin"]  # from the plate up
    assert [lay.thickness for lay in sp.layers] == [0.010, 0.008, 0.002] and sp.thickness == pytest.approx(0.020)
    m = build_model(s.with_overrides(element_size=2e-3))
    assert [p.material.name for p in m.parts] == ["neo-hookean", "cfm", "neo-hookean"]
    assert [p.density for p in m.parts] == [1060.0, 950.0, 1100.0]
    assert m.parts[0].material.values["mu"] == 15600.0 and m.parts[2].material.values["mu"] == 4e5
    assert m.meta["symmetry"] == "quarter" and m.sphere.shape == "hemisphere"
    z = m.nodes[m.hexes, 2].mean(axis=1)  # the skin is on top, the muscle on the plate
    assert z[m.parts[2].elements].min() > 0.018 and z[m.parts[0].elements].max() < 0.010
    # every layer takes the 2 mm of --element-size (none sets its own)
    assert [e["cells_through_thickness"] for e in m.meta["parts"]] == [5, 4, 1]


def test_flat_impactor():
    s = builtin_scene("flat-impactor")
    imp = s.impactor
    assert (imp.shape, imp.radius, imp.edge_radius, imp.mass, imp.velocity) == ("flat", 0.02, 0.003, 0.22, 1.25)
    assert (s.specimen.width, s.specimen.thickness) == (0.05, 0.008) and s.material.name == "cfm"
    m = build_model(s.with_overrides(element_size=2e-3))
    assert m.sphere.center == (0.0, 0.0, 0.008) and m.sphere.velocity == -1.25 and m.meta["symmetry"] == "quarter"


@pytest.mark.parametrize("name", ["layered-tissue", "flat-impactor"])
def test_every_key_is_commented(name):
    """Every key line says what it is (unit, source or assumption), as in drop-test.toml."""
    for line in (SCENES / f"{name}.toml").read_text().splitlines():
        if re.match(r"\s*[A-Za-z_]+\s*=", line) and not line.lstrip().startswith("#"):
            assert "#" in line, f"{name}.toml: key without a comment: {line!r}"
    text = (SCENES / f"{name}.toml").read_text()
    assert "ASSUMED" in text


def _round_trip(scene, tmp_path):
    path = tmp_path / "scene.toml"
    text = scene_to_toml(scene)
    tomllib.loads(text)
    path.write_text(text)
    again = load_scene(path)
    assert again == scene
    assert again.specimen.requested_symmetry == scene.specimen.requested_symmetry
    assert again.symmetry_reason == scene.symmetry_reason
    assert scene_to_toml(again) == text and scene_to_dict(again) == scene_to_dict(scene)
    return again


@pytest.mark.parametrize("name", ["layered-tissue", "flat-impactor", "drop-test"])
def test_builtin_round_trip(name, tmp_path):
    _round_trip(builtin_scene(name), tmp_path)


@pytest.mark.parametrize("d", [
    {"specimen": {"symmetry": "auto"}, "impactor": {"shape": "sphere", "velocity": [0.1, 0.0, -2.0],
                                                    "offset": [0.004, 0.0]}},
    {"impactor": {"velocity": 1.5, "angle": 30.0, "azimuth": 60.0, "offset": [0.001, -0.002]}},
    {"specimen": {"symmetry": "half"}, "impactor": {"shape": "flat", "radius": 0.01, "edge_radius": 0.0}},
    {"specimen": {"symmetry": "none"}, "impactor": {"shape": "plane", "mass": 0.5}},
    {"specimen": {"element_size": 2e-3, "layers": [
        {"thickness": 0.003, "material": "neo-hookean", "parameters": {"mu": 2000.0}, "density": 1000.0,
         "element_size": 1e-3, "moduli": "instantaneous", "elastic": True},
        {"thickness": 0.005, "name": "fat", "parameters": {"c": 12.0}}]},
     "material": {"parameters": {"k1": 1000.0}}},
])
def test_new_keys_round_trip(d, tmp_path):
    scene = scene_from_dict({"scene": {"type": "drop-test"}, **d})
    again = _round_trip(scene, tmp_path)
    assert np.array_equal(again.impactor.vector, scene.impactor.vector)
    assert again.specimen.layers == scene.specimen.layers


def test_auto_is_written_as_asked(tmp_path):
    """scene.toml keeps "auto" (so that a changed impact point re-chooses) and says what was used."""
    s = scene_from_dict({"scene": {"type": "drop-test"}, "impactor": {"offset": [0.002, 0.0]}})
    text = scene_to_toml(s)
    assert 'symmetry = "auto"' in text and "symmetry used: 'half'" in text
    moved = _round_trip(s, tmp_path).with_overrides(offset=[0.002, 0.001])
    assert moved.specimen.symmetry == "none"


def test_specimen_alone_keeps_the_request():
    sp = Specimen()
    assert sp.symmetry == "auto" and sp.requested_symmetry == "auto" and sp.grid == (25, 25, 8)


def test_a_rim_the_mesh_does_not_resolve_is_warned_about():
    from cfm_core.scene.plausible import check_plausible

    flat = builtin_scene("flat-impactor")
    assert check_plausible(flat) == []                       # 3 mm rim on 1 mm elements
    (w,) = check_plausible(flat.with_overrides(edge_radius=0.001))
    assert "edge_radius = 0.001 m" in w and "2 element sizes" in w
    assert check_plausible(builtin_scene("drop-test")) == []  # the hemisphere has no rim
