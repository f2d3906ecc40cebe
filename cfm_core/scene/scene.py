"""Scenes: what is simulated, read from TOML, validated, in SI units (m, s, kg, Pa).

Three scene types (docs/conventions.md section 4). ``drop-test``: sections [scene], [specimen], [impactor],
[contact], [material]. ``single-element``: [scene], [element], [material]. ``relaxation``
(quasi-static, no inertia): [scene], [relaxation], [material]. Every value is checked
when its frozen section dataclass (:mod:`cfm_core.scene.sections`) is built; a bad value, a wrong
type or an unknown key raises :class:`cfm_core.errors.InputError` naming the section, the key,
the value, the unit and what is allowed. The built-in scene files (``cfm_core/scene/scenes/*.toml``)
document every key with its unit.

Any scene may hold a [run] section (:mod:`cfm_core.scene.run_section`): how the run that wrote
it was made (backend, dtype, device, options, input-file digests), so that it can be repeated.

Public API: :func:`load_scene`, :func:`scene_from_dict`, :func:`builtin_scene`,
:meth:`Scene.with_overrides`, :meth:`Scene.with_run`, :func:`scene_to_dict`, :func:`scene_to_toml`.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Mapping

from ..errors import InputError, did_you_mean
from ..tables import decode
from .impactor_section import resolve_symmetry
from .layers import make_parts, mesh_part_elements
from .run_section import RunSettings
from .sections import SCENE_TYPES, Contact, ElementTest, Impactor, MaterialSettings, RelaxationTest, SceneSettings, Specimen, _choice, _set
from .writer import _UNITS, scene_to_dict, scene_to_toml  # noqa: F401 (_UNITS: the studies name scene units)

__all__ = ["Scene", "RunSettings", "SceneSettings", "Specimen", "Impactor", "Contact", "MaterialSettings",
           "ElementTest", "RelaxationTest", "SCENE_TYPES", "load_scene", "scene_from_dict", "builtin_scene",
           "builtin_scenes", "scene_to_dict", "scene_to_toml"]

# ----------------------------------------------------------------------------- the scene
_LAYOUT = {
    "drop-test": {"scene": SceneSettings, "specimen": Specimen, "impactor": Impactor,
                  "contact": Contact, "material": MaterialSettings},
    "single-element": {"scene": SceneSettings, "element": ElementTest, "material": MaterialSettings},
    "relaxation": {"scene": SceneSettings, "relaxation": RelaxationTest, "material": MaterialSettings},
}
_OVERRIDES_COMMON = {"name": ("scene", "name"), "end_time": ("scene", "end_time"),
                     "output_rate": ("scene", "output_rate"), "material": ("material", "name"),
                     "moduli": ("material", "moduli"), "elastic": ("material", "elastic"),
                     "parameters": ("material", "parameters")}
_OVERRIDES = {
    "drop-test": {**{k: ("specimen", k) for k in ("width", "thickness", "element_size", "density",
                                                  "symmetry", "mesh")},
                  **{k: ("impactor", k) for k in ("radius", "mass", "velocity", "shape", "edge_radius", "angle",
                                                  "azimuth", "offset")},
                  "friction": ("contact", "friction"), **_OVERRIDES_COMMON},
    "single-element": {**{k: ("element", k) for k in ("size", "stretch", "rate", "hold",
                                                       "density")}, **_OVERRIDES_COMMON},
    "relaxation": {**{k: ("relaxation", k) for k in ("size", "stretch", "load_time", "hold",
                                                      "lateral")}, **_OVERRIDES_COMMON},
}


@dataclass(frozen=True)
class Scene:
    """A validated scene (docs/conventions.md section 4). Sections a scene type does not use are
    None (and not allowed); a used section left out gets its defaults. Immutable: change it with
    :meth:`with_overrides`.

    Parameters
    ----------
    settings : SceneSettings
        The [scene] section: type ("drop-test", "single-element", "relaxation"), name, end_time
        (s), output_rate (Hz).
    material : MaterialSettings
        The [material] section: registered name, moduli, elastic, parameter overrides (SI).
    specimen, impactor, contact : Specimen, Impactor, Contact, optional
        Drop test only: specimen geometry (m), density (kg/m^3), mesh; rigid hemisphere radius
        (m), mass (kg), velocity (m/s); friction (-).
    element : ElementTest, optional
        Single element only: size (m), stretch (-), rate (1/s), hold (s), density (kg/m^3).
    relaxation : RelaxationTest, optional
        Relaxation only: size (m), stretch (-), load_time (s), hold (s), lateral.
    run : RunSettings, optional
        The [run] section (any scene type): backend, dtype, device, options and input-file
        digests of the run that wrote the scene (:mod:`cfm_core.scene.run_section`); None: the
        defaults.
    parts : tuple of PartSettings
        Drop test with a [specimen] mesh only: ``[parts.NAME]`` tables giving the material of
        each named cell set (:mod:`cfm_core.scene.layers`); empty: one material.

    Attributes
    ----------
    symmetry_reason : str
        Drop test: why [specimen] symmetry (resolved at construction from "auto" or checked when
        asked for, :func:`cfm_core.scene.impactor_section.resolve_symmetry`) is what it is.

    Raises
    ------
    InputError
        ``settings`` is not a SceneSettings, a section the scene type does not use is given, a
        section is not of its class, a requested symmetry the impact breaks, an impact point off
        the specimen, or [parts] that do not match the mesh's cell sets.
    """

    settings: SceneSettings
    material: MaterialSettings = field(default_factory=MaterialSettings)
    specimen: Specimen | None = None
    impactor: Impactor | None = None
    contact: Contact | None = None
    element: ElementTest | None = None
    relaxation: RelaxationTest | None = None
    run: RunSettings | None = None
    parts: tuple = ()

    def __post_init__(self):
        if not isinstance(self.settings, SceneSettings):
            raise InputError(f"Scene.settings must be a SceneSettings, got {self.settings!r}.")
        if self.run is not None and not isinstance(self.run, RunSettings):
            raise InputError(f"Scene.run must be a RunSettings, got {self.run!r}.")
        layout = _LAYOUT[self.type]
        for key, cls in (("specimen", Specimen), ("impactor", Impactor), ("contact", Contact),
                         ("element", ElementTest), ("relaxation", RelaxationTest),
                         ("material", MaterialSettings)):
            val = getattr(self, key)
            if key not in layout:
                if val is not None:
                    raise InputError(f"a {self.type} scene has no [{key}] section; allowed "
                                     f"sections: {', '.join(layout)}.")
            elif val is None:
                _set(self, **{key: cls()})
            elif not isinstance(val, cls):
                raise InputError(f"Scene.{key} must be a {cls.__name__}, got {val!r}.")
        if self.parts and self.type != "drop-test":
            raise InputError(f"a {self.type} scene has no [parts]; parts give the materials of a drop-test mesh.")
        _set(self, parts=make_parts({p.name: p for p in self.parts}) if self.parts else ())
        if self.type == "drop-test":
            self._resolve_drop_test()

    def _resolve_drop_test(self):
        """Resolve the symmetry, check the impact point and the mesh parts."""
        sp, imp = self.specimen, self.impactor
        requested = sp.requested_symmetry
        sym, why = resolve_symmetry(sp, imp, requested)
        if sym != sp.symmetry:
            sp = replace(sp, symmetry=sym)
            object.__setattr__(sp, "requested_symmetry", requested)
            _set(self, specimen=sp)
        object.__setattr__(self, "symmetry_reason", why)
        (ox, oy) = imp.point
        if ox or oy:
            if sp.mesh is not None:
                from .sections import read_specimen_mesh

                nodes = read_specimen_mesh(sp.mesh, bool(sp.merge_nodes))[0]
                lo, hi = nodes[:, :2].min(axis=0), nodes[:, :2].max(axis=0)
            else:
                lo, hi = (-sp.width / 2.0, -sp.width / 2.0), (sp.width / 2.0, sp.width / 2.0)
            for k, v in ((0, ox), (1, oy)):
                if not lo[k] < v < hi[k]:
                    raise InputError(f"[impactor] offset {'xy'[k]} = {v:g} m puts the impact point off the specimen, "
                                     f"whose top spans {lo[k]:g} < {'xy'[k]} < {hi[k]:g} m; give an offset inside it "
                                     f"(m, relative to the specimen centre).")
        if self.parts:
            if sp.mesh is None:
                raise InputError("[parts] give the materials of the cell sets of a [specimen] mesh, but the scene has "
                                 "no mesh; for the built-in block use [[specimen.layers]] (from the plate upwards).")
            mesh_part_elements(sp.mesh, sp.n_elements, self.parts)

    @property
    def type(self) -> str:
        """The scene type: "drop-test", "single-element" or "relaxation"."""
        return self.settings.type

    @property
    def end_time(self) -> float:
        """End time (s): [scene] end_time if given, else automatic.

        drop-test: 10 * thickness / (-v_z) + 5e-3 s, a generous bound (the sphere cannot travel
        further than the thickness, and the run stops earlier once it separates); single-element
        and relaxation: load time + hold.
        """
        if self.settings.end_time is not None:
            return self.settings.end_time
        if self.type == "drop-test":
            return 10.0 * self.specimen.thickness / self.impactor.normal_speed + 5e-3
        if self.type == "relaxation":
            return self.relaxation.load_time + self.relaxation.hold
        return self.element.load_time + self.element.hold

    def with_overrides(self, **kw) -> "Scene":
        """A new validated scene with some values replaced (SI units), e.g.
        ``thickness=0.005, velocity=2.0, moduli="instantaneous", parameters={"c": 20.0}``.

        Keys are the TOML keys of the scene's sections (``material`` sets the material name);
        ``parameters`` are merged into the existing overrides; None restores a default
        (``end_time=None``: automatic; ``mesh=None``: structured mesh with default geometry;
        ``parameters=None``: no parameter overrides). Giving ``mesh`` drops width, thickness and
        element_size unless they are given too (they come from the mesh).

        Parameters
        ----------
        **kw
            Any of: ``name``, ``end_time`` (s), ``output_rate`` (Hz), ``material``, ``moduli``,
            ``elastic``, ``parameters`` (dict, SI); drop test: ``width``, ``thickness``,
            ``element_size`` (m), ``density`` (kg/m^3), ``symmetry``, ``mesh`` (path), ``radius``
            (m), ``mass`` (kg), ``velocity`` (m/s: a speed or [vx, vy, vz]), ``shape``,
            ``edge_radius`` (m), ``angle``, ``azimuth`` (deg), ``offset`` ([x, y] in m),
            ``friction`` (-); single element: ``size``
            (m), ``stretch`` (-), ``rate`` (1/s), ``hold`` (s), ``density`` (kg/m^3); relaxation:
            ``size`` (m), ``stretch`` (-), ``load_time`` (s), ``hold`` (s), ``lateral``.

        Returns
        -------
        Scene
            A new scene; this one is unchanged.

        Raises
        ------
        InputError
            A key the scene type does not have (the message lists the allowed ones),
            ``parameters`` that is not a dict, or a value the section rejects.
        """
        allowed = _OVERRIDES[self.type]
        d = scene_to_dict(self)
        for key, value in kw.items():
            if key not in allowed:
                raise InputError(f"unknown override '{key}' for a {self.type} scene{_close(key, allowed)}; allowed: "
                                 f"{', '.join(sorted(allowed))}.")
            section, name = allowed[key]
            table = d.setdefault(section, {})
            if key == "parameters" and value is not None:
                if not isinstance(value, Mapping):
                    raise InputError(f"override parameters = {value!r} must be a dict "
                                     f"{{name: value (SI)}}.")
                table["parameters"] = {**table.get("parameters", {}), **value}
            elif value is None:
                table.pop(name, None)
            else:
                table[name] = value
        if kw.get("mesh") is not None:
            for key in ("width", "thickness", "element_size"):
                if key not in kw:
                    d["specimen"].pop(key, None)
        return scene_from_dict(d)

    def with_run(self, run: RunSettings | None) -> "Scene":
        """The same scene with another [run] section (how it is run, not what is simulated).

        Parameters
        ----------
        run : RunSettings or None
            Backend, dtype, device, options and input-file digests; None removes the section
            (the scene then runs with the default backend and options).

        Returns
        -------
        Scene
            A new scene; this one is unchanged.
        """
        return replace(self, run=run)


def _close(word: str, names) -> str:
    """``" (did you mean 'x'?)"`` for a mistyped name, or ``""`` (:func:`cfm_core.errors.did_you_mean`)."""
    hint = did_you_mean(word, names)
    return f" ({hint[0].lower()}{hint[1:]})" if hint else ""


def scene_from_dict(d: Mapping, base_dir=None) -> Scene:
    """Validate a nested dict (as read from TOML) into a :class:`Scene`.

    Parameters
    ----------
    d : mapping
        ``{"scene": {"type": ..., ...}, "<section>": {key: value (SI)}, ...}``.
    base_dir : str or path-like, optional
        Folder that a relative [specimen] mesh path is taken from (default: the current one).

    Returns
    -------
    Scene
        The validated scene.

    Raises
    ------
    InputError
        ``d`` is not a table, no [scene] section with a type, an unknown scene type, section or
        key, a section that is not a table, or a value outside what its section allows (the
        message names section, key, value, unit and what is allowed).
    """
    if not isinstance(d, Mapping):
        raise InputError(f"a scene must be a table of sections, got {type(d).__name__}.")
    head = d.get("scene")
    if not isinstance(head, Mapping) or "type" not in head:
        raise InputError(f"a scene needs a [scene] section with type = one of "
                         f"{', '.join(repr(t) for t in SCENE_TYPES)}.")
    stype = _choice("scene", "type", head["type"], SCENE_TYPES)
    layout = _LAYOUT[stype]
    extra = ["run", "parts"] if stype == "drop-test" else ["run"]
    for key in d:
        if key not in layout and key not in extra:
            raise InputError(f"unknown key '{key}' at the top level of a {stype} scene{_close(key, [*layout, *extra])}; "
                             f"allowed sections: {', '.join([*layout, *extra])}.")
    sections = {}
    for key, cls in layout.items():
        table = d.get(key, {})
        if not isinstance(table, Mapping):
            raise InputError(f"[{key}] must be a table (section), got {table!r}.")
        allowed = [f.name for f in fields(cls)]
        for k in table:
            if k not in allowed:
                raise InputError(f"unknown key '{k}' in [{key}] of a {stype} scene{_close(k, allowed)}; allowed keys: "
                                 f"{', '.join(allowed)}.")
        table = dict(table)
        if key == "specimen" and isinstance(table.get("mesh"), str):
            mesh = Path(table["mesh"]).expanduser()
            if not mesh.is_absolute() and base_dir is not None:
                table["mesh"] = str(Path(base_dir) / mesh)
        sections["settings" if key == "scene" else key] = cls(**table)
    if d.get("run") is not None:
        sections["run"] = RunSettings.from_table(d["run"], base_dir)
    if d.get("parts"):
        sections["parts"] = make_parts(d["parts"])
    return Scene(**sections)


def load_scene(path) -> Scene:
    """Read and validate a TOML scene file (SI units); errors name the file.

    Parameters
    ----------
    path : str or path-like
        The ``.toml`` file; a relative ``mesh`` in it is taken from the file's folder.

    Returns
    -------
    Scene
        The validated scene.

    Raises
    ------
    InputError
        The file cannot be read, is not UTF-8 (:func:`cfm_core.tables.decode`; a byte-order mark
        is skipped), is not valid TOML, or does not validate (:func:`scene_from_dict`); the
        message starts with the file name.
    """
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise InputError(f"scene file '{p}' cannot be read: {exc.strerror or exc}.") from None
    text = decode(p, raw, "TOML", what="scene file")  # a UTF-8 byte-order mark skipped, as in CSV files
    try:
        d = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"scene file '{p}' is not valid TOML: {exc}.") from None
    except ValueError as exc:  # Python's limit on the digits of an integer (4300)
        raise InputError(f"scene file '{p}' holds an integer too long to read ({str(exc).split(';')[0]}); a scene "
                         f"value is a finite number in SI units, at most about 1.8e308 in magnitude.") from None
    try:
        return scene_from_dict(d, base_dir=p.resolve().parent)
    except InputError as exc:
        raise InputError(f"scene file '{p}': {exc}") from None


def _scenes_dir() -> Path:
    return Path(__file__).resolve().parent / "scenes"


def builtin_scenes() -> list[str]:
    """Names of the built-in scenes shipped in ``cfm_core/scene/scenes``.

    Returns
    -------
    list of str
        Sorted names, e.g. ``["drop-test", "relaxation", "single-element"]``.
    """
    return sorted(p.stem for p in _scenes_dir().glob("*.toml"))


def builtin_scene(name: str) -> Scene:
    """A built-in scene by name ("drop-test", "single-element", "relaxation").

    Parameters
    ----------
    name : str
        One of :func:`builtin_scenes`.

    Returns
    -------
    Scene
        The validated scene (SI units), e.g. the paper's drop test: 50 x 50 x 8 mm specimen,
        0.220 kg hemisphere of radius 55 mm at 1 m/s (docs/conventions.md section 4).

    Raises
    ------
    InputError
        Unknown name (the message lists the built-in scenes).
    """
    if name not in builtin_scenes():
        raise InputError(f"unknown built-in scene {name!r}; available: "
                         f"{', '.join(builtin_scenes())}.")
    return load_scene(_scenes_dir() / f"{name}.toml")
