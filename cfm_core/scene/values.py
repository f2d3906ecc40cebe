"""Value checks of scene sections: each returns the checked value or raises InputError naming the
section, the key, the value, the unit and what is allowed (SI units)."""

from __future__ import annotations

import math
import numbers

import numpy as np

from ..errors import InputError
from ..tables import as_float, shown
from .plausible import unit_hint


def _num(section, key, value, unit, lo, hi, *, lo_open=False, hi_open=False, note="", fix=None) -> float:
    """``value`` as a float if it is a finite real number in the range, else InputError."""
    lo_s, hi_s = ("<" if lo_open else "<="), ("<" if hi_open else "<=")
    allowed = f"a finite number with {lo:g} {lo_s} {key} {hi_s} {hi:g} {unit}"
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise InputError(f"[{section}] {key} = {shown(value)} ({type(value).__name__}) is not a number; "
                         f"it must be {allowed}. {note}".rstrip())
    x = as_float(value)  # an integer beyond the float range: inf, refused below as 1e400 is
    ok = math.isfinite(x) and (x > lo if lo_open else x >= lo) and (x < hi if hi_open else x <= hi)
    if not ok:
        hint = unit_hint(key, x, unit, lo, hi, fix, flag="." not in section) if math.isfinite(x) else ""  # layers: no flag
        raise InputError(" ".join(filter(None, (f"[{section}] {key} = {shown(value)} {unit} is out of range; it "
                                                 f"must be {allowed}.", note, hint))))
    return x


def _choice(section, key, value, allowed) -> str:
    if not isinstance(value, str) or value not in allowed:
        raise InputError(f"[{section}] {key} = {value!r} is not allowed; use one of "
                         f"{', '.join(repr(a) for a in allowed)}.")
    return value


def _text(section, key, value) -> str:
    if not isinstance(value, str) or not value.strip():
        raise InputError(f"[{section}] {key} = {value!r} must be a non-empty string.")
    return value


def _set(obj, **kw):
    for k, v in kw.items():
        object.__setattr__(obj, k, v)


def parameter_value(section: str, name: str, value) -> float:
    """A material parameter of a scene table as a float: a finite number, else InputError naming the
    table, the name and the value (its range is the material's, checked when the material is bound)."""
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    if ok and math.isfinite(as_float(value)):
        return float(value)
    raise InputError(f"[{section}] {name} = {shown(value)} is not allowed: a material parameter is a finite number "
                     f"in SI units (Pa, s, -); 'cfm materials' lists each material's parameters with their units "
                     f"and ranges.")
