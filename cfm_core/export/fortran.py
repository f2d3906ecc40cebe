"""Fixed-form Fortran from the material's sympy expressions (the same ones every backend compiles).

The energy and its derivatives in the eigenvalues m_a of C come from
:attr:`MaterialSpec.derivatives <cfm_core.material.MaterialSpec.derivatives>` (psi_energy, psi_grad,
psi_hess; :mod:`cfm_core.material.codegen`); here they are renamed to Fortran-safe names
(``em1..em3``, ``xj``, ``xjm23``, parameters ``pv(1..k)``), their common subexpressions shared
(sympy ``cse``) and printed with sympy's Fortran printer in fixed form (72 columns), so one file
serves Abaqus, LS-DYNA and CalculiX builds alike. Double precision throughout: every real is
``real(dp)`` with ``dp = selected_real_kind(15, 307)``, unaffected by default-real promotion flags.
"""

from __future__ import annotations

import functools
import textwrap

import sympy as sp
from sympy.printing.fortran import FCodePrinter

from ..material import codegen

DP = "      integer, parameter :: dp = selected_real_kind(15, 307)"


class _Printer(FCodePrinter):
    """Fortran printer whose Piecewise branches are double precision on both sides of ``merge``."""

    def _print_Piecewise(self, expr):
        out = self._branch(expr.args[-1].expr)
        for e, c in reversed(expr.args[:-1]):
            out = f"merge({self._branch(e)}, {out}, {self._print(c)})"
        return out

    def _print_Integer(self, expr):
        # beyond default integer range: a double literal (exact up to 2**53)
        return f"{int(expr)}.0d0" if abs(int(expr)) > 2**31 - 1 else super()._print_Integer(expr)

    def _branch(self, e):
        return self._print(sp.Float(e)) if e.is_Number else self._print(e)


def _printer():
    return _Printer({"source_format": "free", "standard": 2008, "precision": 17})


def wrap(line: str, indent: int = 6) -> str:
    """Fixed-form lines from one long statement: columns 7-72, ``&`` continuation in column 6.

    Parameters
    ----------
    line : str
        The statement without leading blanks.
    indent : int
        Column of the first character minus one (6 for a statement).

    Returns
    -------
    str
        One or more lines, each at most 72 columns, joined with newlines.
    """
    width = 72 - indent
    if len(line) <= width:
        return " " * indent + line
    parts, rest = [], line
    while len(rest) > width:
        cut = max(rest.rfind(c, 0, width) for c in " +-*/,(")
        cut = width if cut <= 0 else cut + 1
        parts.append(rest[:cut])
        rest = rest[cut:]
        width = 72 - 6 - 3  # continuation lines: '     &   '
    parts.append(rest)
    return "\n".join([" " * indent + parts[0]] + ["     &   " + p for p in parts[1:]])


def refold(text: str) -> str:
    """Fold every statement line longer than 72 columns into continuation lines (fixed form).

    Lines are cut at a blank, comma or operator outside character literals; comment lines are
    left alone.

    Parameters
    ----------
    text : str
        Fixed-form source.

    Returns
    -------
    str
        The same source with every statement line at most 72 columns.

    Raises
    ------
    ValueError
        A line cannot be folded (no break point outside a literal): a generator defect.
    """
    out = []
    for line in text.split("\n"):
        while len(line) > 72 and not line.startswith(("!", "c", "C", "*")):
            cut, quote = 0, None
            for i, ch in enumerate(line[:72]):
                if ch in "'\"" and quote in (None, ch):
                    quote = None if quote else ch
                elif quote is None and i > 6 and ch in " ,+*/(":
                    cut = i + 1
            if cut <= 9:
                raise ValueError(f"cannot fold the generated line {line!r}")
            out.append(line[:cut].rstrip())
            line = "     &   " + line[cut:].lstrip()
        out.append(line)
    return "\n".join(out)


def comment(text: str) -> str:
    """Fixed-form comment lines (``!`` in column 1, at most 72 columns) for free text.

    Parameters
    ----------
    text : str
        Lines of text; long lines are wrapped with the indentation they start with.

    Returns
    -------
    str
        The comment block.
    """
    out = []
    for para in text.split("\n"):
        indent = " " * (len(para) - len(para.lstrip()) + 3)
        out += ["! " + ln for ln in textwrap.wrap(para, 70, subsequent_indent=indent)] if para else ["!"]
    return "\n".join(ln.rstrip() for ln in out)


def _declare(kind: str, names: list[str]) -> list[str]:
    lines = []
    for i in range(0, len(names), 6):
        lines.append(wrap(f"{kind} :: {', '.join(names[i:i + 6])}"))
    return lines


@functools.lru_cache(maxsize=32)
def derivative_routine(spec, prefix: str, hessian: bool) -> str:
    """Fortran subroutine of the energy, gradient (and Hessian) of psi in the eigenvalues of C.

    ``subroutine <prefix>psi(em, pv, e, g)`` (or ``<prefix>psih(em, pv, e, g, h)`` with the
    Hessian): em(3) the eigenvalues of C (-), pv(k + 1) the energy parameters in declaration
    order then s_iso (the moduli factor on the isochoric energy), e(2) = (psi_iso, psi_vol) (Pa),
    g(6) = d psi / d m_a (isochoric 1-3, volumetric 1-3, Pa), h(12) the second derivatives in the
    pair order 11, 22, 33, 12, 23, 13 (isochoric then volumetric, Pa).

    Parameters
    ----------
    spec : MaterialSpec
        The material definition (traced by sympy once; its derivative table is reused).
    prefix : str
        Name prefix of the generated routines (e.g. ``"cfmx_cfm_"``).
    hessian : bool
        Also compute the 12 second derivatives (UMAT tangent).

    Returns
    -------
    str
        Fixed-form Fortran source of the subroutine.
    """
    table = spec.derivatives
    exprs = table["psi_energy"] + table["psi_grad"] + (table["psi_hess"] if hessian else [])
    exprs = codegen._opaque_to_symbols(exprs)  # the J and J^(-2/3) symbols the generated code computes first
    names = spec.symbolic[2]
    rename = {sp.Symbol(n, real=True): sp.Symbol(f"pv{i + 1}", real=True) for i, n in enumerate(names)}
    rename.update({m: sp.Symbol(f"em{a + 1}", positive=True) for a, m in enumerate(codegen.M)})
    rename.update({codegen.J_SYMBOL: sp.Symbol("xj", positive=True),
                   codegen.JM13_SYMBOL: sp.Symbol("xjm23", positive=True)})
    exprs = [sp.sympify(e).xreplace(rename) for e in exprs]
    temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("cg"), optimizations="basic")
    pr = _printer()
    name = f"{prefix}psih" if hessian else f"{prefix}psi"
    args = "em, pv, e, g, h" if hessian else "em, pv, e, g"
    logical = [str(s) for s, e in temps if isinstance(e, (sp.logic.boolalg.Boolean, sp.core.relational.Relational))]
    real = [str(s) for s, e in temps if str(s) not in logical]
    lines = [f"      subroutine {name}({args})", "      implicit none", DP,
             f"      real(dp), intent(in) :: em(3), pv({len(names)})",
             "      real(dp), intent(out) :: e(2), g(6)" + (", h(12)" if hessian else "")]
    lines += _declare("real(dp)", ["em1", "em2", "em3", "xj", "xjm23"] + real)
    lines += _declare("logical", logical) if logical else []
    lines += _declare("real(dp)", [f"pv{i + 1}" for i in range(len(names))])
    lines += [f"      pv{i + 1} = pv({i + 1})" for i in range(len(names))]
    lines += [f"      em{a} = em({a})" for a in (1, 2, 3)]
    lines += ["      xj = sqrt(em1 * em2 * em3)",
              "      xjm23 = 1.0d0 / (xj ** (2.0d0 / 3.0d0))"]
    for sym, e in temps:
        lines.append(wrap(f"{sym} = {pr._print(e)}"))
    outs = ["e(1)", "e(2)"] + [f"g({i + 1})" for i in range(6)] + ([f"h({i + 1})" for i in range(12)] if hessian else [])
    for target, e in zip(outs, reduced):
        text = pr._print(sp.Float(e)) if e.is_Number else pr._print(e)
        lines.append(wrap(f"{target} = {text}"))
    lines.append(f"      end subroutine {name}")
    return "\n".join(lines) + "\n"


def range_checks(spec, prefix: str) -> str:
    """Fortran function ``<prefix>badprops(props)``: .true. when a constant is outside the range
    its :class:`~cfm_core.material.Parameter` declares (energy parameters and Prony terms).

    Parameters
    ----------
    spec : MaterialSpec
        The material definition; its parameters' bounds become the checks.
    prefix : str
        Name prefix of the generated routines.

    Returns
    -------
    str
        Fixed-form Fortran source of the logical function.
    """
    params = list(spec.parameters)
    lines = [f"      logical function {prefix}badprops(props)", "      use, intrinsic :: ieee_arithmetic, only: ieee_is_nan",
             "      implicit none", DP,
             f"      real(dp), intent(in) :: props({len(params) + 1})", f"      {prefix}badprops = .false."]
    pr = _printer()
    for i, p in enumerate(params, start=1):
        tests = [f"ieee_is_nan(props({i}))"]
        if p.low != float("-inf"):
            tests.append(f"props({i}) {'.le.' if p.low_open else '.lt.'} {pr._print(sp.Float(p.low))}")
        if p.high != float("inf"):
            tests.append(f"props({i}) {'.ge.' if p.high_open else '.gt.'} {pr._print(sp.Float(p.high))}")
        if p.nonzero:
            tests.append(f"props({i}) .eq. 0.0d0")
        lines.append(wrap(f"if ({' .or. '.join(tests)}) {prefix}badprops = .true."))
    n = len(params) + 1
    lines.append(wrap(f"if (props({n}) .ne. 0.0d0 .and. props({n}) .ne. 1.0d0) {prefix}badprops = .true."))
    lines.append(f"      end function {prefix}badprops")
    return "\n".join(lines) + "\n"
