"""Writing a scene back: a nested dict of plain values and commented TOML (SI units).

:func:`cfm_core.scene.scene_from_dict` / :func:`cfm_core.scene.load_scene` read what these
write back into an equal scene (same resolved values, same requested symmetry): every run writes
its ``scene.toml`` with :func:`scene_to_toml`, so that it can be repeated.
"""

from __future__ import annotations

import json
import re
from dataclasses import fields

from .layers import region_table
from .run_section import run_toml

__all__ = ["scene_to_dict", "scene_to_toml"]

_UNITS = {"end_time": "s", "output_rate": "Hz", "width": "m", "thickness": "m",
          "element_size": "m", "density": "kg/m^3", "radius": "m", "mass": "kg",
          "velocity": "m/s, impact speed, positive = down", "friction": "-", "size": "m",
          "stretch": "-", "rate": "1/s", "hold": "s", "load_time": "s", "edge_radius": "m, rim of the flat face",
          "angle": "deg from the plate normal", "azimuth": "deg in the plate plane from +x",
          "offset": "m, impact point [x, y] from the specimen centre"}


def scene_to_dict(scene) -> dict:
    """The scene as a nested dict of plain values that :func:`scene_from_dict` reads back.

    Automatic values are left out (end_time when None; width, thickness and element_size when
    they come from a mesh; thickness when it is the sum of the layers); [specimen] symmetry is
    the requested one ("auto" stays "auto"); layers are a list of tables under
    ``specimen.layers``, parts a table of tables under ``parts``.

    Parameters
    ----------
    scene : Scene
        A validated scene.

    Returns
    -------
    dict
        ``{"scene": {...}, "<section>": {key: value (SI)}, ...}``; ``None`` values and empty
        parameter tables are left out; vectors are lists.
    """
    from .scene import _LAYOUT  # the scene module imports this one

    out = {}
    for key in _LAYOUT[scene.type]:
        obj = scene.settings if key == "scene" else getattr(scene, key)
        table = {}
        for f in fields(obj):
            val = getattr(obj, f.name)
            if val is None or (isinstance(val, tuple) and not val and f.name in ("layers", "parameters")):
                continue
            if key == "specimen":
                if obj.mesh is not None and f.name in ("width", "thickness", "element_size"):
                    continue
                if obj.layers and f.name == "thickness":
                    continue
                if f.name == "symmetry":
                    val = getattr(obj, "requested_symmetry", val)
                if f.name == "layers":
                    val = [region_table(lay, skip=()) for lay in val]
            if f.name == "parameters":
                val = dict(val)
            if isinstance(val, tuple):
                val = list(val)
            table[f.name] = val
        out[key] = table
    if getattr(scene, "parts", ()):
        out["parts"] = {p.name: region_table(p) for p in scene.parts}
    if scene.run is not None:
        out["run"] = scene.run.as_dict()
    return out


def _toml_key(k: str) -> str:
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v))
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a valid TOML basic string
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} to TOML")


def _table(header: str, table: dict, comment: str = "") -> list[str]:
    """Lines of one TOML table: its scalar keys (unit comments), then its parameters table."""
    table = dict(table)
    params = table.pop("parameters", None)
    lines = ["", f"{header}{comment}"]
    for k, v in table.items():
        unit = f"  # {_UNITS[k]}" if k in _UNITS else ""
        lines.append(f"{_toml_key(k)} = {_toml_value(v)}{unit}")
    if params:
        head = header.strip("[]")
        lines += ["", f"[{head}.parameters]  # SI units"]
        lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in params.items()]
    return lines


def scene_to_toml(scene) -> str:
    """The scene as TOML text (SI units, commented); :func:`load_scene` reads it back equal.

    Parameters
    ----------
    scene : Scene
        A validated scene.

    Returns
    -------
    str
        TOML with a header comment, one table per section, the unit of each key as a comment,
        material parameter overrides as ``[material.parameters]``, layers as
        ``[[specimen.layers]]`` (from the plate up), mesh parts as ``[parts.NAME]``, and the
        resolved symmetry as a comment.
    """
    lines = [f"# {scene.type} scene written by cfm_core.scene.scene_to_toml (SI units)"]
    d = scene_to_dict(scene)
    d.pop("run", None)
    parts = d.pop("parts", {})
    for section, table in d.items():
        layers = table.pop("layers", [])
        comment = ""
        if section == "specimen" and scene.type == "drop-test":
            comment = (f"  # symmetry used: {scene.specimen.symmetry!r} "
                       f"({getattr(scene, 'symmetry_reason', '')})")
        lines += _table(f"[{section}]", table, comment)
        for lay in layers:
            lines += _table("[[specimen.layers]]", lay, "  # from the plate upwards")
    for name, table in parts.items():
        lines += _table(f"[parts.{_toml_key(name)}]", table)
    if scene.run is not None:
        lines += ["", *run_toml(scene.run)]
    return "\n".join(lines) + "\n"
