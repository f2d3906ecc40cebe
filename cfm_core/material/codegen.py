"""Trace energy terms once with sympy and generate code for every backend.

The energy is re-expressed in the eigenvalues m1, m2, m3 of the right Cauchy-Green tensor C
(squared principal stretches), with the isochoric split inside:

    J = sqrt(m1 m2 m3),   l_a = sqrt(m_a J^(-2/3))   (isochoric principal stretches)
    psi_iso(m) = s_iso * sum_terms W(l1, l2, l3),     psi_vol(m) = U(J)

where s_iso (the last entry of the parameter vector) scales the isochoric energy for the moduli
convention. Derivatives are exact (sympy), common subexpressions are shared (cse). Generated
functions, all of ``(m1, m2, m3, p)``:

- ``psi_energy``    -> (iso, vol)                                      [Pa = J/m^3]
- ``psi_grad``      -> (i1, i2, i3, v1, v2, v3), d psi / d m_a          [Pa]
- ``psi_hess_diag`` -> (i11, i22, i33, v11, v22, v33)                   [Pa]
- ``psi_hess``      -> (i11, i22, i33, i12, i23, i13, v11, ..., v13)    [Pa]
- ``psi_grad_hess_diag`` -> psi_grad then psi_hess_diag, sharing subexpressions (explicit solvers
  need both every step)                                                  [Pa]

Dialects: "math" (scalar code for numba and plain Python), "numpy" and "torch" (array code).
"""

from __future__ import annotations

import sympy as sp
from sympy.printing.numpy import NumPyPrinter
from sympy.printing.pycode import PythonCodePrinter

from ..errors import InputError

M = sp.symbols("m1 m2 m3", positive=True)
J_SYMBOL = sp.Symbol("J", positive=True)
PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (0, 2))


class _MathPrinter(PythonCodePrinter):
    """Scalar Python with the math module; Piecewise becomes a conditional expression."""


class _NumpyPrinter(NumPyPrinter):
    def _print_Piecewise(self, expr):
        out = self._print(expr.args[-1].expr)
        for e, c in reversed(expr.args[:-1]):
            out = f"numpy.where({self._print(c)}, {self._print(e)}, {out})"
        return out


class _TorchPrinter(_NumpyPrinter):
    """Array code for torch: the numpy printer's output with the torch namespace."""

    def doprint(self, expr, assign_to=None):
        return super().doprint(expr, assign_to).replace("numpy.", "torch.")


PRINTERS = {"math": _MathPrinter, "numpy": _NumpyPrinter, "torch": _TorchPrinter}


class _Jm13(sp.Function):
    """(m1 m2 m3)^(-1/3) = J^(-2/3), kept as one symbol so generated code computes one power."""

    nargs = 3

    def fdiff(self, argindex=1):
        return -self / (3 * self.args[argindex - 1])


class _Jac(sp.Function):
    """J = sqrt(m1 m2 m3), kept as one symbol; dJ/dm_a = J / (2 m_a)."""

    nargs = 3

    def fdiff(self, argindex=1):
        return self / (2 * self.args[argindex - 1])


JM13_SYMBOL = sp.Symbol("jm23", positive=True)


def energies(isochoric_terms, volumetric_term, param_symbols):
    """Sympy expressions (psi_iso, psi_vol) in m1, m2, m3 for the given terms.

    J^(-2/3) and J appear as opaque functions so that differentiation keeps them shared. The
    isochoric terms are called with l_a = sqrt(m_a J^(-2/3)), the volumetric term with J
    (docs/conventions.md section 2; paper Eq. 1).

    Parameters
    ----------
    isochoric_terms : sequence of Term
        Isochoric terms; their energies are summed.
    volumetric_term : Term or None
        The volumetric term U(J); None gives psi_vol = 0.
    param_symbols : dict of str to sympy.Symbol
        Parameter name -> symbol, for every parameter of the terms plus ``"s_iso"``, the factor on
        psi_iso for the moduli convention.

    Returns
    -------
    psi_iso, psi_vol : sympy.Expr
        Energies per reference volume (Pa = J/m^3) as functions of m1, m2, m3 (the eigenvalues of
        C, squared principal stretches).

    Raises
    ------
    InputError
        A term's energy cannot be called with sympy symbols (``math.exp``, ``numpy.exp``, Python
        ``if`` on an argument) or does not return an expression; the message names the term and
        the :mod:`cfm_core.sym` helpers to use.
    """
    jm23 = _Jm13(*M)
    J = _Jac(*M)
    lam = [sp.sqrt(m * jm23) for m in M]
    iso = sp.Integer(0)
    for term in isochoric_terms:
        iso += _trace(term, lam, [param_symbols[p.name] for p in term.parameters])
    iso = param_symbols["s_iso"] * iso
    vol = sp.Integer(0)
    if volumetric_term is not None:
        vol = _trace(volumetric_term, [J], [param_symbols[p.name] for p in volumetric_term.parameters])
    return sp.sympify(iso), sp.sympify(vol)


def _trace(term, kinematic, params):
    """Call a term's energy with sympy symbols; a function that cannot take symbols (``math.exp``,
    ``np.exp``, ``if x > 1``) raises InputError naming the term and the symbolic helpers to use."""
    try:
        value = term.energy(*kinematic, *params)
        expr = sp.sympify(value)
    except (TypeError, ValueError, AttributeError, sp.SympifyError) as exc:
        raise InputError(
            f"energy term '{term.name}' cannot be traced symbolically ({type(exc).__name__}: {exc}). Energies are "
            f"called once with sympy symbols, so write them with the helpers of cfm_core.sym (cfm.sym.exp, "
            f"log, sqrt, where(condition, a, b)) and arithmetic, not math.exp, numpy.exp or Python if/else "
            f"on the arguments.") from None
    if not isinstance(expr, sp.Expr):
        raise InputError(f"energy term '{term.name}' returned {value!r}, not an expression of its arguments "
                         f"(energy per reference volume in Pa).")
    return expr


def _opaque_to_symbols(exprs):
    """Replace the opaque J functions by the symbols the generated code computes first."""
    subs = {_Jm13(*M): JM13_SYMBOL, _Jac(*M): J_SYMBOL}
    return [sp.sympify(e).subs(subs) for e in exprs]


def derivative_table(iso, vol):
    """The expressions of every generated function, from the two energies.

    Parameters
    ----------
    iso, vol : sympy.Expr
        psi_iso and psi_vol in m1, m2, m3 (Pa), from :func:`energies`.

    Returns
    -------
    dict of str to list of sympy.Expr
        ``psi_energy`` (iso, vol), ``psi_grad`` (d psi / d m_a: 3 isochoric then 3 volumetric),
        ``psi_hess_diag`` (d2 psi / d m_a^2, 3 + 3), ``psi_hess`` (pairs 11, 22, 33, 12, 23, 13 of
        ``PAIRS``, 6 + 6) and ``psi_grad_hess_diag`` (psi_grad then psi_hess_diag); all in Pa.
    """
    gi = [sp.diff(iso, m) for m in M]
    gv = [sp.diff(vol, m) for m in M]
    hi = [sp.diff(gi[a], M[b]) for a, b in PAIRS]
    hv = [sp.diff(gv[a], M[b]) for a, b in PAIRS]
    return {
        "psi_energy": [iso, vol],
        "psi_grad": gi + gv,
        "psi_hess_diag": hi[:3] + hv[:3],
        "psi_hess": hi + hv,
        "psi_grad_hess_diag": gi + gv + hi[:3] + hv[:3],
    }


def function_source(name, exprs, param_names, dialect):
    """Source text of ``def name(m1, m2, m3, p): ... return (...)`` in the given dialect.

    The function unpacks ``p`` into the parameter names, computes J = sqrt(m1 m2 m3) and
    J^(-2/3) once, then the common subexpressions (sympy ``cse``) and returns a tuple.

    Parameters
    ----------
    name : str
        Function name, e.g. ``"psi_grad"``.
    exprs : sequence of sympy.Expr
        The outputs, in m1, m2, m3 and the parameter symbols.
    param_names : sequence of str
        Names of the entries of ``p`` in order (energy parameters, then ``"s_iso"``).
    dialect : {"math", "numpy", "torch"}
        ``"math"``: scalar code (numba, plain Python); ``"numpy"`` / ``"torch"``: array code, each
        output broadcast to the shape of m1 + m2 + m3.

    Returns
    -------
    str
        The function's source, ending with a newline.
    """
    printer = PRINTERS[dialect]({"fully_qualified_modules": True} if dialect != "math" else {})
    replacements, reduced = sp.cse(_opaque_to_symbols(exprs), symbols=sp.numbered_symbols("t_"),
                                   optimizations="basic")
    lines = [f"def {name}(m1, m2, m3, p):"]
    lines += [f"    {pname} = p[{i}]" for i, pname in enumerate(param_names)]
    sqrt = {"math": "math.sqrt", "numpy": "numpy.sqrt", "torch": "torch.sqrt"}[dialect]
    lines.append(f"    J = {sqrt}(m1 * m2 * m3)")
    lines.append("    jm23 = 1.0 / (J ** (2.0 / 3.0))")
    if dialect != "math":
        lines.append("    zero_ = 0.0 * (m1 + m2 + m3)")
    for sym, expr in replacements:
        lines.append(f"    {sym} = {printer.doprint(expr)}")
    outs = []
    for expr in reduced:
        text = printer.doprint(expr)
        outs.append(text if dialect == "math" else f"({text}) + zero_")
    lines.append("    return (" + ", ".join(outs) + ",)")
    return "\n".join(lines) + "\n"


def module_source(table, param_names, dialect):
    """Source of a module defining all generated functions for one dialect.

    Parameters
    ----------
    table : dict of str to list of sympy.Expr
        Function name -> outputs, from :func:`derivative_table`.
    param_names : sequence of str
        Names of the entries of the parameter vector ``p``, in order.
    dialect : {"math", "numpy", "torch"}
        Target; decides the imported module and the printer.

    Returns
    -------
    str
        Module source: a "generated, do not edit" comment, the import and one function per entry.
    """
    header = {"math": "import math\n", "numpy": "import numpy\n", "torch": "import torch\n"}[dialect]
    body = "\n\n".join(function_source(n, e, param_names, dialect) for n, e in table.items())
    return f"# generated by cfm_core.material.codegen: do not edit\n{header}\n\n{body}"
