"""Fixtures of the study tests: the coarse drop-test scene most of them run (2.5 mm hexahedra, a
30 mm specimen: ~0.05 s per run once the kernels are loaded) and its TOML file."""

import pytest

from cfm_core.scene.scene import builtin_scene, scene_to_toml

#: The coarse scene's overrides of the built-in drop test (SI units).
COARSE = dict(element_size=0.0025, width=0.03)


@pytest.fixture(scope="module")
def scene():
    """The built-in drop test on the coarse mesh (:data:`COARSE`)."""
    return builtin_scene("drop-test").with_overrides(**COARSE)


@pytest.fixture(scope="module")
def scene_file(scene, tmp_path_factory):
    """The coarse scene written as a TOML file (path as str)."""
    path = tmp_path_factory.mktemp("scene") / "coarse.toml"
    path.write_text(scene_to_toml(scene))
    return str(path)
