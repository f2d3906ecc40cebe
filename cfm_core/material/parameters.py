"""Material parameters: name, unit, default and valid range, validated at construction.

A :class:`Parameter` is a frozen declaration; :meth:`Parameter.check` turns a user value into a
float or raises :class:`cfm_core.errors.InputError` naming the field, the value, the unit and the
allowed range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..errors import InputError
from ..tables import as_float, shown


@dataclass(frozen=True)
class Parameter:
    """Declaration of one scalar material parameter.

    Parameters
    ----------
    name : str
        Identifier used in energies, scene files and ``--param NAME=VALUE``.
    unit : str
        SI unit as text (``"Pa"``, ``"s"``, ``"-"``).
    default : float
        Default value, in ``unit``; must lie in the valid range.
    low, high : float
        Bounds of the valid range, in ``unit`` (default: unbounded).
    low_open, high_open : bool
        Exclude the bound itself (e.g. ``low=0, low_open=True`` for a positive modulus).
    description : str
        One line for ``cfm materials`` and error messages.
    nonzero : bool
        Exclude 0 (e.g. an Ogden exponent).
    min_abs : float
        Smallest magnitude allowed (default 0: any): an Ogden exponent of magnitude 1e-16 made
        l^alpha - 1 round to 0 and dropped its term (32 % low stresses, silently).
    typical : float, optional
        Order of magnitude of physical values, in ``unit`` (default: ``default``). A modulus
        (unit Pa) more than 100 times away from it is warned about as a likely unit slip
        (:func:`cfm_core.material.plausible.check_material`); advisory only: it does not enter
        the generated code, its cache key or equality.

    Raises
    ------
    InputError
        ``name`` is not a Python identifier, or ``default`` is outside the valid range.
    """

    name: str
    unit: str
    default: float
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    description: str = ""
    nonzero: bool = False
    min_abs: float = 0.0
    typical: float | None = field(default=None, repr=False, compare=False)

    def __post_init__(self):
        if not self.name.isidentifier():
            raise InputError(f"parameter name {self.name!r} is not a Python identifier; use letters, digits and _")
        self.check(self.default, context="default of")

    @property
    def scale(self) -> float:
        """The typical value (:attr:`typical`, else the default), in ``unit``."""
        return float(self.default if self.typical is None else self.typical)

    def range_text(self) -> str:
        """The valid range in interval notation, without the unit.

        Returns
        -------
        str
            E.g. ``"(0, inf)"``, ``"[0, 1)"``, ``"[-50, 50] without 0"``.
        """
        lo = "(" if self.low_open or math.isinf(self.low) else "["
        hi = ")" if self.high_open or math.isinf(self.high) else "]"
        text = f"{lo}{self.low:g}, {self.high:g}{hi}"
        if self.min_abs > 0.0:
            return text + f" with |{self.name}| >= {self.min_abs:g}"
        return text + " without 0" if self.nonzero else text

    def check(self, value, *, context: str = "parameter") -> float:
        """Return ``value`` as a float if it is finite and inside the range, else raise InputError.

        Parameters
        ----------
        value : float or str
            The value in the parameter's unit; anything ``float()`` accepts.
        context : str
            Words before the parameter name in messages, e.g. ``"material 'cfm' parameter"``.

        Returns
        -------
        float
            ``float(value)``.

        Raises
        ------
        InputError
            ``value`` is not a number, not finite, outside ``[low, high]`` (open bounds
            excluded) or zero when ``nonzero``; the message names the parameter, the value, the
            unit and the allowed range.
        """
        try:
            x = as_float(value)  # an integer beyond the float range: inf, refused below as 1e400 is
        except (TypeError, ValueError):
            raise InputError(
                f"{context} '{self.name}' must be a number{self._in_unit()}, got {shown(value)}; "
                f"allowed range {self.range_text()}{self._unit_suffix()}."
            ) from None
        ok = math.isfinite(x)
        ok = ok and (x > self.low if self.low_open else x >= self.low)
        ok = ok and (x < self.high if self.high_open else x <= self.high)
        ok = ok and not (self.nonzero and x == 0.0) and abs(x) >= self.min_abs
        if not ok:
            raise InputError(
                f"{context} '{self.name}' = {shown(value)}{self._unit_suffix()} is outside the allowed range "
                f"{self.range_text()}{self._unit_suffix()} ({self.description or 'no description'})."
            )
        return x

    def _unit_suffix(self) -> str:
        """" Pa" after a value; nothing for a dimensionless one (unit "-", which reads as a dash)."""
        return "" if self.unit in ("-", "") else f" {self.unit}"

    def _in_unit(self) -> str:
        return " (dimensionless)" if self.unit in ("-", "") else f" in {self.unit}"


def positive(name: str, unit: str, default: float, description: str = "") -> Parameter:
    """A parameter that must be strictly positive and finite: range (0, inf).

    Parameters
    ----------
    name : str
        Identifier (see :class:`Parameter`).
    unit : str
        SI unit as text, e.g. ``"Pa"``.
    default : float
        Default value in ``unit``, > 0.
    description : str
        One line for ``cfm materials``.

    Returns
    -------
    Parameter
        The declaration.

    Raises
    ------
    InputError
        Invalid name or a default <= 0.
    """
    return Parameter(name, unit, default, low=0.0, low_open=True, description=description)


def nonnegative(name: str, unit: str, default: float, description: str = "") -> Parameter:
    """A parameter that must be zero or positive and finite: range [0, inf).

    Parameters
    ----------
    name : str
        Identifier (see :class:`Parameter`).
    unit : str
        SI unit as text, e.g. ``"Pa"``.
    default : float
        Default value in ``unit``, >= 0.
    description : str
        One line for ``cfm materials``.

    Returns
    -------
    Parameter
        The declaration.

    Raises
    ------
    InputError
        Invalid name or a negative default.
    """
    return Parameter(name, unit, default, low=0.0, description=description)
