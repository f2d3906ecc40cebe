"""Mooney-Rivlin on isochoric invariants: the ten-line plugin example of docs/user/materials.md."""

from cfm_core.material.parameters import positive
from cfm_core.material.terms import isochoric

from .volumetric import ogden_volumetric


@isochoric(positive("c10", "Pa", 300.0, "first Mooney-Rivlin constant"),
           positive("c01", "Pa", 100.0, "second Mooney-Rivlin constant"), name="mooney-rivlin-term")
def mooney_rivlin(l1, l2, l3, c10, c01):
    """c10 (I1bar - 3) + c01 (I2bar - 3).

    I1bar = l1^2 + l2^2 + l3^2, I2bar = (l1 l2)^2 + (l2 l3)^2 + (l1 l3)^2 (isochoric invariants).

    Parameters
    ----------
    l1, l2, l3 : sympy.Expr
        Isochoric principal stretches (-), symbols when traced.
    c10, c01 : sympy.Expr
        Mooney-Rivlin constants (Pa); defaults 300 Pa and 100 Pa.

    Returns
    -------
    sympy.Expr
        Energy per reference volume (Pa).
    """
    i1 = l1**2 + l2**2 + l3**2
    i2 = (l1 * l2) ** 2 + (l2 * l3) ** 2 + (l1 * l3) ** 2
    return c10 * (i1 - 3) + c01 * (i2 - 3)


MOONEY_RIVLIN = (mooney_rivlin & ogden_volumetric).named(
    "mooney-rivlin", "Mooney-Rivlin (isochoric) + Ogden volumetric, elastic")
