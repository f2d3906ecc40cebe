"""Symbolic building blocks for writing energy terms once.

Energy terms are plain Python functions of symbols; they are traced once with sympy, and every
backend gets code generated from that single expression. Use these helpers instead of ``math`` or
``numpy`` inside an energy function::

    from cfm_core.material.sym import exp, where

    def fibre(x, k1, k2):
        return where(x >= 1, k1 / (2 * k2) * (exp(k2 * (x - 1) ** 2) - 1), 0)
"""

from __future__ import annotations


def exp(x):
    """Exponential ``e**x`` (a sympy ``exp``), for energy functions.

    Parameters
    ----------
    x : sympy.Expr or number
        Exponent (-).

    Returns
    -------
    sympy.Expr
        ``sympy.exp(x)``.
    """
    import sympy  # deferred: sympy is only needed when an energy is traced (cache miss), not per run

    return sympy.exp(x)


def log(x):
    """Natural logarithm (a sympy ``log``), for energy functions.

    Parameters
    ----------
    x : sympy.Expr or number
        Argument (-), positive on the domain of the energy (e.g. J).

    Returns
    -------
    sympy.Expr
        ``sympy.log(x)``.
    """
    import sympy  # deferred: sympy is only needed when an energy is traced (cache miss), not per run

    return sympy.log(x)


def sqrt(x):
    """Square root (a sympy ``sqrt``), for energy functions.

    Parameters
    ----------
    x : sympy.Expr or number
        Argument, non-negative on the domain of the energy.

    Returns
    -------
    sympy.Expr
        ``sympy.sqrt(x)``.
    """
    import sympy  # deferred: sympy is only needed when an energy is traced (cache miss), not per run

    return sympy.sqrt(x)


def where(condition, if_true, if_false):
    """``if_true`` where ``condition`` holds, else ``if_false`` (a sympy Piecewise).

    Both branches are evaluated by array backends, so each must be finite on the whole domain.
    Used for the tension-only fibres of paper Eq. 3-6 (docs/conventions.md section 2).

    Parameters
    ----------
    condition : sympy relational
        E.g. ``x >= 1`` with ``x`` an expression of the energy's arguments.
    if_true, if_false : sympy.Expr or number
        The two branches (energy per reference volume, Pa, inside an energy term).

    Returns
    -------
    sympy.Piecewise
        ``Piecewise((if_true, condition), (if_false, True))``; printed as a conditional
        expression (math) or ``where`` (numpy, torch) in the generated code.
    """
    import sympy  # deferred: sympy is only needed when an energy is traced (cache miss), not per run

    return sympy.Piecewise((if_true, condition), (if_false, True))


__all__ = ["exp", "log", "sqrt", "where"]
