"""Plausibility of a drop-test scene's SI values: unit slips (g for kg, mm for m, mm/s for m/s).

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

Radius and width above 1 m, the thickness (1e-4 .. 0.1 m), the element size (at most the
thickness) and the density (1 .. 1e5 kg/m^3) are refused by the sections themselves, whose
messages carry the same hint (:func:`unit_hint`).
"""

from __future__ import annotations

#: SI unit -> (the unit often typed instead, the factor from it to the SI unit).
UNIT_SLIPS = {"m": ("mm", 1e-3), "kg": ("g", 1e-3), "m/s": ("mm/s", 1e-3), "kg/m^3": ("g/cm^3", 1e3)}

#: (section, key, SI unit, a unit slip above (None: refused by the section), unusual above, what it is).
BOUNDS = (
    ("impactor", "mass", "kg", 100.0, 20.0, "impactor mass (heavier than any drop-tower or fall impactor on a specimen)"),
    ("impactor", "velocity", "m/s", 100.0, 20.0, "impact speed"),
    ("impactor", "radius", "m", None, 0.25, "impactor (hemisphere) radius"),
    ("specimen", "width", "m", None, 0.5, "specimen width"),
)

_FLAGS = {"mass": "--mass", "radius": "--radius", "velocity": "--velocity", "width": "--width",
          "thickness": "--thickness", "element_size": "--element-size", "density": "--density"}


def unit_hint(key: str, value: float, unit: str, lo: float = 0.0, hi: float = float("inf"), fix: str | None = None) -> str:
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
        What to do instead of writing the corrected value (e.g. for a value taken from a mesh file).

    Returns
    -------
    str
        E.g. ``"220 kg: did you mean 0.22 kg (220 g)? Write mass = 0.22 (--mass 0.22)."``, or ``""``.
    """
    if unit not in UNIT_SLIPS:
        return ""
    alt, factor = UNIT_SLIPS[unit]
    flag = f" ({_FLAGS[key]} {value * factor:g})" if key in _FLAGS else ""
    if lo <= value * factor <= hi:
        todo = fix or f"Write {key} = {value * factor:g}{flag}"
        return (f"{value:g} {unit}: did you mean {value * factor:g} {unit} ({value:g} {alt})? "
                f"{todo}; every value is in SI units.")
    if lo <= value / factor <= hi and value < lo:  # e.g. mm converted to m twice
        return (f"{value:g} {unit}: did you mean {value / factor:g} {unit}? The value looks converted from "
                f"{alt} to {unit} twice; every value is in SI units.")
    return ""


def check_plausible(scene) -> list[str]:
    """Warnings about the values of a drop-test scene that are surely or probably unit slips.

    Parameters
    ----------
    scene : Scene
        A validated scene; only drop tests are checked (other types: no warnings).

    Returns
    -------
    list of str
        One paragraph per value above its bounds in :data:`BOUNDS`, naming the section, the field,
        the value, the SI unit and the likely slip (e.g. "220 kg: did you mean 0.22 kg (220 g)?").
        The run goes ahead as given: a value is never refused on a guess, and the run checks stop a
        run whose physics breaks (exit 3).
    """
    if scene.type != "drop-test":
        return []
    warnings = []
    for section, key, unit, slip, unusual, what in BOUNDS:
        value = float(getattr(getattr(scene, section), key))
        if slip is not None and value > slip:
            hint = unit_hint(key, value, unit, 0.0, slip)
            warnings.append(f"[{section}] {key} = {value:g} {unit} is not a plausible {what}: above {slip:g} {unit} it "
                            f"is almost surely a unit slip. {hint or f'Give the {key} in {unit}.'} It runs as given; "
                            f"the run checks stop it if its physics breaks.")
        elif value > unusual:
            hint = unit_hint(key, value, unit, 0.0, unusual)
            warnings.append(f"[{section}] {key} = {value:g} {unit} is unusually large for the {what.split(' (')[0]} "
                            f"(above {unusual:g} {unit}); it runs as given. {hint}".rstrip())
    return warnings
