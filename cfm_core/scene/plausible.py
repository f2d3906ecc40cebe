"""Plausibility of a drop-test scene's SI values: unit slips (g for kg, mm for m, mm/s for m/s).

The sections (:mod:`cfm_core.scene.sections`) accept every value that is legal in SI units; some
legal values are almost surely a unit written wrongly: 220 for a 220 g impactor is read as 220 kg,
which runs for seconds and then fails the physics checks (or worse, reports a peak). This module
says so before anything runs, in one paragraph naming the field, the value, the unit expected and
the likely mistake. Bounds (SI), chosen so that no legitimate drop test is refused:

========================  ==============  ============================================
field                     refused above   warned above (a judgement call: runs anyway)
========================  ==============  ============================================
[impactor] mass           100 kg          20 kg
[impactor] velocity       100 m/s         20 m/s (a fall from 20 m)
[impactor] radius         1 m (section)   0.25 m
[specimen] width          1 m (section)   0.5 m
========================  ==============  ============================================

The sections keep mass (up to 1e4 kg) and speed (up to 1e3 m/s) legal, so that a model built
directly (:func:`cfm_core.scene.build_model`) can still exercise the run checks; radius and width
above 1 m, the thickness (1e-4 .. 0.1 m), the element size (at most the thickness) and the density
(1 .. 1e5 kg/m^3) are refused by the sections themselves, whose messages carry the same hint
(:func:`unit_hint`).
"""

from __future__ import annotations

from ..errors import InputError

#: SI unit -> (the unit often typed instead, the factor from it to the SI unit).
UNIT_SLIPS = {"m": ("mm", 1e-3), "kg": ("g", 1e-3), "m/s": ("mm/s", 1e-3), "kg/m^3": ("g/cm^3", 1e3)}

#: (section, key, SI unit, refused above (None: by the section), warned above, what it is) of a drop test.
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
    """Refuse a drop-test scene with a value that is surely a unit slip; warn about doubtful ones.

    Parameters
    ----------
    scene : Scene
        A validated scene; only drop tests are checked (other types: no warnings).

    Returns
    -------
    list of str
        Warnings (one paragraph each) for values above the "warned" bounds of :data:`BOUNDS`.

    Raises
    ------
    InputError
        A value above its "refused" bound of :data:`BOUNDS` (mass, speed), naming the section, the field, the
        value, the SI unit and the likely slip (e.g. "220 kg: did you mean 0.22 kg (220 g)?").
    """
    if scene.type != "drop-test":
        return []
    warnings = []
    for section, key, unit, refuse, warn, what in BOUNDS:
        value = float(getattr(getattr(scene, section), key))
        if refuse is not None and value > refuse:
            hint = unit_hint(key, value, unit, 0.0, refuse)
            raise InputError(f"[{section}] {key} = {value:g} {unit} is not a plausible {what}: values above "
                             f"{refuse:g} {unit} are refused as a unit slip. {hint or f'Give the {key} in {unit}.'}")
        if value > warn:
            hint = unit_hint(key, value, unit, 0.0, warn)
            warnings.append(f"[{section}] {key} = {value:g} {unit} is unusually large for the {what.split(' (')[0]} "
                            f"(above {warn:g} {unit}); it runs as given. {hint}".rstrip())
    return warnings
