"""Generated user materials for other solvers (Abaqus UMAT and VUMAT, LS-DYNA umat41 and utan41).

One material definition (the sympy energy every backend compiles) becomes a fixed-form Fortran
source with the Prony series, the moduli convention and the solver's calling convention
(docs/conventions.md section 7), a ready material card and a ``manifest.json``
(:mod:`cfm_core.export.generate`). :mod:`cfm_core.export.harness` compiles a generated source
with gfortran and calls it through its solver's argument list; :mod:`cfm_core.export.expected`
gives what it must return, from the numpy reference.
"""

from __future__ import annotations

import math
from pathlib import Path

from ..errors import InputError
from ..post.staging import staged_folder
from ..tables import overflowed_to_inf
from .targets import TARGETS

__all__ = ["TARGETS", "check_density", "export"]

#: Densities the explicit cards take, kg/m^3 (the range of a scene's density).
DENSITY_RANGE = (1.0, 1e5)


def check_density(density, shown: str | None = None) -> float:
    """The density of the explicit cards (kg/m^3), checked against :data:`DENSITY_RANGE`: the one check of
    :func:`export` and ``cfm export --density``.

    Parameters
    ----------
    density : float
        The density given (kg/m^3).
    shown : str, optional
        How it was typed, for the message (the command line's text: ``1e400`` reads as inf, and the
        message names 1e400); default its repr.

    Returns
    -------
    float
        The density.

    Raises
    ------
    InputError
        Outside :data:`DENSITY_RANGE` or not a finite number, with the unit it looks like (9.2e-10 is
        tonne/mm^3, 9.2e-7 kg/mm^3, 0.92 g/cm^3: 920 kg/m^3; :func:`cfm_core.scene.plausible.unit_hint`).
    """
    lo, hi = DENSITY_RANGE
    finite = isinstance(density, (int, float)) and not isinstance(density, bool) and math.isfinite(density)
    if finite and lo <= density <= hi:
        return float(density)
    from ..scene.plausible import DENSITY_USUAL, unit_hint

    text = shown if shown is not None else repr(density)
    overflow = ""
    if overflowed_to_inf(text, density):
        overflow = f" (beyond the float range, about 1.8e308, so it reads as {'-' if density < 0 else ''}inf)"
    # the hint proposes a density usual for tissue: 9.2e-10 tonne/mm^3, 9.2e-7 kg/mm^3, 0.92 g/cm^3 are 920 kg/m^3
    hint = unit_hint("density", density, "kg/m^3", *DENSITY_USUAL, option="--density") if finite else ""
    raise InputError(" ".join(filter(None, (
        f"--density {text} kg/m^3 is not allowed{overflow}; give the tissue's density in kg/m^3 ({lo:g} to {hi:g}; "
        f"soft tissue 900-1100).", hint))))


def export(material, target: str, out, density: float | None = None) -> list[Path]:
    """Write the generated source, card and manifest of ``material`` for ``target`` into ``out``.

    The folder is checked before the work and written whole or not at all
    (:func:`cfm_core.post.staging.staged_folder`).

    Parameters
    ----------
    material : Material
        A bound material: its spec gives the code, its values the card's example constants.
    target : {"abaqus-umat", "abaqus-vumat", "lsdyna-umat"}
        Solver interface.
    out : str or path-like
        Output folder (new, or one holding an earlier cfm output).
    density : float, optional
        Density of the explicit cards, kg/m^3 (1 to 1e5; default 950, the project's assumption for fat).

    Returns
    -------
    list of pathlib.Path
        The files written, in ``out``.

    Raises
    ------
    InputError
        ``target`` is not one of :data:`TARGETS`, ``density`` is outside :data:`DENSITY_RANGE`
        (:func:`check_density`), ``out`` cannot hold the output, or an energy cannot be traced
        symbolically.
    """
    if target not in TARGETS:
        raise InputError(f"--to {target!r} is not a known target; use one of {', '.join(TARGETS)}.")
    from .generate import DENSITY, generate  # deferred: imports sympy, which the command line does not need

    rho = check_density(DENSITY if density is None else density)
    with staged_folder(out, "--out", need_bytes=200_000) as stage:
        result = generate(material, target, float(rho))
        for name, text in result.files.items():
            (stage / name).write_text(text)
    return [Path(out) / name for name in result.files]
