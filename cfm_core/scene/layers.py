"""Regions of a drop-test specimen with their own material: layers of a block, parts of a mesh.

``[[specimen.layers]]`` (listed from the plate upwards) cut the built-in block into layers,
each with its thickness (m), material, parameters (SI), density (kg/m^3) and element size through
its thickness (m); the in-plane element size stays [specimen] element_size, so the mesh is
conforming (the layers share the nodes of their interfaces: tied). ``[parts.NAME]`` give the
material of the cells of a user mesh that a cell set / physical group named NAME holds
(:func:`cfm_core.scene.mesh.read_cell_sets`). A region that names no material inherits the
[material] section (name, parameters, moduli, elastic) and adds its own parameters on top.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Mapping

import numpy as np

from ..errors import InputError
from .values import _choice, _num, _set, _text, parameter_value

__all__ = ["Layer", "PartSettings", "make_layers", "make_parts", "layer_cells", "layer_z", "bind_material",
           "region_table"]


def _parameters(section: str, p) -> tuple:
    """Parameter overrides as sorted (name, value) pairs, each a finite number (SI)."""
    items = p.items() if isinstance(p, Mapping) else p
    try:
        items = [(k, v) for k, v in items]
    except (TypeError, ValueError):
        raise InputError(f"[{section}.parameters] = {p!r} must be a table of name = number (SI units).") from None
    out = {}
    for k, v in items:
        _text(f"{section}.parameters", "name", k)
        out[k] = parameter_value(f"{section}.parameters", k, v)
    return tuple(sorted(out.items()))


def _region(obj, section: str) -> None:
    """Check the material keys shared by layers and parts (in place)."""
    if obj.material is not None:
        _text(section, "material", obj.material)
    if obj.moduli is not None:
        _choice(section, "moduli", obj.moduli, ("instantaneous", "long-term"))
    if obj.elastic is not None and not isinstance(obj.elastic, (bool, np.bool_)):
        raise InputError(f"[{section}] elastic = {obj.elastic!r} must be true or false.")
    if obj.elastic is not None:
        _set(obj, elastic=bool(obj.elastic))
    _set(obj, parameters=_parameters(section, obj.parameters))
    if obj.density is not None:
        _set(obj, density=_num(section, "density", obj.density, "kg/m^3", 1, 1e5))


@dataclass(frozen=True)
class Layer:
    """One ``[[specimen.layers]]`` entry (SI units).

    thickness (m, 1e-5..0.1); material (registered name; default: the [material] section's);
    parameters (overrides by name, SI; a layer without material adds them to [material]'s);
    density (kg/m^3, 1..1e5; default: [specimen] density); element_size (m, the element size
    through this layer's thickness, 0 < element_size <= thickness; default: [specimen]
    element_size); name (text; default "layer1", "layer2", ... from the plate up); moduli and
    elastic as in [material] (default: [material]'s).
    """

    thickness: float
    material: str | None = None
    parameters: tuple = ()
    density: float | None = None
    element_size: float | None = None
    name: str | None = None
    moduli: str | None = None
    elastic: bool | None = None

    def __post_init__(self):
        s = "specimen.layers"
        _set(self, thickness=_num(s, "thickness", self.thickness, "m", 1e-5, 0.1,
                                  note="It is the thickness of this layer; the specimen's is their sum."))
        if self.name is not None:
            _text(s, "name", self.name)
        if self.element_size is not None:
            _set(self, element_size=_num(s, "element_size", self.element_size, "m", 0, self.thickness, lo_open=True,
                                         note="It is the element size through this layer; at most the layer "
                                              "thickness, so that the layer has at least one element."))
        _region(self, s)

    @property
    def parameter_dict(self) -> dict[str, float]:
        """The layer's own parameter overrides {name: value (SI)}."""
        return dict(self.parameters)


@dataclass(frozen=True)
class PartSettings:
    """One ``[parts.NAME]`` table: the material of a named cell set of the [specimen] mesh (SI units).

    name (the cell set / physical group name, the table's key); material (registered name;
    default: [material]'s); parameters (overrides by name, SI); density (kg/m^3; default:
    [specimen] density); moduli, elastic (default: [material]'s).
    """

    name: str
    material: str | None = None
    parameters: tuple = ()
    density: float | None = None
    moduli: str | None = None
    elastic: bool | None = None

    def __post_init__(self):
        _text("parts", "name", self.name)
        _region(self, f"parts.{self.name}")

    @property
    def parameter_dict(self) -> dict[str, float]:
        """The part's own parameter overrides {name: value (SI)}."""
        return dict(self.parameters)


def _from_tables(cls, tables, where: str, label, extra=None, fixed=()):
    """Validate a list of tables (or instances) into ``cls`` objects; errors say which one.
    ``extra(i, table)`` gives values of the ``fixed`` fields (not keys of the table)."""
    allowed = [f.name for f in fields(cls) if f.name not in fixed]
    out = []
    for i, t in enumerate(tables):
        if isinstance(t, cls):
            out.append(t)
            continue
        if not isinstance(t, Mapping):
            raise InputError(f"{where}: entry {label(i, None)} must be a table, got {t!r}.")
        unknown = [k for k in t if k not in allowed]
        if unknown:
            raise InputError(f"{where}: unknown key '{unknown[0]}' in {label(i, t)}; allowed keys: "
                             f"{', '.join(allowed)}.")
        try:
            out.append(cls(**{**t, **(extra(i, t) if extra else {})}))
        except TypeError:
            raise InputError(f"{where}: {label(i, t)} needs thickness (m).") from None
        except InputError as exc:
            raise InputError(f"{label(i, t)}: {exc}") from None
    return tuple(out)


def make_layers(value) -> tuple:
    """[[specimen.layers]] as a tuple of :class:`Layer` (from the plate up); names default to layerN.

    Raises
    ------
    InputError
        Not a list of tables, an unknown key, a missing thickness, a bad value (the message names
        the layer by number and name), or two layers with the same name.
    """
    if isinstance(value, Mapping) or not isinstance(value, (list, tuple)):
        raise InputError(f"[specimen] layers = {value!r} must be an array of tables [[specimen.layers]], listed "
                         f"from the plate upwards, each with thickness (m).")

    def label(i, t):
        name = t.get("name") if isinstance(t, Mapping) else None
        return f"layer {i + 1} of [[specimen.layers]] (counted from the plate{', ' + repr(name) if name else ''})"

    layers = _from_tables(Layer, value, "[specimen] layers", label)
    layers = tuple(lay if lay.name is not None else Layer(**{**_plain(lay), "name": f"layer{i + 1}"})
                   for i, lay in enumerate(layers))
    _unique([lay.name for lay in layers], "[[specimen.layers]] name")
    return layers


def make_parts(table) -> tuple:
    """[parts] as a tuple of :class:`PartSettings`, in the order of the file.

    Raises
    ------
    InputError
        Not a table of tables, an unknown key or a bad value (the message names the part).
    """
    if not isinstance(table, Mapping) or not all(isinstance(v, (Mapping, PartSettings)) for v in table.values()):
        raise InputError(f"[parts] must hold one table per mesh cell set, [parts.NAME] with material = ..., got "
                         f"{table!r}.")
    items = list(table.items())
    return _from_tables(PartSettings, [v for _, v in items], "[parts]",
                        lambda i, t: f"[parts.{items[i][0]}]",
                        extra=lambda i, t: {"name": items[i][0]}, fixed=("name",))


def _unique(names, what):
    seen = set()
    for n in names:
        if n in seen:
            raise InputError(f"{what} {n!r} is used twice; give each region its own name.")
        seen.add(n)


def _plain(obj) -> dict:
    return {f.name: getattr(obj, f.name) for f in fields(obj)}


def region_table(obj, skip=("name",)) -> dict:
    """A layer or part as a plain TOML table (None values left out, parameters as a dict)."""
    out = {}
    for f in fields(obj):
        val = getattr(obj, f.name)
        if f.name in skip or val is None or (f.name == "parameters" and not val):
            continue
        out[f.name] = dict(val) if f.name == "parameters" else val
    return out


def layer_cells(layers, element_size: float) -> list[int]:
    """Elements through each layer's thickness: round(thickness / element_size), at least 1.

    Parameters
    ----------
    layers : sequence of Layer
        From the plate up.
    element_size : float
        [specimen] element_size (m), for layers that give none.
    """
    out = []
    for lay in layers:
        h = lay.element_size if lay.element_size is not None else element_size
        out.append(max(1, math.floor(lay.thickness / h + 0.5)))
    return out


def layer_z(layers, element_size: float) -> np.ndarray | None:
    """z of the node planes of a layered block (m), or None when they are equally spaced.

    Each layer's planes are equally spaced between its bottom and top (the sum of the
    thicknesses below, exactly as float64 adds them). When every layer has the same spacing
    (thickness / elements equal to 1e-12), the block is the one-material block of the same
    thickness and None is returned, so that it is built by the very same code (same nodes).

    Returns
    -------
    ndarray, shape (sum of the layers' elements + 1,) or None
    """
    n = layer_cells(layers, element_size)
    steps = [lay.thickness / k for lay, k in zip(layers, n)]
    if max(steps) - min(steps) <= 1e-12 * max(steps):
        return None
    z, bottom = [np.zeros(1)], 0.0
    for lay, k in zip(layers, n):
        z.append(bottom + np.linspace(0.0, lay.thickness, k + 1)[1:])
        bottom = bottom + lay.thickness
    return np.concatenate(z)


def unused_by_layers(scene, names) -> dict:
    """The names among ``names`` ([material] parameters, ``"density"``) that no layer of a layered
    specimen takes from the scene's sections, with the reason: a layer that names its own material
    takes no [material] parameter, one that gives a parameter itself does not take that one, and
    one with its own density does not take [specimen] density. A sweep or override of such a name
    changes nothing (every run the same, labelled with values never applied). Empty for a specimen
    without layers (a mesh's parts are known only from the mesh: cells outside every part take
    the [material] section).

    Parameters
    ----------
    scene : Scene
        A drop-test scene.
    names : iterable of str
        Parameter names and the scene keys ``"density"``, ``"material"``, ``"moduli"``, ``"elastic"``.

    Returns
    -------
    dict
        {name: reason (text)} for the names no layer uses.
    """
    layers = getattr(getattr(scene, "specimen", None), "layers", ()) or ()
    if not layers:
        return {}
    own = [f"{lay.name or f'layer{i + 1}'} ({lay.material})" for i, lay in enumerate(layers) if lay.material]
    out = {}
    for name in names:
        if name == "density":
            if all(lay.density is not None for lay in layers):
                out[name] = "every layer gives its own density"
        elif name == "material":
            if len(own) == len(layers):
                out[name] = "every layer names its own material: " + ", ".join(own)
        elif name in ("moduli", "elastic"):
            if not any(lay.material is None and getattr(lay, name) is None for lay in layers):
                out[name] = (f"every layer names its own material or gives its own {name}: " +
                             ", ".join(f"{lay.name or f'layer{i + 1}'} ({lay.material or getattr(lay, name)})"
                                       for i, lay in enumerate(layers)))
        elif not any(lay.material is None and name not in lay.parameter_dict for lay in layers):
            out[name] = ("every layer names its own material: " + ", ".join(own) if len(own) == len(layers) else
                         f"no layer takes {name} from [material] (each gives its own {name} or names its own material)")
    return out


def refuse_unused(scene, names, flag, effect: str, advice: str = "Give the layer its value in the scene file.") -> None:
    """InputError for the first of ``names`` no layer uses (:func:`unused_by_layers`).

    Parameters
    ----------
    scene : Scene
        A drop-test scene.
    names : iterable of str
        Parameter names and the scene keys of :func:`unused_by_layers`.
    flag : callable
        name -> how the command line names it (``"--vary k1"``, ``"--density"``).
    effect : str
        What would happen otherwise, for the message.
    advice : str
        The message's last sentence: what to do instead (``{name}`` stands for the name).
    """
    unused = unused_by_layers(scene, names)
    if unused:
        name, why = next(iter(unused.items()))
        where = {"density": "[specimen] density", "material": "[material] name"}.get(name, f"[material] {name}")
        raise InputError(f"{flag(name)}: no layer of the specimen uses {where} ({why}), so {effect}. "
                         f"{advice.replace('{name}', name)}")


def regions(scene) -> list[tuple[str, object]]:
    """(label, region) of every layer and part of a scene that has its own material or parameters; the
    label names it as a scene file does (``[[specimen.layers]] 2 (fat)``, ``[parts.skin]``)."""
    out = []
    specimen = scene.specimen
    for i, layer in enumerate(getattr(specimen, "layers", ()) or ()):
        out.append((f"[[specimen.layers]] {i + 1} ({layer.name or f'layer{i + 1}'})", layer))
    for part in scene.parts or ():
        out.append((f"[parts.{part.name}]", part))
    return [(label, r) for label, r in out if r.material is not None or r.parameters]


def bind_material(region, scene_material, default_density: float, material=None):
    """(Material, density) of a layer or part.

    Parameters
    ----------
    region : Layer or PartSettings
        The region's keys.
    scene_material : MaterialSettings
        The [material] section (what a region without material inherits).
    default_density : float
        [specimen] density (kg/m^3), for a region without density.
    material : Material, optional
        A bound material replacing the [material] section's (``build_model(scene, material)``):
        used for regions that name no material and have no own parameters, moduli or elastic.

    Returns
    -------
    (Material, float)
        The bound material and the density (kg/m^3).

    Raises
    ------
    InputError
        Unknown material or a parameter out of its range (the message names the region).
    """
    from ..material.registry import make_material

    rho = float(region.density) if region.density is not None else float(default_density)
    own = (region.parameters, region.moduli, region.elastic)
    if region.material is None and material is not None and own == ((), None, None):
        return material, rho
    inherit = region.material is None
    name = scene_material.name if inherit else region.material
    params = {**(scene_material.parameter_dict if inherit else {}), **region.parameter_dict}
    moduli = region.moduli if region.moduli is not None else scene_material.moduli
    elastic = region.elastic if region.elastic is not None else scene_material.elastic
    where = f"layer {region.name!r}" if isinstance(region, Layer) else f"[parts.{region.name}]"
    try:
        return make_material(name, params, moduli, elastic), rho
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def mesh_part_elements(mesh: str, n_elements: int, parts) -> list[np.ndarray]:
    """The hexahedra of each [parts.NAME] in a user mesh (sorted int64 indices, in part order).

    A name is matched exactly, else case-insensitively when that is unique (Abaqus names are
    case-insensitive).

    Parameters
    ----------
    mesh : str
        The [specimen] mesh path.
    n_elements : int
        Its number of hexahedra.
    parts : sequence of PartSettings
        The [parts] tables.

    Returns
    -------
    list of ndarray
        One index array per part.

    Raises
    ------
    InputError
        A part name that no cell set of the mesh has (the message lists the names the mesh has),
        a cell in two parts, or cells in no part (their count and the first few, by the file's element
        labels where it has them, else by their place in the file).
    """
    from .mesh import file_mesh_names
    from .sections import read_specimen_cell_sets  # the sections import this module

    sets = read_specimen_cell_sets(mesh)
    have = ", ".join(repr(k) for k in sets) or "none (no cell sets, physical groups or integer cell data)"
    out = []
    owner = np.full(n_elements, -1, dtype=np.int64)
    for i, part in enumerate(parts):
        key = part.name if part.name in sets else None
        if key is None:
            folded = [k for k in sets if k.lower() == part.name.lower()]
            key = folded[0] if len(folded) == 1 else None
        if key is None:
            raise InputError(f"[parts.{part.name}]: the mesh '{mesh}' has no cell set (cell set, physical group or "
                             f"integer cell-data id) named {part.name!r}; the names it has: {have}. Rename the "
                             f"part to one of them.")
        el = np.asarray(sets[key], dtype=np.int64)
        taken = el[owner[el] >= 0]
        if taken.size:
            other = parts[int(owner[taken[0]])].name
            raise InputError(f"[parts.{part.name}] and [parts.{other}] both hold {taken.size} cell(s) of the mesh "
                             f"'{mesh}' (e.g. {file_mesh_names(mesh).element(int(taken[0]))}); a cell must belong "
                             f"to exactly one part. Fix the mesh's cell sets or list only disjoint ones.")
        owner[el] = i
        out.append(el)
    free = np.flatnonzero(owner < 0)
    if free.size:
        first = file_mesh_names(mesh).elements(free[:5], more=free.size > 5)
        raise InputError(f"[parts]: {free.size} of the {n_elements} hexahedra of the mesh '{mesh}' are in no part "
                         f"({first}); every cell needs a material. Add a "
                         f"[parts.NAME] for their cell set (the mesh has: {have}) or put them in one in the mesher.")
    return out
