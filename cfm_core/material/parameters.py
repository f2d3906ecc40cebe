"""Material parameters: name, unit, default and valid range, validated at construction.

A :class:`Parameter` is a frozen declaration; :meth:`Parameter.check` turns a user value into a
float or raises :class:`cfm_core.errors.InputError` naming the field, the value, the unit and the
allowed range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import InputError


@dataclass(frozen=True)
class Parameter:
    """Declaration of one scalar material parameter.

    name: identifier used in energies, scene files and ``--param NAME=VALUE``.
    unit: SI unit as text ("Pa", "s", "-"). default: value in that unit.
    low, high: bounds of the valid range; ``low_open``/``high_open`` exclude the bound itself;
    ``nonzero`` excludes 0 (e.g. an Ogden exponent).
    description: one line for ``cfm materials``.
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

    def __post_init__(self):
        if not self.name.isidentifier():
            raise InputError(f"parameter name {self.name!r} is not a Python identifier; use letters, digits and _")
        self.check(self.default, context="default of")

    def range_text(self) -> str:
        """The valid range in interval notation, e.g. ``(0, inf) Pa``."""
        lo = "(" if self.low_open or math.isinf(self.low) else "["
        hi = ")" if self.high_open or math.isinf(self.high) else "]"
        text = f"{lo}{self.low:g}, {self.high:g}{hi}"
        return text + " without 0" if self.nonzero else text

    def check(self, value, *, context: str = "parameter") -> float:
        """Return ``value`` as a float if it is finite and inside the range, else raise InputError."""
        try:
            x = float(value)
        except (TypeError, ValueError):
            raise InputError(
                f"{context} '{self.name}' must be a number in {self.unit}, got {value!r}; "
                f"allowed range {self.range_text()} {self.unit}."
            ) from None
        ok = math.isfinite(x)
        ok = ok and (x > self.low if self.low_open else x >= self.low)
        ok = ok and (x < self.high if self.high_open else x <= self.high)
        ok = ok and not (self.nonzero and x == 0.0)
        if not ok:
            raise InputError(
                f"{context} '{self.name}' = {value!r} {self.unit} is outside the allowed range "
                f"{self.range_text()} {self.unit} ({self.description or 'no description'})."
            )
        return x


def positive(name: str, unit: str, default: float, description: str = "") -> Parameter:
    """A parameter that must be strictly positive and finite."""
    return Parameter(name, unit, default, low=0.0, low_open=True, description=description)


def nonnegative(name: str, unit: str, default: float, description: str = "") -> Parameter:
    """A parameter that must be zero or positive and finite."""
    return Parameter(name, unit, default, low=0.0, description=description)
