"""Generated user-material sources, material cards and manifest for one material and target.

``cfm export MATERIAL --to TARGET --out DIR`` writes, for TARGET in :data:`TARGETS`:

- the Fortran source (fixed form, double precision, one file: the interface routine (LS-DYNA: umat41
  and its implicit tangent utan41), the core of
  :mod:`cfm_core.export.kernel` and the derivatives generated from the material's sympy
  definition by :mod:`cfm_core.export.fortran`), with a header naming the material, the project
  version, the definition hash, the constants and the state variables;
- a ready material card with the example constants (the spec's defaults, Table 1 for the CFM, or
  the values given);
- ``manifest.json``: constants in order with name, unit and value, state variables with their
  meaning, the target and its calling convention, the file names, so that tools can drive it.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass

from ..fingerprint import code_state, package_version
from ..material.cache import spec_fingerprint
from . import abaqus, fortran, kernel, layout, lsdyna
from .targets import TARGETS

DENSITY = 950.0  # kg/m^3: not in the paper (docs/conventions.md section 2), the project's default

@dataclass(frozen=True)
class Export:
    """The generated files of one export, as text.

    Attributes
    ----------
    target : str
        One of :data:`TARGETS`.
    files : dict of str to str
        File name -> content (source, card, ``manifest.json``).
    manifest : dict
        The manifest's content.
    """

    target: str
    files: dict
    manifest: dict


def prefix(spec) -> str:
    """Name prefix of the generated helper routines: ``cfmx_<material>_`` (Fortran-safe).

    Parameters
    ----------
    spec : MaterialSpec
        The material definition.

    Returns
    -------
    str
        Letters, digits and _ only, at most 24 characters.
    """
    return "cfmx_" + re.sub(r"[^0-9a-z]", "_", spec.name.lower())[:18] + "_"


def sizes(spec) -> dict:
    """Array sizes the Fortran templates need (see :func:`cfm_core.export.kernel.core_source`).

    Parameters
    ----------
    spec : MaterialSpec
        The material definition.

    Returns
    -------
    dict
        ``NC``, ``NK``, ``NP``, ``NPD``, ``NH``, ``NHD``, ``NS`` (number of state variables) and
        ``DP`` (the kind declaration line), ``GMIN`` (:data:`cfm_core.export.kernel.GAMMA_INF_FLOOR`, the
        smallest gamma_inf the routine accepts, as a Fortran double literal).
    """
    k = layout.n_prony(spec)
    nh = 6 * (k + 1) if k else 0
    return {"NC": len(spec.parameters) + 1, "NK": len(spec.energy_parameters) + 1, "NP": k, "NPD": max(k, 1),
            "NH": nh, "NHD": max(nh, 1), "NS": nh + 1, "DP": fortran.DP,
            "GMIN": f"{kernel.GAMMA_INF_FLOOR:.15e}".replace("e", "d")}


def generate(material, target: str, density: float = DENSITY) -> Export:
    """Generate the source, card and manifest of ``material`` for ``target``.

    Parameters
    ----------
    material : Material
        A bound material: its spec gives the code, its values the card's example constants.
    target : {"abaqus-umat", "abaqus-vumat", "lsdyna-umat"}
        Solver interface.
    density : float
        Density on the explicit cards (VUMAT ``*DENSITY``, LS-DYNA ``RO``), kg/m^3 (default 950, the
        project's assumption for fat; the UMAT card has none: Abaqus/Standard takes it from
        ``*DENSITY`` where dynamics needs it).

    Returns
    -------
    Export
        File name -> text, and the manifest.

    Raises
    ------
    InputError
        An energy of the spec cannot be traced symbolically.
    """
    spec = material.spec
    info = TARGETS[target]
    p = prefix(spec)
    n = sizes(spec)
    is_dyna = target == "lsdyna-umat"
    consts = layout.constants(spec, lsdyna=is_dyna, material=material)
    states = layout.state_variables(spec)
    interface = {"abaqus-umat": abaqus.UMAT, "abaqus-vumat": abaqus.VUMAT,
                 "lsdyna-umat": lsdyna.UMAT41 + "\n" + lsdyna.UTAN41}[target]
    body = [interface, kernel.core_source(p, n, tangent=target != "abaqus-vumat"),
            fortran.derivative_routine(spec, p, hessian=False), fortran.derivative_routine(spec, p, hessian=True),
            fortran.range_checks(spec, p)]
    text = "\n".join(body)
    for key, value in {**n, "P": p, "NAME": re.sub(r"[^0-9A-Za-z_.-]", "_", spec.name)[:20], "N": "41"}.items():
        text = text.replace("{" + key + "}", str(value))
    text = fortran.refold(text)
    state = code_state()
    definition = spec_fingerprint(spec) or "none (a term defined interactively)"
    header = _header(spec, info, consts, states, state, definition)
    source = header + "\n" + text
    card = {"abaqus-umat": lambda: abaqus.umat_card(spec.name, consts, n["NS"]),
            "abaqus-vumat": lambda: abaqus.vumat_card(spec.name, consts, n["NS"], density),
            "lsdyna-umat": lambda: lsdyna.card(spec.name, consts, n["NS"], density, 41)}[target]()
    manifest = {
        "material": spec.name, "description": spec.description, "target": target, "solver": info["solver"],
        "entry_point": info["entry"], "calling_convention": info["convention"],
        "routines": _routines(info),
        "source": info["source"], "card": info["card"],
        "source_sha256": hashlib.sha256(source.encode()).hexdigest(),
        "generated_by": {"version": package_version(), "commit": state.get("commit"), "dirty": state.get("dirty"),
                         "definition_hash": definition},
        "precision": "double (real(dp), dp = selected_real_kind(15, 307)); no promotion flags needed",
        "source_form": "fixed (columns 7-72), gfortran -std=f2008 -ffixed-form",
        "units": "SI: m, s, kg, Pa",
        "density": None if target == "abaqus-umat" else float(density),
        "constants": [dict(index=i, name=e.name, unit=e.unit, value=e.default, meaning=e.meaning)
                      for i, e in enumerate(consts, 1)],
        "state_variables": [dict(index=i, name=e.name, unit=e.unit, meaning=e.meaning)
                            for i, e in enumerate(states, 1)],
        "error_codes": {str(k): v for k, v in layout.ERROR_CODES.items()},
        "verified": "through its calling convention by cfm's harness (gfortran, ctypes, against the numpy "
                    "reference); not run in the commercial solver here",
    }

    return Export(target, {info["source"]: source, info["card"]: card,
                           "manifest.json": json.dumps(manifest, indent=2) + "\n"}, manifest)


def _routines(info) -> list:
    """The routines of the source with their role and calling convention (manifest ``routines``)."""
    out = [dict(name=info["entry"], role="stress and state update" + (" (explicit and implicit runs)"
                                                                      if "tangent" in info else ""),
                calling_convention=info["convention"])]
    if "tangent" in info:
        out.append(dict(name=info["tangent"]["entry"], role="material tangent for implicit runs",
                        calling_convention=info["tangent"]["convention"]))
    return out


def _header(spec, info, consts, states, state, definition) -> str:
    lines = [
        f"Generated by cfm export (cfm-materials {state.get('version')}, commit "
        f"{(state.get('commit') or 'none')[:10]}{', uncommitted changes' if state.get('dirty') else ''}): "
        f"do not edit.",
        f"Material '{spec.name}': {spec.description}",
        f"Definition hash: {definition}",
        f"Target: {info['solver']}; entry point '{info['entry']}'"
        + (f"; '{info['tangent']['entry']}' the tangent for implicit runs (es = c / J, the push-forward of "
           f"dS/dE over J, xx, yy, zz, xy, yz, zx; symmetric; zero and a line to unit 6 on an error)."
           if "tangent" in info else "."),
        "SI units (m, s, kg, Pa). Double precision throughout; fixed form.",
        "Verified through its calling convention by cfm's harness (gfortran, against the numpy reference); "
        "not run in the commercial solver here.",
        "",
        f"Constants ({len(consts)}):",
    ]
    lines += [f"  {i:>2} {e.name:<7} [{e.unit}] {e.meaning} (example: {e.default:.10g})"
              for i, e in enumerate(consts, 1)]
    lines += ["", f"State variables ({len(states)}):"]
    lines += [f"  {i:>2} {e.name:<7} [{e.unit}] {e.meaning}" for i, e in enumerate(states, 1)]
    return fortran.comment("\n".join(lines)) + "\n"
