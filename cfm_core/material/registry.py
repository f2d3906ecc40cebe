"""Registries of materials (``cfm.materials``) and energy terms (``cfm.terms``).

Both are kinds of :mod:`cfm_core.plugins`: found through entry points, lazily, with runtime
registration for notebooks and tests. A material is checked when it is registered (isotropy,
stress-free reference state), not at first use.
"""

from __future__ import annotations

from .. import plugins
from ..errors import InputError
from .material import Material
from .spec import MaterialSpec, Term

plugins.declare_kind(
    "materials", "cfm.materials", lambda obj: isinstance(obj, MaterialSpec), "a MaterialSpec",
    "register one with cfm_core.register_material or the 'cfm.materials' entry-point group")
plugins.declare_kind(
    "terms", "cfm.terms", lambda obj: isinstance(obj, Term), "a Term",
    "register one with cfm_core.register_term or the 'cfm.terms' entry-point group")


def get_material(name: str) -> MaterialSpec:
    """The :class:`~cfm_core.material.MaterialSpec` registered as ``name``.

    Parameters
    ----------
    name : str
        Registered material name, e.g. ``"cfm"`` (``cfm materials`` lists them).

    Returns
    -------
    MaterialSpec
        The declaration, no values bound (see :meth:`MaterialSpec.bind`).

    Raises
    ------
    InputError
        Unknown name (the message lists the registered materials) or a broken plugin.
    """
    return plugins.get("materials", name)


def get_term(name: str) -> Term:
    """The :class:`~cfm_core.material.Term` registered as ``name``.

    Parameters
    ----------
    name : str
        Registered term name, e.g. ``"lipid"``, ``"ogden-volumetric"``.

    Returns
    -------
    Term
        The energy term.

    Raises
    ------
    InputError
        Unknown name (the message lists the registered terms) or a broken plugin.
    """
    return plugins.get("terms", name)


def make_material(name: str, parameters: dict | None = None, moduli: str | None = None,
                  elastic: bool = False) -> Material:
    """Look up a registered material by name and bind parameter values.

    Parameters
    ----------
    name : str
        Registered material name (``cfm materials`` lists them).
    parameters : dict, optional
        Parameter overrides in SI units (Pa, s, -); the others keep their defaults.
    moduli : {"long-term", "instantaneous"}, optional
        Whether the isochoric parameters are relaxed or instantaneous values (docs/conventions.md).
    elastic : bool
        Switch the Prony series off.

    Returns
    -------
    Material
        The bound material (values in SI units).

    Raises
    ------
    InputError
        Unknown material, unknown parameter or a value outside its valid range.
    """
    return get_material(name).bind(parameters, moduli, elastic)


def register_material(spec: MaterialSpec, name: str | None = None, overwrite: bool = False) -> MaterialSpec:
    """Register a :class:`MaterialSpec` at run time; it is checked now (isotropy, stress-free C = I).

    Parameters
    ----------
    spec : MaterialSpec
        Terms composed with ``&``, e.g. ``lipid & circular_fibers & ogden_volumetric``.
    name : str, optional
        Name to register under; default ``spec.name`` (the spec is renamed to it otherwise).
    overwrite : bool
        Replace an existing registration of that name.

    Returns
    -------
    MaterialSpec
        The registered spec (under ``name``).

    Raises
    ------
    InputError
        Not a MaterialSpec, a name already taken (unless ``overwrite``), or a spec that fails its
        checks (the message names the material and the failed check).
    """
    if not isinstance(spec, MaterialSpec):
        raise InputError(f"register_material expects a MaterialSpec (compose terms with &), got {spec!r}.")
    name = name or spec.name
    spec = spec if spec.name == name else spec.named(name)
    spec.energy_parameters  # checks parameter declarations now
    spec.kernels("numpy")  # traces the energy and checks isotropy and the stress-free reference now
    return plugins.register("materials", name, spec, overwrite)


def register_term(term: Term, name: str | None = None, overwrite: bool = False) -> Term:
    """Register an energy :class:`Term` at run time.

    Parameters
    ----------
    term : Term
        A term made with ``@isochoric`` or ``@volumetric``.
    name : str, optional
        Name to register under; default ``term.name``.
    overwrite : bool
        Replace an existing registration of that name.

    Returns
    -------
    Term
        ``term`` itself.

    Raises
    ------
    InputError
        ``term`` is not a Term, or the name is taken and ``overwrite`` is False.
    """
    if not isinstance(term, Term):
        raise InputError(f"register_term expects a Term (use @isochoric or @volumetric), got {term!r}.")
    return plugins.register("terms", name or term.name, term, overwrite)
