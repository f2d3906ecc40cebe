"""The scene layer: what is simulated, and the backend-neutral model it becomes.

Flow: a TOML scene (scene.py, validated sections in sections.py, built-ins in ``scenes/``) ->
meshes (mesh.py: structured hexahedra or a user's mesh: Abaqus .inp through abaqus_inp.py, other
formats through meshio) -> the model builder
(builder.py), which includes only what a scene needs (docs/conventions.md section 4) -> a
:class:`Model` of plain arrays (model.py) that every backend runs. SI units everywhere.
"""

from .builder import build_model
from .model import Model, Prescribed, RigidPlane, RigidSphere
from .scene import Scene, builtin_scene, builtin_scenes, load_scene, scene_from_dict, scene_to_dict, scene_to_toml

__all__ = ["build_model", "Model", "Prescribed", "RigidPlane", "RigidSphere", "Scene", "builtin_scene",
           "builtin_scenes", "load_scene", "scene_from_dict", "scene_to_dict", "scene_to_toml"]
