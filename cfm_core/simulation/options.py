"""Typed backend options: declared once (name, default, unit, valid range or choices, meaning).

A backend declares its options as a frozen dataclass deriving from :class:`Options` whose fields
are made with :func:`option`; the same declaration validates a user's options at construction,
writes the docstring table and the ``cfm backends --options`` listing (sfepy style: one table,
nothing listed twice)::

    @dataclass(frozen=True)
    class ExplicitOptions(Options):
        safety: float = option(0.9, "-", "time-step safety factor", low=0.0, high=1.0, low_open=True)
        dt_max: float = option(math.inf, "s", "largest time step", low=0.0, low_open=True)

    ExplicitOptions.from_mapping({"safety": 2.0}, backend="numba")  # InputError naming the field

Values are checked for type (number, integer, boolean, text), finiteness (unless the default is
infinite), range and choices; ``None`` is allowed where the declaration says ``none=...`` (its
meaning, e.g. "automatic").
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, ClassVar, Mapping

from ..errors import InputError
from ..tables import as_float, shown


@dataclass(frozen=True)
class OptionSpec:
    """What one option accepts: unit, meaning, range (closed unless ``*_open``), choices, None."""

    unit: str
    doc: str
    kind: str = "float"  # "float", "int", "bool", "str", "any"
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    choices: tuple = ()
    none: str = ""  # meaning of None when None is allowed ("" = not allowed)

    def allowed(self) -> str:
        """The allowed values as text (for messages and listings)."""
        if self.kind == "bool":
            text = "True or False"
        elif self.kind in ("float", "int"):
            lo = "(" if self.low_open or math.isinf(self.low) else "["
            hi = ")" if self.high_open or math.isinf(self.high) else "]"
            text = f"{'an integer' if self.kind == 'int' else 'a number'} in {lo}{self.low:g}, {self.high:g}{hi}"
            text += "".join(f", or {c!r}" for c in self.choices)
        elif self.choices:
            text = "one of " + ", ".join(repr(c) for c in self.choices)
        else:
            text = "any value"
        return text + (f", or None ({self.none})" if self.none else "")

    def check(self, name: str, value, owner: str):
        """``value`` converted to the option's type, or InputError naming owner, field and value."""
        if value is None and self.none:
            return None
        unit = "" if self.unit in ("", "-") else f" {self.unit}"
        bad = InputError(f"{owner}: option {name} = {shown(value)}{unit} is not allowed; expected {self.allowed()} "
                         f"({self.doc}).")
        if self.kind == "bool":
            if not isinstance(value, bool):
                raise bad
            return value
        if self.choices and self.kind not in ("float", "int"):
            if value not in self.choices:
                raise bad
            return value
        if self.kind in ("float", "int"):
            if isinstance(value, str) and value in self.choices:  # a named setting of a number ("auto")
                return value
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise bad
            x = as_float(value)  # an integer beyond the float range: inf, as 1e400 is
            if self.kind == "int" and not x.is_integer():
                raise bad
            x = int(value) if self.kind == "int" else x
            if math.isnan(x) or (math.isinf(x) and not math.isinf(self.high if x > 0 else self.low)):
                raise bad
            ok = (x > self.low if self.low_open else x >= self.low) and (x < self.high if self.high_open else x <= self.high)
            if not ok:
                raise bad
            return x
        if self.kind == "str" and not isinstance(value, str):
            raise bad
        return value


def option(default, unit: str = "-", doc: str = "", *, kind: str | None = None, low: float = -math.inf,
           high: float = math.inf, low_open: bool = False, high_open: bool = False, choices: tuple = (),
           none: str = "") -> Any:
    """A dataclass field declaring one backend option.

    Parameters
    ----------
    default
        Default value (checked against the declaration when the options class is built).
    unit : str
        SI unit ("s", "N/m", "-").
    doc : str
        One line: what the option does.
    kind : {"float", "int", "bool", "str", "any"}, optional
        Value type; inferred from the default when omitted, which a default of None cannot give:
        such an option must state its kind.
    low, high, low_open, high_open : optional
        Valid range of numbers (closed unless ``*_open``).
    choices : tuple, optional
        Allowed values of a text option; for a number, named settings allowed besides the range
        (``error_tol = "auto"``).
    none : str, optional
        Meaning of ``None`` if None is allowed ("automatic", ...).

    Raises
    ------
    TypeError
        A default of None without ``kind`` (the option would accept any value unchecked).
    """
    if kind is None:
        if default is None:
            raise TypeError(f"option(None, {unit!r}, {doc[:40]!r}...): a default of None needs kind= "
                            f"('float', 'int', 'bool', 'str' or 'any'), or the option accepts any value unchecked")
        kind = ("bool" if isinstance(default, bool) else "int" if isinstance(default, int) else
                "float" if isinstance(default, float) else "str" if isinstance(default, str) else "any")
    spec = OptionSpec(unit, doc, kind, low, high, low_open, high_open, tuple(choices), none)
    return dataclasses.field(default=default, metadata={"option": spec})


@dataclass(frozen=True)
class Options:
    """Base class of a backend's options (a frozen dataclass of :func:`option` fields).

    Construction checks every value; use :meth:`from_mapping` to build from a user's dict (unknown
    names raise InputError listing the allowed ones).
    """

    owner: ClassVar[str] = "backend"

    def __post_init__(self):
        for f in dataclasses.fields(self):
            spec = f.metadata.get("option")
            if spec is not None:
                object.__setattr__(self, f.name, spec.check(f.name, getattr(self, f.name), self.owner))

    @classmethod
    def specs(cls) -> dict[str, OptionSpec]:
        """name -> :class:`OptionSpec` of every option, in declaration order."""
        return {f.name: f.metadata["option"] for f in dataclasses.fields(cls) if "option" in f.metadata}

    @classmethod
    def from_mapping(cls, mapping: Mapping | None = None, **overrides):
        """Options from a user's mapping (and keyword overrides).

        Raises
        ------
        InputError
            An unknown option name (the message lists the allowed ones) or a value outside what
            its declaration allows (the message names the option, the value, the unit and what
            is allowed).
        """
        if isinstance(mapping, cls) and not overrides:
            return mapping
        values = dict(dataclasses.asdict(mapping) if isinstance(mapping, Options) else (mapping or {}), **overrides)
        unknown = sorted(set(values) - set(cls.specs()))
        if unknown:
            raise InputError(f"{cls.owner}: unknown option(s) {', '.join(unknown)}; allowed: "
                             f"{', '.join(cls.specs())} (see 'cfm backends --options').")
        return cls(**values)

    def replace(self, **changes):
        """A copy with some options changed (checked)."""
        return type(self).from_mapping(self, **changes)

    def as_dict(self) -> dict:
        """The options as a plain dict (name -> value)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    @classmethod
    def table(cls) -> str:
        """The options as a text table (name, default, unit, allowed values, meaning)."""
        rows = [(name, repr(getattr(f, "default", None)), spec.unit, spec.allowed(), spec.doc)
                for name, spec, f in ((f.name, f.metadata["option"], f) for f in dataclasses.fields(cls)
                                      if "option" in f.metadata)]
        widths = [max(len(r[i]) for r in rows + [("option", "default", "unit", "allowed", "")]) for i in range(3)]
        lines = [f"{'option':<{widths[0]}}  {'default':<{widths[1]}}  {'unit':<{widths[2]}}  meaning; allowed"]
        lines += [f"{n:<{widths[0]}}  {d:<{widths[1]}}  {u:<{widths[2]}}  {doc}; {allowed}" for n, d, u, allowed, doc in rows]
        return "\n".join(lines)


def document(cls):
    """Class decorator: append the options table to the class docstring (the one listing)."""
    cls.__doc__ = (cls.__doc__ or "").rstrip() + "\n\nOptions (name, default, unit, meaning; allowed)::\n\n" + \
        "\n".join("    " + line for line in cls.table().splitlines()) + "\n"
    return cls
