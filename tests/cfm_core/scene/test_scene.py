"""Tests of cfm_core.scene: TOML scenes, validation messages, overrides, round trips."""

import math
import re

import meshio
import numpy as np
import pytest

from cfm_core.errors import InputError
from cfm_core.scene.mesh import structured_hex_mesh
from cfm_core.scene.scene import Scene, builtin_scene, builtin_scenes, load_scene, scene_from_dict, scene_to_dict, scene_to_toml
from cfm_core.scene.sections import MaterialSettings, SceneSettings, Specimen


def drop(**sections):
    d = {"scene": {"type": "drop-test"}}
    d.update(sections)
    return d


def single(**sections):
    d = {"scene": {"type": "single-element"}}
    d.update(sections)
    return d


def test_builtin_defaults():
    assert {"drop-test", "single-element"} <= set(builtin_scenes())
    s = builtin_scene("drop-test")
    assert s.type == "drop-test" and s.element is None
    sp, imp = s.specimen, s.impactor
    assert (sp.width, sp.thickness, sp.element_size, sp.density) == (0.05, 0.008, 0.001, 950.0)
    assert sp.symmetry == "quarter" and sp.mesh is None and sp.grid == (25, 25, 8)
    assert (imp.radius, imp.mass, imp.velocity) == (0.055, 0.22, 1.0)
    assert s.contact.friction == 0.0 and s.settings.output_rate == 50_000.0
    assert s.material == MaterialSettings("cfm", "long-term", False, ())
    assert s.end_time == pytest.approx(10 * 0.008 / 1.0 + 5e-3)
    assert s == scene_from_dict(drop())  # the file states the defaults
    e = builtin_scene("single-element")
    assert e.specimen is None and e.impactor is None and e.contact is None
    assert e.element.load_time == pytest.approx(0.5 / 100.0) and e.end_time == e.element.load_time
    assert e == scene_from_dict(single())


def test_builtin_files_comment_units():
    from cfm_core.scene import scene as mod
    from pathlib import Path

    for name in builtin_scenes():
        text = (Path(mod.__file__).parent / "scenes" / f"{name}.toml").read_text()
        for line in text.splitlines():
            if re.match(r"^[a-z_]+ = ", line) and not line.startswith("type"):
                assert "#" in line, f"{name}.toml: uncommented line {line!r}"


def test_unknown_builtin():
    with pytest.raises(InputError, match="drop-test"):
        builtin_scene("drop")


@pytest.mark.parametrize("scene", [builtin_scene("drop-test"), builtin_scene("single-element")])
def test_toml_round_trip(tmp_path, scene):
    scene = scene.with_overrides(end_time=0.02, parameters={"c": 12.5, "k1": 1000},
                                 moduli="instantaneous", name="my run")
    path = tmp_path / "s.toml"
    path.write_text(scene_to_toml(scene))
    assert load_scene(path) == scene
    assert scene_from_dict(scene_to_dict(scene)) == scene


def test_round_trip_keeps_odd_floats(tmp_path):
    s = builtin_scene("drop-test").with_overrides(thickness=0.1 + 0.2 - 0.3 + 0.0048, velocity=1e-3,
                                                  friction=1 / 3)
    path = tmp_path / "s.toml"
    path.write_text(scene_to_toml(s))
    assert load_scene(path) == s


@pytest.mark.parametrize("d, key, section", [
    (drop(specimen={"thicknes": 0.008}), "thicknes", "[specimen]"),
    (drop(impactor={"speed": 1.0}), "speed", "[impactor]"),
    (drop(scene={"type": "drop-test", "endtime": 1.0}), "endtime", "[scene]"),
    (drop(material={"modulus": "long-term"}), "modulus", "[material]"),
    (drop(plate={}), "plate", "top level"),
    (single(specimen={"thickness": 0.008}), "specimen", "top level"),
    (single(element={"velocity": 1.0}), "velocity", "[element]"),
])
def test_unknown_keys(d, key, section):
    with pytest.raises(InputError) as err:
        scene_from_dict(d)
    msg = str(err.value)
    assert f"'{key}'" in msg and section in msg and "allowed" in msg


def test_unknown_key_lists_allowed_keys():
    with pytest.raises(InputError) as err:
        scene_from_dict(drop(specimen={"hight": 0.008}))
    for k in ("width", "thickness", "element_size", "density", "symmetry", "mesh"):
        assert k in str(err.value)


BAD = [
    ("specimen", "thickness", 0.0, "m"), ("specimen", "thickness", -0.008, "m"),
    ("specimen", "thickness", math.nan, "m"), ("specimen", "thickness", math.inf, "m"),
    ("specimen", "thickness", 0.2, "m"), ("specimen", "thickness", 5e-5, "m"),
    ("specimen", "thickness", "8 mm", "m"), ("specimen", "thickness", True, "m"),
    ("specimen", "width", 0.0, "m"), ("specimen", "width", -math.inf, "m"),
    ("specimen", "element_size", 0.0, "m"), ("specimen", "element_size", 0.009, "m"),
    ("specimen", "element_size", math.nan, "m"), ("specimen", "density", 0.0, "kg/m^3"),
    ("specimen", "symmetry", "octant", ""), ("specimen", "mesh", 3, ""),
    ("impactor", "velocity", 0.0, "m/s"), ("impactor", "velocity", -1.0, "m/s"),
    ("impactor", "velocity", math.inf, "m/s"), ("impactor", "velocity", "1", "m/s"),
    ("impactor", "radius", 0.0, "m"), ("impactor", "mass", -0.22, "kg"),
    ("impactor", "mass", math.nan, "kg"),
    ("contact", "friction", -0.1, "-"), ("contact", "friction", 1.5, "-"),
    ("scene", "end_time", 0.0, "s"), ("scene", "output_rate", -50.0, "Hz"),
    ("scene", "name", "", ""),
    ("material", "moduli", "initial", ""), ("material", "elastic", "yes", ""),
    ("material", "name", 5, ""),
]


@pytest.mark.parametrize("section, key, value, unit", BAD)
def test_bad_drop_test_values(section, key, value, unit):
    table = {"type": "drop-test", key: value} if section == "scene" else {key: value}
    with pytest.raises(InputError) as err:
        scene_from_dict(drop(**{section: table}))
    msg = str(err.value)
    assert f"[{section}] {key}" in msg and repr(value) in msg and unit in msg
    assert "\n" not in msg


@pytest.mark.parametrize("key, value, unit", [
    ("stretch", 1.0, "-"), ("stretch", 0.01, "-"), ("stretch", 4.0, "-"), ("rate", 0.0, "1/s"),
    ("rate", -1.0, "1/s"), ("hold", -1.0, "s"), ("size", 0.0, "m"), ("size", math.nan, "m"),
    ("density", math.inf, "kg/m^3"),
])
def test_bad_single_element_values(key, value, unit):
    with pytest.raises(InputError) as err:
        scene_from_dict(single(element={key: value}))
    msg = str(err.value)
    assert f"[element] {key}" in msg and repr(value) in msg and unit in msg


def test_range_is_stated():
    with pytest.raises(InputError, match=r"0\.0001 <= thickness <= 0\.1 m.*4\.8e-3"):
        scene_from_dict(drop(specimen={"thickness": 0.5}))
    with pytest.raises(InputError, match=r"element_size <= 0\.005 m"):
        scene_from_dict(drop(specimen={"thickness": 0.005, "element_size": 0.006}))


def test_bad_type_and_parameters():
    with pytest.raises(InputError, match="'point'"):
        scene_from_dict({"scene": {"type": "point"}})
    with pytest.raises(InputError, match=r"\[scene\]"):
        scene_from_dict({"specimen": {}})
    with pytest.raises(InputError, match=r"\[material.parameters\] c = 'ten'"):
        scene_from_dict(drop(material={"parameters": {"c": "ten"}}))
    with pytest.raises(InputError, match="must be a table"):
        scene_from_dict(drop(specimen=5))


def test_too_many_elements():
    with pytest.raises(InputError, match=r"element_size = 1e-05 m gives .* elements"):
        scene_from_dict(drop(specimen={"element_size": 1e-5}))


def test_integers_accepted_as_floats():
    s = scene_from_dict(drop(impactor={"velocity": 2}))
    assert s.impactor.velocity == 2.0 and isinstance(s.impactor.velocity, float)


def test_with_overrides():
    base = builtin_scene("drop-test").with_overrides(parameters={"c": 10.0})
    s = base.with_overrides(thickness=0.005, velocity=2.0, moduli="instantaneous", elastic=True,
                            parameters={"k1": 900.0}, friction=0.2)
    assert base.specimen.thickness == 0.008  # unchanged: frozen, a new scene is returned
    assert s.specimen.thickness == 0.005 and s.impactor.velocity == 2.0
    assert s.material.parameter_dict == {"c": 10.0, "k1": 900.0}
    assert s.with_overrides(parameters=None).material.parameters == ()
    assert s.material.moduli == "instantaneous" and s.material.elastic and s.contact.friction == 0.2
    assert s.end_time == pytest.approx(10 * 0.005 / 2.0 + 5e-3)
    assert s.with_overrides(end_time=0.01).end_time == 0.01
    assert s.with_overrides(end_time=0.01).with_overrides(end_time=None).end_time == s.end_time
    with pytest.raises(InputError, match="velocity = -1"):
        s.with_overrides(velocity=-1.0)
    with pytest.raises(InputError, match="unknown override 'stretch'"):
        s.with_overrides(stretch=0.5)
    e = builtin_scene("single-element").with_overrides(stretch=1.5, rate=10.0, hold=0.1)
    assert e.end_time == pytest.approx(0.05 + 0.1)
    with pytest.raises(InputError, match="'velocity'"):
        e.with_overrides(velocity=1.0)


def test_sections_validate_on_direct_construction():
    with pytest.raises(InputError, match="thickness"):
        Specimen(thickness=-1.0)
    with pytest.raises(InputError, match="no \\[impactor\\] section"):
        Scene(SceneSettings("single-element"), impactor=builtin_scene("drop-test").impactor)


def test_load_scene_errors(tmp_path):
    with pytest.raises(InputError, match="cannot be read"):
        load_scene(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[scene\ntype = 1")
    with pytest.raises(InputError, match="not valid TOML"):
        load_scene(bad)
    bad.write_text('[scene]\ntype = "drop-test"\n[specimen]\nthickness = -0.008\n')
    with pytest.raises(InputError, match=r"bad\.toml.*thickness = -0\.008 m"):
        load_scene(bad)


def _write_mesh(path, lx, ly, lz, n, origin):
    nodes, hexes = structured_hex_mesh(lx, ly, lz, n, n, 4, origin)
    meshio.write(path, meshio.Mesh(nodes, [("hexahedron", hexes)]))
    return nodes, hexes


def test_scene_with_mesh(tmp_path):
    (tmp_path / "meshes").mkdir()
    _write_mesh(tmp_path / "meshes" / "q.vtu", 0.02, 0.02, 0.006, 8, (0, 0, 0))
    path = tmp_path / "s.toml"
    path.write_text('[scene]\ntype = "drop-test"\n[specimen]\nmesh = "meshes/q.vtu"\n'
                    'thickness = 0.006\n')  # relative to the scene file; agrees with the mesh
    s = load_scene(path)
    sp = s.specimen
    assert sp.mesh == str((tmp_path / "meshes" / "q.vtu").resolve())
    assert sp.width == pytest.approx(0.04) and sp.thickness == pytest.approx(0.006)
    assert sp.element_size == pytest.approx((8 * 0.0025 + 4 * 0.0015) / 12)
    assert sp.n_elements == 8 * 8 * 4
    path.write_text(scene_to_toml(s))
    assert load_scene(path) == s
    with pytest.raises(InputError, match="thickness = 0.008 m disagrees with the mesh"):
        s.with_overrides(thickness=0.008)
    assert s.with_overrides(mesh=None).specimen.thickness == 0.008  # back to the defaults


def test_mesh_placement_errors(tmp_path):
    full = tmp_path / "full.vtu"
    _write_mesh(full, 0.04, 0.04, 0.006, 4, (-0.02, -0.02, 0.0))
    with pytest.raises(InputError, match="symmetry = 'quarter' must be the x >= 0, y >= 0"):
        scene_from_dict(drop(specimen={"mesh": str(full), "symmetry": "quarter"}))
    assert scene_from_dict(drop(specimen={"mesh": str(full)})).specimen.symmetry == "none"  # auto: its shape
    s = scene_from_dict(drop(specimen={"mesh": str(full), "symmetry": "none"}))
    assert s.specimen.width == pytest.approx(0.04)
    shifted = tmp_path / "shifted.vtu"
    _write_mesh(shifted, 0.04, 0.04, 0.006, 4, (-0.01, -0.02, 0.0))
    with pytest.raises(InputError, match="must be centred at x = y = 0"):
        scene_from_dict(drop(specimen={"mesh": str(shifted), "symmetry": "none"}))
    lifted = tmp_path / "lifted.vtu"
    _write_mesh(lifted, 0.02, 0.02, 0.006, 4, (0.0, 0.0, 0.001))
    with pytest.raises(InputError, match="bottom is at z = 0.001 m"):
        scene_from_dict(drop(specimen={"mesh": str(lifted)}))
    with pytest.raises(InputError, match="does not exist"):
        scene_from_dict(drop(specimen={"mesh": str(tmp_path / "none.vtu")}))


def test_mesh_override_drops_structured_geometry(tmp_path):
    q = tmp_path / "q.vtu"
    _write_mesh(q, 0.01, 0.01, 0.004, 4, (0, 0, 0))
    s = builtin_scene("drop-test").with_overrides(mesh=str(q))
    assert s.specimen.thickness == pytest.approx(0.004)
    assert np.isclose(s.end_time, 10 * 0.004 + 5e-3)
