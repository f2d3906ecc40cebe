"""Plausibility of a scene's SI values: unit slips (g for kg, mm for m, mm/s for m/s, kPa for Pa).

The sections (:mod:`cfm_core.scene.sections`) accept every value that is legal in SI units; some
legal values are almost surely a unit written wrongly: 220 for a 220 g impactor is read as 220 kg,
which runs for seconds and then fails the physics checks (exit 3). This module says so before
anything runs, in one warning paragraph naming the field, the value, the unit expected and the
likely mistake; the run then goes ahead as given, so that the run checks decide (a legal value is
never refused on a guess). Bounds (SI):

========================  =====================================  ===============================
field                     "almost surely a unit slip" above      "unusually large" above
========================  =====================================  ===============================
[impactor] mass           100 kg                                 20 kg
[impactor] velocity       100 m/s                                20 m/s (a fall from 20 m)
[impactor] radius         (refused above 1 m by the section)     0.25 m
[specimen] width          (refused above 1 m by the section)     0.5 m
========================  =====================================  ===============================

An impactor mass below 1 g (1e-3 kg) and a speed below 1 cm/s are warned about as converted twice
(:data:`LOW_BOUNDS`). Radius and width above 1 m, the thickness (1e-4 .. 0.1 m), the element size (at most the
thickness) and the density (1 .. 1e5 kg/m^3) are refused by the sections themselves, whose
messages carry the same hint (:func:`unit_hint`). Within those ranges, warned about:

========================  =====================================  ===============================
field                     "almost surely a unit slip"            "unusual"
========================  =====================================  ===============================
any density (specimen,    below 100 kg/m^3 (g/cm^3: 1.06 for     below 500 or above 3000 kg/m^3
layer, part, element)     1060)                                  (soft tissue 900-1100, bone
                                                                 up to ~2000)
[element] / [relaxation]  above 0.1 m (mm: size = 1 for 1 mm)    above 0.02 m
size (one cube's edge)
========================  =====================================  ===============================

The density row is :func:`density_warning`, which ``cfm export --density`` uses too.

Every scene type's material is checked too (:func:`cfm_core.material.plausible.check_material`:
a modulus 100 times off its typical value, a Poisson ratio far from 0.5, gamma_inf near 0), and a
drop-test specimen with fewer than :data:`MIN_LAYERS` = 2 elements through the thickness is warned
about: with element_size = thickness (one layer, 3 x 3 elements in the quarter) the default drop
test's peak is 23 % below that of the 2 mm mesh (43.5 g vs 56.7 g, numba; 2 layers of 4 mm: 1.6 %
below), measured in ``tests/cfm_core/scene/test_plausible.py``.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..material.plausible import check_material
from ..material.registry import make_material

#: SI unit -> the units often typed instead, each with the factor from it to the SI unit (a density in
#: tonne/mm^3 is what an LS-DYNA or Abaqus model in mm-s-tonne units holds: 9.2e-10 for 920 kg/m^3; in
#: kg/mm^3 one in mm-ms-kg units: 9.2e-7; docs/user/export.md's table of units).
UNIT_SLIPS = {"m": (("mm", 1e-3),), "kg": (("g", 1e-3),), "m/s": (("mm/s", 1e-3),),
              "kg/m^3": (("g/cm^3", 1e3), ("tonne/mm^3", 1e12), ("kg/mm^3", 1e9))}

#: Smallest value a unit-slip hint proposes (SI): below it the corrected value is no more plausible.
PLAUSIBLE_FLOOR = {"m": 1e-4, "kg": 1e-3, "m/s": 1e-2}

#: (section, key, SI unit, a unit slip above (None: refused by the section), unusual above, what it is).
BOUNDS = (
    ("impactor", "mass", "kg", 100.0, 20.0, "impactor mass (heavier than any drop-tower or fall impactor on a specimen)"),
    ("impactor", "velocity", "m/s", 100.0, 20.0, "impact speed"),
    ("impactor", "radius", "m", None, 0.25, "impactor (hemisphere) radius"),
    ("specimen", "width", "m", None, 0.5, "specimen width"),
)

#: (section, key, SI unit, unusual below, what it is): a value below is warned about as converted twice (0.22 g
#: written 0.00022 kg for a 220 g impactor ran a 0.22 g one without a word).
LOW_BOUNDS = (
    ("impactor", "mass", "kg", 1e-3, "impactor mass"),
    ("impactor", "velocity", "m/s", 1e-2, "impact speed"),
)

#: Densities (kg/m^3): below the first almost surely g/cm^3; outside (second, third) unusual for tissue.
DENSITY_SLIP, DENSITY_USUAL = 100.0, (500.0, 3000.0)
#: Edge of a single-element or relaxation cube (m): above the first almost surely mm, above the second unusual.
CUBE_SLIP, CUBE_USUAL = 0.1, 0.02

#: A flat impactor's rim radius under this many element sizes is warned about (not resolved).
RIM_ELEMENTS = 2.0
#: Fewer elements than this through a drop-test specimen's thickness are warned about.
MIN_LAYERS = 2

_FLAGS = {"mass": "--mass", "radius": "--radius", "velocity": "--velocity", "width": "--width",
          "thickness": "--thickness", "element_size": "--element-size", "density": "--density"}


def unit_hint(key: str, value: float, unit: str, lo: float = 0.0, hi: float = float("inf"), fix: str | None = None,
              flag: bool = True, option: str | None = None) -> str:
    """The likely unit slip of a value outside its range, as a sentence ("" when none fits).

    Parameters
    ----------
    key : str
        The field (e.g. ``"thickness"``), named in the hint.
    value : float
        The value given, read in ``unit``.
    unit : str
        The SI unit the field is read in: ``"m"``, ``"kg"``, ``"m/s"`` or ``"kg/m^3"`` (others: no hint).
    lo, hi : float
        The allowed or plausible range (SI); the corrected value must fall inside it.
    fix : str, optional
        What to do instead of writing the corrected value (e.g. for a value taken from a mesh file);
        ``{value}`` in it is replaced by the corrected value (SI) of the unit that matched.
    flag : bool
        Name the command-line flag that sets the field (default); False for a layer's or part's field,
        which no flag sets (``--element-size`` sets [specimen]'s).
    option : str, optional
        The option of a command without a scene (``"--density"`` of ``cfm export``): the hint says
        "Give --density 920" instead of "Write density = 920".

    Returns
    -------
    str
        E.g. ``"220 kg: did you mean 0.22 kg (220 g)? Write mass = 0.22 (--mass 0.22)."``, or ``""``.
        Of the units often typed instead (:data:`UNIT_SLIPS`), the first whose corrected value falls
        in [lo, hi] is named.
    """
    if unit not in UNIT_SLIPS or value == 0.0:  # zero is no unit slip
        return ""
    lo = max(lo, PLAUSIBLE_FLOOR.get(unit, 0.0))  # no "did you mean 2e-05 m" for an element size
    for alt, factor in UNIT_SLIPS[unit]:
        if lo <= value * factor <= hi:
            flagged = f" ({_FLAGS[key]} {value * factor:g})" if key in _FLAGS and flag else ""
            todo = (fix.format(value=value * factor) if fix else f"Give {option} {value * factor:g}" if option else
                    f"Write {key} = {value * factor:g}{flagged}")
            return (f"{value:g} {unit}: did you mean {value * factor:g} {unit} ({value:g} {alt})? "
                    f"{todo}; every value is in SI units.")
    for alt, factor in UNIT_SLIPS[unit]:
        if lo <= value / factor <= hi and value < lo:  # e.g. mm converted to m twice
            return (f"{value:g} {unit}: did you mean {value / factor:g} {unit}? The value looks converted from "
                    f"{alt} to {unit} twice; every value is in SI units.")
    return ""


def check_plausible(scene, material=None) -> list[str]:
    """Warnings about the values of a scene that are surely or probably unit slips or too coarse.

    Parameters
    ----------
    scene : Scene
        A validated scene (any type).
    material : Material, optional
        The bound material that will run, when it is not the scene's own (default: bound from the
        scene's [material] section).

    Returns
    -------
    list of str
        One paragraph per finding: a drop-test value above its bounds in :data:`BOUNDS`, naming
        the section, the field, the value, the SI unit and the likely slip (e.g. "220 kg: did you
        mean 0.22 kg (220 g)?"); a specimen with fewer than :data:`MIN_LAYERS` elements through
        the thickness; then the material's (:func:`cfm_core.material.plausible.check_material`,
        e.g. "k1 = 1.32 Pa is 1,000x below the typical 1320 Pa ... Was it kPa?"). The run goes
        ahead as given: a value is never refused on a guess, and the run checks stop a run whose
        physics breaks (exit 3).

    Raises
    ------
    InputError
        The scene's material is unknown or a parameter is out of its range (as when it is built).
    """
    if material is None:
        m = scene.material
        material = make_material(m.name, m.parameter_dict, m.moduli, m.elastic)
    warnings = _drop_test_warnings(scene) if scene.type == "drop-test" else []
    warnings += _cube_warnings(scene) + _ramp_warnings(scene) + _density_warnings(scene)
    return warnings + check_material(material) + _region_material_warnings(scene, material)


def _region_material_warnings(scene, material) -> list[str]:
    """:func:`check_material` of each layer's and part's own material (a kPa slip under a layer's
    parameters ran silently while the same value in [material] was warned about), each finding
    naming its layer or part instead of [material]; moduli far above the typical values are not
    warned about there (a layer of skin or muscle is stiffer than fat)."""
    from .layers import bind_material, regions

    out = []
    density = float(scene.specimen.density) if scene.specimen is not None else 1000.0
    for label, region in regions(scene):
        bound, _ = bind_material(region, scene.material, density, material)
        out += [_in_region(text, label) for text in check_material(bound, above=False)]
    return out


def _in_region(text: str, label: str) -> str:
    """A [material] warning said of a layer or part: its label for [material], and the fix written in the
    layer's or part's parameters (``--param`` sets [material]'s, not theirs)."""
    text = re.sub(r" \(--param \w+=[^)]+\)", lambda _: f" in the parameters of {label}", text)
    return text.replace("[material]", label, 1) if text.startswith("[material]") else f"{label}: {text}"


def _densities(scene) -> list[tuple[str, float]]:
    """(where, density in kg/m^3) of every density a scene gives."""
    out = []
    if scene.specimen is not None:
        out.append(("[specimen] density", float(scene.specimen.density)))
        for i, layer in enumerate(getattr(scene.specimen, "layers", ()) or ()):
            if layer.density is not None:
                out.append((f"[[specimen.layers]] {i + 1} ({layer.name}) density", float(layer.density)))
    for part in scene.parts or ():
        if part.density is not None:
            out.append((f"[parts.{part.name}] density", float(part.density)))
    if scene.element is not None:
        out.append(("[element] density", float(scene.element.density)))
    return out


def density_warning(where: str, rho: float, fix: str | None = None, option: str | None = None,
                    as_given: str | None = None) -> str | None:
    """The warning for a density (kg/m^3) that is almost surely a unit slip (below :data:`DENSITY_SLIP`: g/cm^3)
    or unusual for tissue (outside :data:`DENSITY_USUAL`): the one check of a scene's densities and of
    ``cfm export --density``.

    Parameters
    ----------
    where : str
        Where it was given: ``"[specimen] density"`` (named ``where = value``) or an option ``"--density"``
        (named ``--density value``).
    rho : float
        The density (kg/m^3), within the range the caller accepts.
    fix, option
        Passed to :func:`unit_hint` (what to do instead; the option of a command without a scene).
    as_given : str, optional
        What happens to the value, a clause (default: a scene's "it runs as given", with the time step a slip
        costs; ``cfm export``: "the card holds it as given").

    Returns
    -------
    str or None
        The warning, or None for a usual density.
    """
    lo, hi = DENSITY_USUAL
    named = f"{where} {rho:g}" if where.startswith("--") else f"{where} = {rho:g}"
    if rho < DENSITY_SLIP:
        hint = unit_hint("density", rho, "kg/m^3", lo, hi, fix=fix, option=option)
        after = (f"{as_given.capitalize()}." if as_given else
                 f"It runs as given (a specimen {1e3 / rho:.0f}x lighter than soft tissue takes a "
                 f"{(1e3 / rho) ** 0.5:.0f}x smaller time step).")
        return (f"{named} kg/m^3 is not a plausible tissue density (soft tissue 900-1100, bone up to ~2000 kg/m^3): "
                f"below {DENSITY_SLIP:g} kg/m^3 it is almost surely a unit slip. "
                f"{hint or 'Give the density in kg/m^3.'} {after}")
    if not lo <= rho <= hi:
        return (f"{named} kg/m^3 is unusual for tissue (soft tissue 900-1100, bone up to ~2000 kg/m^3); "
                f"{as_given or 'it runs as given'}.")
    return None


def _density_warnings(scene) -> list[str]:
    """A density that is almost surely in g/cm^3 (below :data:`DENSITY_SLIP`), or unusual for tissue
    (:func:`density_warning`)."""
    warnings = []
    for where, rho in _densities(scene):
        fix = None if where.startswith("[specimen]") else f"Write density = {{value:g}} in {where.split(' density')[0]}"
        text = density_warning(where, rho, fix=fix)  # --density sets [specimen]'s only
        if text:
            warnings.append(text)
    return warnings


def _cube_warnings(scene) -> list[str]:
    """The edge of a single-element or relaxation cube: almost surely mm above :data:`CUBE_SLIP`."""
    sec = scene.element if scene.element is not None else scene.relaxation
    if sec is None:
        return []
    name = "element" if scene.element is not None else "relaxation"
    size = float(sec.size)
    if size > CUBE_SLIP:
        hint = unit_hint("size", size, "m", 1e-5, CUBE_USUAL)
        return [f"[{name}] size = {size:g} m is not a plausible edge of a tissue cube: above {CUBE_SLIP:g} m it is "
                f"almost surely a unit slip. {hint or 'Give the size in m.'} It runs as given."]
    if size > CUBE_USUAL:
        return [f"[{name}] size = {size:g} m is unusually large for the edge of a tissue cube (above "
                f"{CUBE_USUAL:g} m); it runs as given. {unit_hint('size', size, 'm', 1e-5, CUBE_USUAL)}".rstrip()]
    return []


def _ramp_warnings(scene) -> list[str]:
    """A single-element or relaxation scene whose [scene] end_time comes before its ramp ends: the
    stretch it names is never reached (end_time = 1 ms before a 5 ms ramp ran with exit 0)."""
    sec = scene.element if scene.element is not None else scene.relaxation
    if sec is None or scene.settings.end_time is None:
        return []
    name = "element" if scene.element is not None else "relaxation"
    ramp, end = float(sec.load_time), float(scene.settings.end_time)
    if end >= ramp * (1.0 - 1e-9):
        return []
    reached = 1.0 + (float(sec.stretch) - 1.0) * end / ramp
    return [f"[scene] end_time = {end:g} s ends before the [{name}] ramp does ({ramp:g} s to the stretch "
            f"{float(sec.stretch):g}): the run stops at the stretch {reached:.4g}, so the stretch of the scene is never "
            f"reached. Raise end_time (or leave it out: automatic), or lower the stretch. It runs as given."]


def layers_through_thickness(specimen) -> int:
    """Number of elements through a drop-test specimen's thickness.

    Parameters
    ----------
    specimen : Specimen
        A validated [specimen] section.

    Returns
    -------
    int
        nz of the structured grid; for a mesh file, the thickness (m) over the median z extent
        of its elements (m), rounded (at least 1).
    """
    if specimen.mesh is None:
        return int(specimen.grid[2])
    from .sections import read_specimen_mesh  # the sections import this module

    nodes, hexes, _ = read_specimen_mesh(specimen.mesh, bool(specimen.merge_nodes))
    z = nodes[hexes, 2]
    extent = float(np.median(z.max(axis=1) - z.min(axis=1)))
    return max(1, int(round(specimen.thickness / extent))) if extent > 0 else 1


def _bounded_value(scene, section: str, key: str) -> float:
    """The SI value of a :data:`BOUNDS` or :data:`LOW_BOUNDS` field (a velocity vector's speed)."""
    obj = getattr(scene, section)
    return float(obj.speed if key == "velocity" else getattr(obj, key))


def _drop_test_warnings(scene) -> list[str]:
    """Unit slips of the drop-test values (:data:`BOUNDS`) and a specimen too coarse through its thickness."""
    warnings = []
    for section, key, unit, slip, unusual, what in BOUNDS:
        value = _bounded_value(scene, section, key)
        if slip is not None and value > slip:
            hint = unit_hint(key, value, unit, 0.0, slip)
            warnings.append(f"[{section}] {key} = {value:g} {unit} is not a plausible {what}: above {slip:g} {unit} it "
                            f"is almost surely a unit slip. {hint or f'Give the {key} in {unit}.'} It runs as given; "
                            f"the run checks stop it if its physics breaks.")
        elif value > unusual:
            hint = unit_hint(key, value, unit, 0.0, unusual)
            warnings.append(f"[{section}] {key} = {value:g} {unit} is unusually large for the {what.split(' (')[0]} "
                            f"(above {unusual:g} {unit}); it runs as given. {hint}".rstrip())
    for section, key, unit, low, what in LOW_BOUNDS:
        value = _bounded_value(scene, section, key)
        if 0.0 < value < low:
            warnings.append(f"[{section}] {key} = {value:g} {unit} is unusually small for the {what} (below {low:g} "
                            f"{unit}): was it converted twice ({value * 1e3:g} {unit} meant)? Every value is in SI "
                            f"units. It runs as given.")
    sp = scene.specimen
    if sp.mesh is None and sp.element_size and float(sp.element_size) > 0.5 * float(sp.width):
        warnings.append(f"[specimen] element_size = {sp.element_size:g} m is larger than half the width "
                        f"{sp.width:g} m: the mesh has a single element across half the width ({0.5 * sp.width:g} m), so "
                        f"the elements are not the size asked for and the specimen is far narrower than the "
                        f"impactor's contact (radius {scene.impactor.radius:g} m). Was the width meant in m "
                        f"(--width)? It runs as given.")
    layers = layers_through_thickness(sp)
    if layers < MIN_LAYERS:
        source = f"the mesh '{sp.mesh}' has" if sp.mesh is not None else f"element_size = {sp.element_size:g} m gives"
        fix = ("refine the mesh through the thickness" if sp.mesh is not None else
               f"use element_size <= {sp.thickness / MIN_LAYERS:g} m (--element-size {sp.thickness / MIN_LAYERS:g})")
        warnings.append(f"[specimen] {source} {layers} element through the thickness {sp.thickness:g} m: too coarse. "
                        f"With element_size = thickness the default drop test's peak is 23 % low (43.5 g instead of "
                        f"56.7 g with 2 mm elements); give it at least {MIN_LAYERS}: {fix}. It runs as given.")
    imp = scene.impactor
    h = float(sp.element_size) if sp.element_size else 0.0
    edge = float(imp.edge) if getattr(imp, "shape", "hemisphere") == "flat" else 0.0   # the default when not given
    corner = math.hypot(*(0.5 * float(sp.width) + abs(float(c)) for c in imp.point))     # farthest specimen corner
    if 0.0 < edge < RIM_ELEMENTS * h and float(imp.radius) - edge < corner:             # the rim meets the specimen
        warnings.append(f"[impactor] edge_radius = {edge:g} m is less than {RIM_ELEMENTS:g} element sizes "
                        f"({RIM_ELEMENTS * h:g} m at element_size = {h:g} m): the mesh does not resolve the flat "
                        f"impactor's rim, and the fat squeezed round it may fold elements (the built-in "
                        f"flat-impactor scene folded at 4 ms with a 1 mm rim on 1 mm elements; 3 mm ran). It runs "
                        f"as given; the run checks stop it if an element folds.")
    return warnings
