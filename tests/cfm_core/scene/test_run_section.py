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
