"""The [run] section of a scene: read, validated, written back equal; kept through overrides."""

import math
import tomllib

import pytest

from cfm_core.errors import InputError
from cfm_core.scene.run_section import RunSettings
from cfm_core.scene.scene import builtin_scene, load_scene, scene_from_dict, scene_to_dict, scene_to_toml

RUN = {"backend": "torch", "dtype": "float32", "device": "cpu",
       "options": {"hourglass": 0.05, "max_steps": 50_000_000, "dt_max": math.inf, "hourglass_wave": "shear",
                   "warm_up": True},
       "input_files": {"/data/spécimen 1.vtu": "sha256:" + "ab" * 32}}


def test_run_section_round_trips_through_toml_with_types_kept():
    scene = builtin_scene("drop-test").with_run(RunSettings(**RUN))
    text = scene_to_toml(scene)
    back = scene_from_dict(tomllib.loads(text))
    assert back == scene and back.run.option_dict == RUN["options"]
    options = tomllib.loads(text)["run"]["options"]
    assert type(options["max_steps"]) is int and options["dt_max"] == math.inf and options["warm_up"] is True
    assert "spécimen 1.vtu" in text  # written as text, not as \\u escapes
    # what is simulated can change; how it is run stays
    assert back.with_overrides(thickness=0.005).run == scene.run


def test_scene_without_run_section_has_none_and_writes_none():
    scene = builtin_scene("drop-test")
    assert scene.run is None and "run" not in scene_to_dict(scene) and "[run]" not in scene_to_toml(scene)


def test_relative_input_file_paths_are_taken_from_the_scene_file_folder(tmp_path):
    (tmp_path / "s.toml").write_text('[scene]\ntype = "single-element"\n[run]\nbackend = "numba"\n'
                                     '[run.input_files]\n"mesh.vtu" = "sha256:00"\n')
    assert load_scene(tmp_path / "s.toml").run.file_dict == {str(tmp_path / "mesh.vtu"): "sha256:00"}


@pytest.mark.parametrize("run, match", [
    ({"backend": 3}, r"\[run\] backend = 3 must be a non-empty name"),
    ({"dtype": "float16"}, r"\[run\] dtype = 'float16' is not allowed; use 'float64' or 'float32'"),
    ({"options": {"hourglass": [1, 2]}}, r"\[run.options\] hourglass = \[1, 2\] must be a number"),
    ({"options": {"hourglass": math.nan}}, r"\[run.options\] hourglass = nan"),
    ({"input_files": {"m.vtu": "abc"}}, r"\[run.input_files\] 'm.vtu' = 'abc' must be a content digest"),
    ({"backnd": "numba"}, r"unknown key 'backnd' in \[run\] \(did you mean 'backend'\?\)"),
    ({"options": 5}, r"\[run.options\] = 5 must be a table"),
])
def test_bad_run_sections_name_the_key_and_value(run, match):
    with pytest.raises(InputError, match=match):
        scene_from_dict({"scene": {"type": "drop-test"}, "run": run})


def test_a_definition_digest_in_upper_case_is_read_as_cfm_writes_it():
    """An upper-case digest in [run.materials] was refused with "must be a material definition digest (24
    hexadecimal characters ...)" although it was 24 hexadecimal characters; it is read in lower case, and the repeat
    compares it with the material's without a false "defined differently" warning."""
    from cfm_core.material.cache import definition_digest
    from cfm_core.material.registry import get_material
    from cfm_core.runs.settings import changed_inputs

    digest = definition_digest(get_material("cfm"))
    upper = "sha256:" + "AB" * 32
    scene = scene_from_dict({"scene": {"type": "drop-test"},
                             "run": {"backend": "numba", "materials": {"cfm": digest.upper()},
                                     "input_files": {"/data/m.vtu": upper.upper()}}})
    assert scene.run.materials == (("cfm", digest),) and digest == digest.lower()
    assert scene.run.file_dict == {"/data/m.vtu": upper.lower()}
    assert not any("defined differently" in w for w in changed_inputs(scene))
    assert "cfm = " + repr(digest).replace("'", '"') in scene_to_toml(scene)  # written back as cfm writes it


@pytest.mark.parametrize("value, says", [("0123456789ABCDEF0123456G", "it has characters other than 0-9 and a-f"),
                                         ("0123456789abcdef0123456", "it has 23 characters"),
                                         (5, "it is not text (int)")])
def test_a_bad_definition_digest_is_told_what_is_wrong_with_it(value, says):
    with pytest.raises(InputError) as err:
        scene_from_dict({"scene": {"type": "drop-test"}, "run": {"materials": {"cfm": value}}})
    assert ("[run.materials] cfm = " + repr(value) + " must be a material definition digest: 24 hexadecimal digits "
            "(0-9, a-f in either case), as cfm writes it; " + says + ".") in str(err.value)
