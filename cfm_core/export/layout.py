"""What a generated user material reads and keeps: its constants (``PROPS`` / ``cm``) and state
variables (``STATEV`` / ``stateNew`` / ``hsv``), in order, with name, unit and meaning.

Constants: the energy parameters of the spec in declaration order, then the Prony series
(g1, tau1, g2, tau2, ...), then ``moduli`` (1 = long-term, 0 = instantaneous, docs/conventions.md
section 2). LS-DYNA also needs a bulk and a shear modulus in ``cm`` for its time step and contact
(``IBULK``, ``IG``): two derived constants after those.

State variables: per Prony term the six components of the history stress H_i (Pa), then the six
of the instantaneous isochoric second Piola-Kirchhoff stress S0 at the last converged step (Pa),
each in the order 11, 22, 33, 12, 23, 13; then one error code (0 ok, 1 J <= 0 or non-finite F,
2 non-finite stress (overflow), 3 constants invalid, 4 element type or dimensions not supported).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..material.plausible import small_strain_moduli
from ..material.kinematics import VOIGT

COMPONENTS = tuple(f"{a + 1}{b + 1}" for a, b in VOIGT)  # 11, 22, 33, 12, 23, 13
ERROR_CODES = {0: "ok", 1: "J <= 0 or a non-finite deformation", 2: "non-finite stress (overflow of an exponential)",
               3: "material constants invalid (count, range, or g1 + g2 + ... >= 1)",
               4: "element type or tensor dimensions not supported (3-D solids only)"}


@dataclass(frozen=True)
class Entry:
    """One material constant or state variable.

    Parameters
    ----------
    name : str
        Short name (``"c"``, ``"tau1"``, ``"H1_12"``).
    unit : str
        SI unit (``"Pa"``, ``"s"``, ``"-"``).
    meaning : str
        One line.
    default : float or None
        Value on the example card (the spec's defaults, Table 1 for the CFM); None for a state
        variable.
    """

    name: str
    unit: str
    meaning: str
    default: float | None = None


def n_prony(spec) -> int:
    """Number of Prony terms of a material definition.

    Parameters
    ----------
    spec : MaterialSpec
        The material definition.

    Returns
    -------
    int
        The number of (g_i, tau_i) pairs; 0 without a Prony series.
    """
    return len(spec.prony.defaults) if spec.prony is not None else 0


def constants(spec, lsdyna: bool = False, material=None) -> list[Entry]:
    """The material constants in the order the generated routine reads them.

    Parameters
    ----------
    spec : MaterialSpec
        The material definition.
    lsdyna : bool
        Append the bulk and shear modulus LS-DYNA reads through ``IBULK`` and ``IG``.
    material : Material, optional
        Values for the ``default`` column (and the derived moduli); default: the spec bound with
        its defaults.

    Returns
    -------
    list of Entry
        Name, unit, meaning and the value of ``material`` for each constant.
    """
    material = material if material is not None else spec.bind()
    out = [Entry(p.name, p.unit, p.description or p.name, float(material.values[p.name]))
           for p in spec.energy_parameters]
    gammas = material.values if not material.elastic else {k: 0.0 for k in material.values}
    for p in (spec.prony.parameters if spec.prony is not None else ()):
        value = gammas[p.name] if p.name.startswith("g") else material.values[p.name]
        out.append(Entry(p.name, p.unit, p.description, float(value)))
    out.append(Entry("moduli", "-", "1: the isochoric constants are long-term (relaxed) moduli, 0: instantaneous",
                     1.0 if material.moduli == "long-term" else 0.0))
    if lsdyna:
        bulk, shear = small_strain_moduli(material)
        out.append(Entry("bulk", "Pa", "bulk modulus at the reference state (IBULK: LS-DYNA's time step and contact "
                                       "stiffness only; not used by the stress)", bulk))
        out.append(Entry("shear", "Pa", "instantaneous shear modulus at the reference state (IG: LS-DYNA's time step "
                                        "and contact stiffness only; not used by the stress)", shear))
    return out


def state_variables(spec) -> list[Entry]:
    """The state variables in order: H_i components, S0 components, the error code.

    Parameters
    ----------
    spec : MaterialSpec
        The material definition.

    Returns
    -------
    list of Entry
        ``6 (n_prony + 1) + 1`` entries (25 for the CFM's three Prony terms); without a Prony
        series only the error code.
    """
    out = []
    k = n_prony(spec)
    for i in range(1, k + 1):
        out += [Entry(f"H{i}_{c}", "Pa", f"history stress of Prony term {i}, component {c} (second Piola-Kirchhoff)")
                for c in COMPONENTS]
    if k:
        out += [Entry(f"S0_{c}", "Pa", f"instantaneous isochoric second Piola-Kirchhoff stress at the last step, "
                                        f"component {c}") for c in COMPONENTS]
    codes = "; ".join(f"{k} {v}" for k, v in ERROR_CODES.items())
    out.append(Entry("error", "-", f"error code of the last call ({codes})"))
    return out


def props(material, lsdyna: bool = False) -> np.ndarray:
    """The constants vector of a bound material (what goes into ``PROPS`` / ``cm``).

    Parameters
    ----------
    material : Material
        A bound material; an elastic one gets g_i = 0.
    lsdyna : bool
        Append the bulk and shear modulus (LS-DYNA's ``IBULK``, ``IG``).

    Returns
    -------
    ndarray, shape (n,)
        float64 values in SI units, in the order of :func:`constants`.
    """
    return np.array([e.default for e in constants(material.spec, lsdyna, material)], dtype=np.float64)
