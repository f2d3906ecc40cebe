"""Compressible Neo-Hookean material (isochoric/volumetric split)."""

from cfm_core.material.parameters import positive
from cfm_core.material.terms import isochoric

from .volumetric import quadratic_volumetric


@isochoric(positive("mu", "Pa", 1000.0, "shear modulus"), name="neo-hookean-term")
def neo_hookean(l1, l2, l3, mu):
    """mu/2 (l1^2 + l2^2 + l3^2 - 3) on isochoric stretches.

    Parameters
    ----------
    l1, l2, l3 : sympy.Expr
        Isochoric principal stretches (-), symbols when traced.
    mu : sympy.Expr
        Shear modulus (Pa); default 1000 Pa.

    Returns
    -------
    sympy.Expr
        Energy per reference volume (Pa).
    """
    return mu / 2 * (l1**2 + l2**2 + l3**2 - 3)


NEO_HOOKEAN = (neo_hookean & quadratic_volumetric).named(
    "neo-hookean", "compressible Neo-Hookean: mu/2 (I1bar - 3) + kappa/2 (J - 1)^2, elastic")
