"""Energy terms: the ~10 lines a plugin author writes, and how they compose into a material.

An *isochoric* term is a function of the isochoric principal stretches (l1, l2, l3) and its
parameters; a *volumetric* term is a function of J = det F and its parameters. Both return a
strain energy per unit reference volume (J/m^3 = Pa) as a sympy expression; write them with
:mod:`cfm_core.sym` (``exp``, ``log``, ``sqrt``, ``where``). Example (Mooney-Rivlin)::

    from cfm_core import isochoric, positive

    @isochoric(positive("c10", "Pa", 100.0), positive("c01", "Pa", 50.0))
    def mooney_rivlin(l1, l2, l3, c10, c01):
        i1 = l1**2 + l2**2 + l3**2
        i2 = (l1 * l2) ** 2 + (l2 * l3) ** 2 + (l1 * l3) ** 2
        return c10 * (i1 - 3) + c01 * (i2 - 3)

Terms compose with ``&`` (FElupe style): ``lipid & circular_fibers & ogden_volumetric`` gives a
:class:`cfm_core.material.MaterialSpec`.
"""

from __future__ import annotations

from typing import Callable

from ..errors import InputError
from .parameters import Parameter
from .spec import Term


def _term_decorator(kind: str, parameters: tuple[Parameter, ...], name: str | None, description: str | None):
    for p in parameters:
        if not isinstance(p, Parameter):
            raise InputError(f"{kind} term parameters must be Parameter declarations, got {p!r}.")

    def wrap(func: Callable) -> Term:
        doc = (func.__doc__ or "").strip().splitlines()
        return Term(
            name=name or func.__name__.replace("_", "-"),
            kind=kind,
            energy=func,
            parameters=tuple(parameters),
            description=description if description is not None else (doc[0] if doc else ""),
        )

    return wrap


def isochoric(*parameters: Parameter, name: str | None = None, description: str | None = None):
    """Decorator: turn ``f(l1, l2, l3, *params)`` into an isochoric :class:`Term`.

    l1, l2, l3 are the isochoric principal stretches (J^(-1/3) lambda_a, dimensionless); the
    function returns energy per reference volume in Pa. The energy must be symmetric in l1, l2, l3
    (isotropy); this is checked when a material is built (or registered).

    Parameters
    ----------
    *parameters : Parameter
        Declarations of the function's arguments after l1, l2, l3, in the same order.
    name : str, optional
        Registry name; default the function name with ``_`` replaced by ``-``.
    description : str, optional
        One line for ``cfm materials``; default the first line of the function's docstring.

    Returns
    -------
    callable
        Decorator ``f -> Term`` (kind "isochoric").

    Raises
    ------
    InputError
        Now, if a declaration is not a :class:`Parameter`; when decorating, if the function's
        arguments are not ``(l1, l2, l3, *declared names)``.
    """
    return _term_decorator("isochoric", parameters, name, description)


def volumetric(*parameters: Parameter, name: str | None = None, description: str | None = None):
    """Decorator: turn ``U(J, *params)`` into a volumetric :class:`Term` (energy in Pa).

    U should satisfy U(1) = 0 and must satisfy U'(1) = 0 (stress-free reference state; U'(1) is
    checked when a material is built or registered). Example: paper Eq. 7, Ogden with beta = 9.

    Parameters
    ----------
    *parameters : Parameter
        Declarations of the function's arguments after J, in the same order.
    name : str, optional
        Registry name; default the function name with ``_`` replaced by ``-``.
    description : str, optional
        One line for ``cfm materials``; default the first line of the function's docstring.

    Returns
    -------
    callable
        Decorator ``U -> Term`` (kind "volumetric").

    Raises
    ------
    InputError
        Now, if a declaration is not a :class:`Parameter`; when decorating, if the function's
        arguments are not ``(J, *declared names)``.
    """
    return _term_decorator("volumetric", parameters, name, description)
